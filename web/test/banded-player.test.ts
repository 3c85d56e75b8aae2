// The player's session on a banded file (proto/container.md, "Index": each group's chunks lie
// together, frame after frame): a coarse budget reads only its levels' index groups and chunks,
// fetches fewer bytes than a full one in fewer requests than runs (read-ahead blocks to the
// end of a keyframe interval, several runs a request), and decodes the same frames as a session
// over the whole file; and what the player fetches of RobotExpressive at 10%, 25% and 100%.
import { test } from "node:test";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { FLAG_BANDS } from "../src/container/format.js";
import type { FetchRanges } from "../src/player/ranges.js";
import { Session } from "../src/player/session.js";
import type { FramePayload } from "../src/player/protocol.js";
import { pmcodecBin, repoRoot, scratchDir } from "./paths.js";

const root = repoRoot();
const bin = pmcodecBin(root);

/** A multi-range source over bytes in memory: every request's ranges, and bytes fetched twice. */
function source(bytes: Uint8Array): { fetch: FetchRanges; calls: [number, number][][]; again: () => number } {
  const calls: [number, number][][] = [], seen = new Uint8Array(bytes.length);
  let again = 0;
  const fetch: FetchRanges = async (ranges) => {
    const asked = ranges.map(([s, e]): [number, number] => [s, Math.min(e, bytes.length)]);
    calls.push(asked);
    for (const [s, e] of asked) for (let i = s; i < e; i++) if (seen[i]++) again++;
    await new Promise((r) => setTimeout(r, 1));
    return { parts: asked.map(([s, e]) => ({ start: s, bytes: bytes.slice(s, e) })), total: bytes.length };
  };
  return { fetch, calls, again: () => again };
}

/** A host that ignores Range: the whole file, once. */
const whole = (bytes: Uint8Array): FetchRanges => async () => ({ parts: [{ start: 0, bytes: bytes.slice() }], total: bytes.length });

function encode(args: string[], name: string): Uint8Array {
  if (!existsSync(bin)) throw new Error(`${bin} is missing: build it with cargo build -p pmcodec (or set PMCODEC_BIN)`);
  const out = join(scratchDir("pmc-banded-player-"), name);
  execFileSync(bin, ["encode", "-q", ...args, "-o", out, "--banded-index"]);
  const bytes = new Uint8Array(readFileSync(out));
  assert.ok((bytes[10] | (bytes[11] << 8)) & FLAG_BANDS, `${name} came out without the banded index`);
  return bytes;
}

/** Plays every frame at `budget` (a function of the session: its share of the triangles), then
 *  frames `then` at `later`; each frame's positions, normals and (resolved) indices. */
async function play(fetch: FetchRanges, budget: (s: Session) => number, opts: { later?: (s: Session) => number; then?: number[]; readAhead?: number } = {}) {
  const s = await Session.open(fetch, { readAhead: opts.readAhead ?? 8 });
  s.colour = "plain";
  s.budget = budget(s);
  const frames: { p: FramePayload; indices: Uint32Array }[] = [];
  const indexOf = new Map<number, Uint32Array>();
  const take = async (f: number) => {
    const p = await s.frame(f);
    if (p.indices) indexOf.set(p.indexVersion, p.indices);
    frames.push({ p, indices: indexOf.get(p.indexVersion)! });
  };
  for (let f = 0; f < s.container.header.frameCount; f++) await take(f);
  if (opts.later) s.budget = opts.later(s);
  for (const f of opts.then ?? []) await take(f);
  return { s, frames };
}

function same(a: Awaited<ReturnType<typeof play>>["frames"], b: Awaited<ReturnType<typeof play>>["frames"], what: string): void {
  assert.equal(a.length, b.length);
  for (let i = 0; i < a.length; i++) {
    const [x, y] = [a[i], b[i]];
    assert.equal(x.p.level, y.p.level, `${what} frame ${i}: level`);
    assert.deepEqual(Buffer.from(x.p.positions.buffer), Buffer.from(y.p.positions.buffer), `${what} frame ${i}: positions`);
    assert.deepEqual(Buffer.from(x.p.normals.buffer), Buffer.from(y.p.normals.buffer), `${what} frame ${i}: normals`);
    assert.deepEqual(Array.from(x.indices), Array.from(y.indices), `${what} frame ${i}: indices`);
  }
}

