// The resealed fuzz corpus (crates/pmcodec-container/tests/resealed: files whose checksums are
// right but whose header, index or payloads are damaged) through the TypeScript decoder. Each
// file is decoded in a worker with a heap limit, and timed: it must open and
// play, or fail with a DecodeError (a TypeError, a RangeError or an out-of-memory is a bug),
// within the time limit per file; and it accepts exactly the files the Rust decoder accepts.
import { test } from "node:test";
import { repoRoot } from "./paths.js";
import assert from "node:assert/strict";
import { readdirSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { isMainThread, parentPort, Worker, workerData } from "node:worker_threads";
import { DecodeError, Decoder, Reader } from "../src/container/index.js";

/** Per file: what a client does must end within this. */
const TIME_LIMIT_MS = 10_000;
/** The worker's JavaScript heap, and the most its whole process may grow by while decoding
 * (typed arrays live outside the heap). */
const HEAP_MB = 256;
const RSS_GROWTH_MB = 1024;

interface Outcome { result: "ok" | "DecodeError" | string; message: string; rssGrowthMb: number }

/** What a client does with a file, and what the Rust test support's `exercise` does: open it,
 * read every chunk (as `verify` does), then play every frame at full resolution, at level 1 and
 * at the top level, and cut triangle budgets on the last frame, drawn with the file's appearance
 * and images where it has one. */
async function play(bytes: Uint8Array): Promise<void> {
  const c = await Reader.open(async (o, n) => bytes.slice(o, o + n), bytes.length);
  for (const e of c.index) await c.chunk(e);
  const levels = new Set([0, 1, c.header.levelSizes.length - 1]);
  for (const level of levels) {
    if (level >= c.header.levelSizes.length) continue;
    const p = new Decoder(c, level);
    for (let f = 0; f < c.header.frameCount; f++) await p.seek(f);
    const pos = p.positions();
    if (c.header.appearance) {
      await p.loadAppearance();
      await p.images();
    }
    for (const budget of [50, 20, c.header.triangleCount]) {
      p.replay.selectTriangles(budget, p.replay.splitBenefits(pos));
      p.orderedMesh(pos);
      if (c.header.appearance) p.texturedMesh(pos);
    }
    await p.seek(0);
  }
}

if (!isMainThread) {
  // One worker plays the files in turn and says when it starts and ends each, so that the
  // main thread can time each file (a worker per file cost 0.2 s each on a busy machine).
  for (const path of workerData as string[]) {
    parentPort?.postMessage({ start: path });
    const rss0 = process.memoryUsage.rss();
    const bytes = new Uint8Array(readFileSync(path));
    let result = "ok", message = "";
    try {
      await play(bytes);
    } catch (e) {
      result = e instanceof DecodeError ? "DecodeError" : e instanceof Error ? e.constructor.name : typeof e;
      message = e instanceof Error ? e.message : String(e);
    }
    const out: Outcome = { result, message, rssGrowthMb: (process.memoryUsage.rss() - rss0) / (1 << 20) };
    parentPort?.postMessage({ path, out });
  }
} else {
  const root = repoRoot();
  // PMC_RESEALED_DIR: another directory of files and outcomes.txt (the Rust example
  // reseal_run writes one with RESEAL_WRITE=1), for longer runs than the committed corpus.
  const corpus = process.env.PMC_RESEALED_DIR ?? join(root, "crates/pmcodec-container/tests/resealed");

  /** Plays the files in a worker; one that takes longer than the time limit, or that
   * exhausts the worker's heap, fails the test by name. */
  function inWorker(paths: string[]): Promise<Map<string, Outcome>> {
    return new Promise((resolve, reject) => {
      const results = new Map<string, Outcome>();
      const w = new Worker(new URL(import.meta.url), { workerData: paths, resourceLimits: { maxOldGenerationSizeMb: HEAP_MB } });
      let current = "";
      let timer: NodeJS.Timeout | undefined;
      const fail = (why: string) => { clearTimeout(timer); void w.terminate(); reject(new Error(`${current}: ${why}`)); };
      w.on("message", (m: { start?: string; path?: string; out?: Outcome }) => {
        clearTimeout(timer);
        if (m.start !== undefined) {
          current = m.start;
          timer = setTimeout(() => fail(`no answer within ${TIME_LIMIT_MS} ms`), TIME_LIMIT_MS);
        } else if (m.path !== undefined && m.out !== undefined) {
          results.set(m.path, m.out);
          if (results.size === paths.length) { void w.terminate(); resolve(results); }
        }
      });
      w.on("error", (e) => fail(e.message));
      w.on("exit", (code) => { if (results.size < paths.length) fail(`worker exited with ${code}`); });
    });
  }

  test("the resealed fuzz corpus gives DecodeErrors or plays, in time and in bounded memory", async () => {
    const outcomes = new Map<string, string>();
    for (const line of readFileSync(join(corpus, "outcomes.txt"), "utf8").split("\n")) {
      if (!line.trim() || line.startsWith("#")) continue;
      const [name, outcome] = line.trim().split(" ");
      outcomes.set(name, outcome);
    }
    const files = readdirSync(corpus).filter((f) => f.endsWith(".pmc")).sort();
    assert.ok(files.length >= 20, `only ${files.length} files in ${corpus}`);
    let refused = 0;
    const results = await inWorker(files.map((f) => join(corpus, f)));
    const wrong: string[] = [];
    for (const f of files) {
      const o = results.get(join(corpus, f))!;
      if (o.result !== "ok" && o.result !== "DecodeError") wrong.push(`${f}: ${o.result}: ${o.message}`);
      if (o.rssGrowthMb >= RSS_GROWTH_MB) wrong.push(`${f}: the process grew by ${o.rssGrowthMb.toFixed(0)} MB`);
      if (outcomes.get(f) === "ok" && o.result !== "ok") wrong.push(`${f}: the Rust decoder plays it, this one says ${o.message}`);
      // And the other way: what the Rust decoder refuses, this one refuses too (a header, an
      // index or a hierarchy one of them takes and the other not is a gap in the other's checks).
      if (outcomes.has(f) && outcomes.get(f) !== "ok" && o.result === "ok") wrong.push(`${f}: the Rust decoder refuses it (${outcomes.get(f)}), this one plays it`);
      if (o.result !== "ok") refused++;
    }
    assert.deepEqual(wrong, [], `${wrong.length} of ${files.length} files`);
    // Most of the corpus is damage both decoders must refuse.
    assert.ok(refused * 2 >= files.length, `only ${refused} of ${files.length} refused`);
  });
}
