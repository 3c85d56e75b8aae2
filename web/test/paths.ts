// Where the tests find the repository and the Rust CLI, shared by every test file.
import { existsSync } from "node:fs";
import { dirname, join } from "node:path";

/** The repository root: the nearest folder above this file (compiled into build-test/ or not)
 *  that holds the workspace's Cargo.toml and web/. */
export function repoRoot(): string {
  let dir = import.meta.dirname;
  while (!existsSync(join(dir, "Cargo.toml")) || !existsSync(join(dir, "web"))) {
    const up = dirname(dir);
    if (up === dir) throw new Error(`no repository root above ${import.meta.dirname}`);
    dir = up;
  }
  return dir;
}

/** The `pmcodec` binary the bit-for-bit tests compare with (PMCODEC_BIN, or the debug build). */
export function pmcodecBin(root: string = repoRoot()): string {
  return process.env.PMCODEC_BIN ?? join(root, "target/debug/pmcodec");
}