test("banded file: a coarse budget fetches fewer bytes than a full one, in fewer requests than runs, no byte twice, and decodes the frames a whole-file read decodes", async () => {
  const dir = scratchDir("pmc-banded-tube-");
  execFileSync(bin, ["sample", "twisting-tube", "-o", join(dir, "frames"), "--frames", "48"]);
  const bytes = encode([join(dir, "frames"), "--keyframe-interval", "8"], "tube.pmc");
  const coarseBudget = (s: Session) => s.trianglesPerLevel[s.trianglesPerLevel.length - 2];
  const full = source(bytes), coarse = source(bytes);
  const a = await play(full.fetch, (s) => s.container.header.triangleCount);
  const b = await play(coarse.fetch, coarseBudget);
  const levels = a.s.container.header.levelSizes.length;
  assert.ok(levels >= 3, `${levels} levels`);
  assert.equal(b.frames[0].p.level, levels - 2);
  // The coarse session's reader holds its levels' index entries only.
  assert.ok(b.s.container.index.length < a.s.container.index.length, "a coarse reader holds every index entry");
  const [fa, fb] = [a.s.cache, b.s.cache];
  console.log(`tube (${bytes.length} B, ${levels} levels, 48 frames): full ${fa.fetched} B in ${fa.requests} requests (${fa.ranges} runs); level ${levels - 2}: ${fb.fetched} B in ${fb.requests} requests (${fb.ranges} runs)`);
  assert.ok(fb.fetched < fa.fetched / 2, `coarse ${fb.fetched} B, full ${fa.fetched} B`);
  for (const c of [fa, fb]) assert.ok(c.requests < c.ranges, `${c.requests} requests for ${c.ranges} runs`);
  // Read ahead by keyframe intervals: about one request an interval (6 here), not one a frame.
  for (const c of [fa, fb]) assert.ok(c.requests <= 3 + 6 + 2, `${c.requests} requests for 48 frames`);
  assert.equal(full.again() + coarse.again(), 0, "bytes fetched twice");
  // The same frames as sessions over the whole file.
  same((await play(whole(bytes), (s) => s.container.header.triangleCount)).frames, a.frames, "full");
  same((await play(whole(bytes), coarseBudget)).frames, b.frames, "coarse");
  // A budget raised while playing reads the finer index groups then, and plays as from the whole file.
  const raise = { later: (s: Session) => s.container.header.triangleCount, then: [3, 4, 20, 47] };
  const r = source(bytes), up = await play(r.fetch, coarseBudget, raise);
  assert.equal(up.frames.at(-1)!.p.level, 0);
  same((await play(whole(bytes), coarseBudget, raise)).frames, up.frames, "raised");
  assert.equal(r.again(), 0, "bytes fetched twice after the budget rose");
});

test("banded file, one frame at a time (no read-ahead): one request a frame, however many groups it spans", async () => {
  const dir = scratchDir("pmc-banded-tube1-");
  execFileSync(bin, ["sample", "twisting-tube", "-o", join(dir, "frames"), "--frames", "32"]);
  const bytes = encode([join(dir, "frames"), "--keyframe-interval", "8"], "tube.pmc");
  const src = source(bytes);
  const s = await Session.open(src.fetch, { readAhead: 0 });
  for (let f = 0; f < s.container.header.frameCount; f++) {
    const before = src.calls.length;
    await s.frame(f);
    // A frame's chunks lie in one span per group (two index requests more before the first).
    assert.ok(src.calls.length - before <= (f === 0 ? 3 : 1), `frame ${f}: ${src.calls.length - before} requests`);
    if (f > 0) assert.ok(src.calls.at(-1)!.length > 1, `frame ${f}: its groups asked in one request`);
  }
});

test("RobotExpressive, banded: what the player fetches at 10%, 25% and 100% of the triangles, playing every frame once", async () => {
  const glb = join(root, "../shared/data/gltf/RobotExpressive.glb");
  if (!existsSync(glb)) throw new Error(`${glb} is absent: this test reads the real models in ../shared/data beside the repository`);
  const bytes = encode([glb, "--quant-bits", "12"], "robot.pmc");
  const got: Record<string, { fetched: number; requests: number; ranges: number }> = {};
  for (const share of [0.1, 0.25, 1]) {
    const { s } = await play(source(bytes).fetch, (x) => Math.round(share * x.container.header.triangleCount));
    got[share] = { fetched: s.cache.fetched, requests: s.cache.requests, ranges: s.cache.ranges };
  }
  const pct = (k: number) => ((100 * got[k].fetched) / got[1].fetched).toFixed(1);
  console.log(`robot (${bytes.length} B): ${Object.entries(got).map(([k, v]) => `${Number(k) * 100}%: ${v.fetched} B (${k === "1" ? "100" : pct(Number(k))}%) in ${v.requests} requests, ${v.ranges} runs`).join("; ")}`);
  assert.ok(got[0.1].fetched < got[0.25].fetched && got[0.25].fetched < got[1].fetched);
  for (const v of Object.values(got)) assert.ok(v.requests <= v.ranges);
});
