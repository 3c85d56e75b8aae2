// Where the tests find the repository and the Rust CLI, shared by every test file.
import { existsSync, mkdtempSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
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

/** A fresh directory under the system's temporary one, removed when the test process exits
 *  (the encoded files a test writes there are not left behind run after run). */
export function scratchDir(prefix: string): string {
  const dir = mkdtempSync(join(tmpdir(), prefix));
  process.on("exit", () => rmSync(dir, { recursive: true, force: true }));
  return dir;
}
