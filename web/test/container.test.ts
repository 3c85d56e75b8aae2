// The TypeScript container decoder against files the Rust encoder writes: same hierarchy-driven
// cut, same triangles, positions equal to the Rust decoder's (and so within the stated bound).
import { test } from "node:test";
import { pmcodecBin, repoRoot, scratchDir } from "./paths.js";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, mkdirSync, readdirSync, readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { FLAG_BANDS, FLAG_NAMES, frontDecode, parseTable } from "../src/container/format.js";
import { BELOW, ChunkKind, DecodeError, Decoder, Motion, NONE, Reader, type RevealFrom, VertexOrder, attributeEntry, bandFaces, chartsNeedTriangles, dequantizeUv, needsBind, needsFaces, readBand0Table, readCharts, readPositions, readTable, texturedMesh } from "../src/container/index.js";
import type { Faces } from "../src/container/index.js";
import { keyFromFirst, readCornerUpdates, readDelta, readFaces, readKey, readTriangles } from "../src/container/payload.js";
import { nodeSkins, readBinds } from "../src/container/skin.js";

const root = repoRoot();
const bin = pmcodecBin(root);

function fixtures(): { dir: string; pmc: string } {
  if (!existsSync(bin)) throw new Error(`${bin} is missing: build it with cargo build -p pmcodec (or set PMCODEC_BIN)`);
  const dir = scratchDir("pmc-ts-");
  execFileSync(bin, ["sample", "twisting-tube", "-o", join(dir, "frames"), "--frames", "20"]);
  const pmc = join(dir, "tube.pmc");
  // Coarse nodes on a grid, so residual shifts are exercised too; every band's faces and
  // corner updates sent, so that their codings are (derived ones: "derived topology" below).
  execFileSync(bin, ["encode", "-q", join(dir, "frames"), "-o", pmc, "--keyframe-interval", "8", "--quant-bits", "14", "--coarse-grid", "1", "--derived-topology", "never"]);
  return { dir, pmc };
}

function readObj(path: string): { positions: number[]; indices: number[] } {
  const positions: number[] = [], indices: number[] = [];
  for (const line of readFileSync(path, "utf8").split("\n")) {
    const w = line.trim().split(/\s+/);
    if (w[0] === "v") positions.push(+w[1], +w[2], +w[3]);
    if (w[0] === "f") indices.push(+w[1] - 1, +w[2] - 1, +w[3] - 1);
  }
  return { positions, indices };
}

async function open(pmc: string): Promise<Reader> {
  const bytes = new Uint8Array(readFileSync(pmc));
  return Reader.open(async (o, n) => bytes.slice(o, o + n), bytes.length);
}

const { dir, pmc } = fixtures();

test("decodes the same cut and positions as the Rust decoder", async () => {
  const c = await open(pmc);
  assert.equal(c.header.frameCount, 20);
  const player = new Decoder(c, 0);
  for (const [frame, budget] of [[0, 300], [5, 1000], [13, 4000], [19, 150]]) {
    const out = join(dir, `expected-${frame}-${budget}.obj`);
    execFileSync(bin, ["decode", "-q", pmc, "--frame", String(frame), "--triangles", String(budget), "-o", out]);
    const expected = readObj(out);
    await player.seek(frame);
    const pos = player.positions();
    player.replay.selectTriangles(budget, player.replay.splitBenefits(pos));
    const mesh = player.orderedMesh(pos);
    assert.deepEqual(Array.from(mesh.indices), expected.indices, `frame ${frame} budget ${budget}: triangles`);
    assert.equal(mesh.positions.length, expected.positions.length);
    for (let i = 0; i < expected.positions.length; i++) {
      assert.ok(Math.abs(mesh.positions[i] - expected.positions[i]) <= 1e-5 * (1 + Math.abs(expected.positions[i])), `frame ${frame}: coordinate ${i}`);
    }
  }
});

test("level-major whole splits (the option `--budget-cut level`) on a generated cloth: the Rust decoder's cut at every budget, and a budget at exactly a level's triangle count is that level's cut (every cut node of that level)", async () => {
  const frames = join(dir, "cloth-level-frames"), cloth = join(dir, "cloth-level.pmc");
  execFileSync(bin, ["sample", "waving-cloth", "-q", "-o", frames, "--frames", "6"]);
  execFileSync(bin, ["encode", "-q", frames, "-o", cloth, "--keyframe-interval", "4"]);
  const c = await open(cloth);
  const player = new Decoder(c, 0);
  const r = player.replay;
  const sizes = c.header.levelSizes;
  let atLevels = 0;
  for (const frame of [0, 5]) {
    const budgets: [number, number | undefined][] = [];
    for (let L = 1; L < sizes.length - 1; L++) {
      const out = join(dir, `cloth-level-${frame}-L${L}.obj`);
      execFileSync(bin, ["decode", "-q", cloth, "--frame", String(frame), "--level", String(L), "-o", out]);
      const n = readObj(out).indices.length / 3;
      budgets.push([n, L], [n + 7, undefined], [n - 1, undefined]);
    }
    for (const [budget, level] of budgets) {
      const out = join(dir, `cloth-level-${frame}-${budget}.obj`);
      execFileSync(bin, ["decode", "-q", cloth, "--frame", String(frame), "--triangles", String(budget), "--budget-cut", "level", "-o", out]);
      const expected = readObj(out);
      await player.seek(frame);
      const pos = player.positions();
      r.selectTriangles(budget, r.splitBenefits(pos), "levels");
      const mesh = player.orderedMesh(pos);
      assert.deepEqual(Array.from(mesh.indices), expected.indices, `frame ${frame} budget ${budget}: triangles`);
      assert.ok(r.shown.length <= budget);
      if (level === undefined) continue;
      assert.equal(r.shown.length, budget, `frame ${frame} level ${level}: every triangle of the level shown`);
      const rep = r.cutNodes(), base = r.offsets[r.minLevel];
      for (let v = 0; v < sizes[r.minLevel]; v++) {
        const g = rep[base + v];
        assert.ok(g >= r.offsets[level] && g < r.offsets[level + 1], `frame ${frame} level ${level}: vertex ${v} stands for node ${g}, not of the level`);
      }
      atLevels++;
    }
  }
  assert.ok(atLevels >= 4);
});

test("partial splits (the option; budgets between levels) on a generated cloth, reveals ranked on the frame's or the keyframe's positions or banded: the same cut as the Rust decoder's `decode --budget-cut partial-frame`, `partial-keyframe`, `partial-banded1` and `partial-banded2`, and every shown triangle's corners are three distinct revealed nodes", async () => {
  const frames = join(dir, "cloth-frames"), cloth = join(dir, "cloth.pmc");
  execFileSync(bin, ["sample", "waving-cloth", "-q", "-o", frames, "--frames", "12"]);
  execFileSync(bin, ["encode", "-q", frames, "-o", cloth, "--keyframe-interval", "8"]);
  const c = await open(cloth);
  const player = new Decoder(c, 0);
  const tris = c.header.triangleCount;
  let partial = 0;
  const cases: [number, number, RevealFrom][] = [[0, 0.03, "frame"], [3, 0.17, "keyframe"], [3, 0.17, "frame"], [5, 0.2, "banded1"], [9, 0.41, "keyframe"], [11, 0.63, "frame"], [11, 0.9, "keyframe"], [10, 0.3, "keyframe"], [7, 0.35, "banded2"], [10, 0.5, "banded1"]];
  for (const [frame, share, from] of cases) {
    const budget = Math.round(share * tris), how = `partial-${from}`;
    const out = join(dir, `cloth-${frame}-${budget}-${how}.obj`);
    execFileSync(bin, ["decode", "-q", cloth, "--frame", String(frame), "--triangles", String(budget), "--budget-cut", how, "-o", out]);
    const expected = readObj(out);
    await player.seek(frame);
    const pos = player.positions();
    const r = player.replay;
    r.selectTriangles(budget, player.revealBenefits(from), true);
    const mesh = player.orderedMesh(pos);
    assert.deepEqual(Array.from(mesh.indices), expected.indices, `${how} frame ${frame} budget ${budget}: triangles`);
    assert.equal(mesh.positions.length, expected.positions.length, `${how} frame ${frame} budget ${budget}: vertices`);
    for (let i = 0; i < expected.positions.length; i++) {
      assert.ok(Math.abs(mesh.positions[i] - expected.positions[i]) <= 1e-5 * (1 + Math.abs(expected.positions[i])), `${how} frame ${frame} budget ${budget}: coordinate ${i}`);
    }
    assert.ok(r.shown.length <= budget);
    const rep = r.cutNodes(), base = r.offsets[r.minLevel];
    for (const t of r.shown) {
      const g = [0, 1, 2].map((i) => rep[base + r.corners[3 * t + i]]);
      assert.ok(g[0] !== g[1] && g[1] !== g[2] && g[0] !== g[2], `${how} frame ${frame} budget ${budget}: triangle ${t} has two corners on one node`);
      for (const x of g) {
        const p = r.parentGlobal(x);
        assert.ok(x !== NONE && (p === NONE || r.expanded[p] || r.revealed[x]), `${how} frame ${frame} budget ${budget}: triangle ${t} on node ${x}, not revealed`);
      }
    }
    // Revealed nodes whose parent is not expanded: the cut is partial there.
    for (let g = 0; g < r.nodeCount; g++) if (r.revealed[g] && !r.expanded[r.parentGlobal(g)]) partial++;
  }
  assert.ok(partial > 0, "no budget made a partial split");
});

test("level 0 is the input within the quantization bound", async () => {
  const c = await open(pmc);
  const player = new Decoder(c, 0);
  await player.seek(7);
  const pos = player.positions();
  const input = readObj(join(dir, "frames", "frame-0007.obj"));
  const bound = c.header.step * Math.sqrt(3) / 2 * 1.001;
  for (let v = 0; v < c.header.vertexCount; v++) {
    const d = Math.hypot(pos[3 * v] - input.positions[3 * v], pos[3 * v + 1] - input.positions[3 * v + 1], pos[3 * v + 2] - input.positions[3 * v + 2]);
    assert.ok(d <= bound, `vertex ${v}: ${d} > ${bound}`);
  }
});

/** Every frame's input vertices as the Rust decoder writes them, beside this decoder's. */
async function sameAsRust(pmc: string, name: string): Promise<Reader> {
  const out = join(dir, `${name}-frames`);
  execFileSync(bin, ["decode", "-q", pmc, "--all-frames", "--level", "0", "-o", out]);
  const c = await open(pmc);
  const files = readdirSync(out).filter((f) => f.endsWith(".obj")).sort();
  assert.equal(files.length, c.header.frameCount);
  const player = new Decoder(c, 0);
  for (let f = 0; f < files.length; f++) {
    await player.seek(f);
    const pos = player.positions(), expected = readObj(join(out, files[f]));
    assert.equal(expected.positions.length, 3 * c.header.vertexCount);
    // The OBJ holds each f32 in its shortest exact form, so equal predictions give equal numbers.
    for (let i = 0; i < expected.positions.length; i++) assert.equal(pos[i], Math.fround(expected.positions[i]), `${name} frame ${f}: coordinate ${i}`);
  }
  return c;
}

test("Triangles coding 1 (a tube with its vertices renumbered at random): TS reads the triangles and every frame as the Rust decoder does; damage is a DecodeError", async () => {
  // The same permutation for every frame, from a fixed linear congruential sequence.
  const src = join(dir, "frames"), dst = join(dir, "shuffled");
  mkdirSync(dst, { recursive: true });
  const names = readdirSync(src).filter((f) => f.endsWith(".obj")).sort();
  const n = readObj(join(src, names[0])).positions.length / 3;
  const order = Array.from({ length: n }, (_, i) => i);
  let s = 12345n;
  for (let i = n - 1; i > 0; i--) {
    s = (s * 6364136223846793005n + 1442695040888963407n) & 0xffffffffffffffffn;
    const k = Number((s >> 33n) % BigInt(i + 1));
    [order[i], order[k]] = [order[k], order[i]];
  }
  const newId = new Array<number>(n);
  order.forEach((old, i) => { newId[old] = i; });
  for (const name of names) {
    const { positions, indices } = readObj(join(src, name));
    const lines: string[] = [];
    for (const old of order) lines.push(`v ${positions[3 * old]} ${positions[3 * old + 1]} ${positions[3 * old + 2]}`);
    for (let t = 0; t < indices.length; t += 3) lines.push(`f ${newId[indices[t]] + 1} ${newId[indices[t + 1]] + 1} ${newId[indices[t + 2]] + 1}`);
    writeFileSync(join(dst, name), lines.join("\n") + "\n");
  }
  const file = join(dir, "shuffled.pmc");
  execFileSync(bin, ["encode", "-q", dst, "-o", file, "--keyframe-interval", "8", "--quant-bits", "12"]);
  const c = await sameAsRust(file, "shuffled");
  const raw = await c.chunk(c.find(ChunkKind.Triangles, 0, 0));
  assert.deepEqual(Array.from(raw.subarray(0, 2)), [0, 1], "the encoder keeps coding 1");
  const h = c.header, tris = readTriangles(raw, "triangles", h.triangleCount, h.vertexCount, c.version);
  const first = readdirSync(join(dir, "shuffled-frames")).filter((f) => f.endsWith(".obj")).sort()[0];
  assert.deepEqual(Array.from(tris), readObj(join(dir, "shuffled-frames", first)).indices);
  assert.throws(() => readTriangles(raw, "triangles", h.triangleCount + 1, h.vertexCount, c.version), DecodeError);
  assert.throws(() => readTriangles(raw, "triangles", h.triangleCount, 3, c.version), DecodeError);
  assert.throws(() => readTriangles(raw.subarray(0, raw.length - 1), "triangles", h.triangleCount, h.vertexCount, c.version), DecodeError);
  assert.throws(() => readTriangles(Uint8Array.from([0, 3, ...raw.subarray(2)]), "triangles", h.triangleCount, h.vertexCount, c.version), /topology coding 3/);
});

test("Key coding 3 (a later keyframe's changes from frame 0's parent map): TS reads every frame as the Rust decoder does, seeking straight to a late frame too", async () => {
  const file = join(dir, "tube-key3.pmc");
  execFileSync(bin, ["encode", "-q", join(dir, "frames"), "-o", file, "--keyframe-interval", "4", "--quant-bits", "12"]);
  const c = await sameAsRust(file, "key3");
  const h = c.header;
  let coded = 0;
  for (const e of c.index.filter((x) => x.kind === ChunkKind.Key)) {
    const raw = await c.chunk(e);
    if (!keyFromFirst(raw)) continue;
    coded++;
    assert.ok(e.frame > 0, "never in frame 0's Key chunk");
    assert.throws(() => readKey(raw, "k", h.levelSizes, e.band, c.version), /frame 0's parents/);
    const first = readKey(await c.chunk(c.find(ChunkKind.Key, 0, e.band)), "k0", h.levelSizes, e.band, c.version);
    assert.throws(() => readKey(raw, "k", h.levelSizes, e.band, c.version, first.subarray(1)), DecodeError);
    assert.throws(() => readKey(raw.subarray(0, raw.length - 1), "k", h.levelSizes, e.band, c.version, first), DecodeError);
  }
  assert.ok(coded > 0, "no Key chunk took coding 3");
  // A player that seeks straight to the last frame reads frame 0's Key chunks for it.
  const last = h.frameCount - 1, files = readdirSync(join(dir, "key3-frames")).filter((f) => f.endsWith(".obj")).sort();
  const player = new Decoder(c, 0);
  await player.seek(last);
  const pos = player.positions(), expected = readObj(join(dir, "key3-frames", files[last]));
  for (let i = 0; i < expected.positions.length; i++) assert.equal(pos[i], Math.fround(expected.positions[i]), `frame ${last}: coordinate ${i}`);
});

test("every band-0 motion and order: every frame's input vertices equal the Rust decoder's, bit for bit", async () => {
  const cases: [string, string[], Motion, VertexOrder][] = [
    ["keyframe-affine", [], Motion.KeyframeAffine, VertexOrder.BreadthFirst],
    ["affine", ["--motion", "affine"], Motion.Affine, VertexOrder.BreadthFirst],
    ["mean-input", ["--motion", "mean", "--order", "input"], Motion.Mean, VertexOrder.Input],
  ];
  for (const [name, args, motion, order] of cases) {
    const file = join(dir, `tube-${name}.pmc`);
    execFileSync(bin, ["encode", "-q", join(dir, "frames"), "-o", file, "--keyframe-interval", "8", "--quant-bits", "14", ...args]);
    const c = await sameAsRust(file, name);
    assert.equal(c.header.motion, motion, name);
    assert.equal(c.header.order, order, name);
  }
});

test("version 3, 4, 5 and 6 files still decode, as the Rust decoder decodes them", async () => {
  const files = [
    ["v3-cloth-k1.pmc", 3, Motion.Mean, VertexOrder.Input],
    ["v4-cloth-affine-k4.pmc", 4, Motion.Affine, VertexOrder.Input],
    ["v5-cloth-k4.pmc", 5, Motion.KeyframeAffine, VertexOrder.BreadthFirst],
    // Version 6's postcard index, with stored and left-out chunks (version 7 codes the index compactly).
    ["v6-cloth-k4.pmc", 6, Motion.KeyframeAffine, VertexOrder.BreadthFirst],
  ] as const;
  for (const [file, version, motion, order] of files) {
    const path = join(root, "crates/pmcodec-container/tests/compat", file);
    const c = await sameAsRust(path, `v${version}`);
    assert.equal(c.version, version);
    assert.equal(c.header.motion, motion);
    assert.equal(c.header.order, order);
    assert.equal(c.header.skin, null);
  }
  const bytes = new Uint8Array(readFileSync(join(root, "crates/pmcodec-container/tests/compat/v3-cloth-k1.pmc")));
  bytes[8] = 9;
  await assert.rejects(Reader.open(async (o, n) => bytes.slice(o, o + n), bytes.length), /version 9 is not supported/);
});

test("a level-limited player reads fewer bytes and agrees above its level", async () => {
  const full = await open(pmc), part = await open(pmc);
  const a = new Decoder(full, 0), b = new Decoder(part, 2);
  await a.seek(11);
  await b.seek(11);
  // Chunks read, beyond the preamble, header and index every client reads alike.
  const [p, f] = [part.bytesRead - part.dataStart, full.bytesRead - full.dataStart];
  assert.ok(p * 3 < f, `${p} vs ${f} chunk bytes`);
  const off = a.replay.offsets[2] * 3;
  assert.deepEqual(Array.from(b.current.subarray(off)), Array.from(a.current.subarray(off)));
});

test("level-limited players derive the same degenerate sets as a full one, frame by frame", async () => {
  for (const level of [1, 2]) {
    const a = new Decoder(await open(pmc), 0), b = new Decoder(await open(pmc), level);
    const firstAbove = a.replay.offsets[level + 1];
    let alive = 0;
    for (let f = 0; f < 20; f++) {
      await a.seek(f);
      await b.seek(f);
      for (let t = 0; t < a.replay.triangleCount; t++) {
        const g = a.replay.nodeOf[t];
        // Alive at `level`: its degeneration node lies above it (or it never degenerates).
        if (g === NONE || g >= firstAbove) {
          alive++;
          assert.equal(b.replay.nodeOf[t], g, `level ${level} frame ${f} triangle ${t}`);
        } else assert.equal(b.replay.nodeOf[t], BELOW, `level ${level} frame ${f} triangle ${t} is not alive`);
      }
    }
    assert.ok(alive > 0);
  }
});

test("bit-coded topology chunks (coding 1): the tube holds them of every kind, and a damaged one is a DecodeError naming it", async () => {
  const c = await open(pmc), h = c.header;
  const coded = new Map<ChunkKind, number>();
  for (const e of c.index) {
    if (![ChunkKind.Key, ChunkKind.Delta, ChunkKind.Faces, ChunkKind.Corners].includes(e.kind)) continue;
    const raw = await c.chunk(e);
    if (raw.length >= 2 && raw[0] === 0) coded.set(e.kind, (coded.get(e.kind) ?? 0) + 1);
  }
  for (const k of [ChunkKind.Key, ChunkKind.Delta, ChunkKind.Faces, ChunkKind.Corners]) assert.ok((coded.get(k) ?? 0) > 0, `no coded chunk of kind ${k}`);
  // Every truncation of a coded Key, Faces and Delta chunk is refused with the chunk's name.
  const codedOf = async (kind: ChunkKind) => {
    for (const e of c.index.filter((x) => x.kind === kind)) {
      const raw = await c.chunk(e);
      if (raw.length > 2 && raw[0] === 0) return { e, raw };
    }
    throw new Error(`no coded chunk of kind ${kind}`);
  };
  const key = await codedOf(ChunkKind.Key), faces = await codedOf(ChunkKind.Faces), delta = await codedOf(ChunkKind.Delta);
  const [k, kb] = [key.raw, key.e.band], [f, fb] = [faces.raw, faces.e.band];
  assert.equal(readKey(k, "k", h.levelSizes, kb, c.version).length, h.levelSizes[kb]);
  assert.ok(readFaces(f, "f", h.levelSizes[fb], h.triangleCount, c.version).length > 0);
  for (let cut = 2; cut < k.length; cut++) assert.throws(() => readKey(k.subarray(0, cut), "a key", h.levelSizes, kb, c.version), /a key/);
  for (let cut = 2; cut < f.length; cut++) assert.throws(() => readFaces(f.subarray(0, cut), "some faces", h.levelSizes[fb], h.triangleCount, c.version), /some faces/);
  for (let cut = 2; cut < delta.raw.length; cut++) assert.throws(() => readDelta(delta.raw.subarray(0, cut), "a delta", h.levelSizes, delta.e.band, { swaps: [], corners: [] }), /a delta/);
  const odd = k.slice();
  odd[1] = 2;
  assert.throws(() => readKey(odd, "a key", h.levelSizes, kb, c.version), /topology coding/);
  // A coded Corners chunk read against the corners a level-limited player holds before it.
  for (const level of [1, 2]) {
    const p = new Decoder(await open(pmc), level);
    let tried = 0;
    for (let fr = 1; fr < h.frameCount; fr++) {
      await p.seek(fr - 1);
      const e = c.index.find((x) => x.kind === ChunkKind.Corners && x.frame === fr && x.band === level);
      if (!e) continue;
      const raw = await c.chunk(e);
      if (raw[0] !== 0) continue;
      const held = p.replay.corners.slice();
      assert.ok(readCornerUpdates(raw, "c", h.levelSizes[level], held).length > 0);
      for (let cut = 2; cut < raw.length; cut++) assert.throws(() => readCornerUpdates(raw.subarray(0, cut), "band x corners", h.levelSizes[level], held), DecodeError);
      tried++;
    }
    assert.ok(tried > 0, `level ${level}: no coded Corners chunk`);
  }
});

test("derived topology (Faces coding 2): level-limited players hold the same corners and positions as with the faces sent, every frame and after seeks, and read what Reader.reads names", async () => {
  const derivedPmc = join(dir, "tube-derived.pmc");
  execFileSync(bin, ["encode", "-q", join(dir, "frames"), "-o", derivedPmc, "--keyframe-interval", "8", "--quant-bits", "14", "--coarse-grid", "1"]);
  const d = await open(derivedPmc), s = await open(pmc);
  const faces = d.index.filter((e) => e.kind === ChunkKind.Faces);
  assert.ok(faces.length > 0 && faces.every((e) => e.rawLen === 2), "every Faces chunk derived");
  for (const e of d.index.filter((x) => x.kind === ChunkKind.Corners)) assert.deepEqual(Array.from(await d.chunk(e)), [0]);
  for (let level = 1; level < d.header.levelSizes.length; level++) {
    assert.ok(d.derives(13, level) && !s.derives(13, level));
    assert.ok(d.index.some((e) => e.kind === ChunkKind.Key && e.band === 0 && d.reads(e, level)));
    assert.ok(!s.index.some((e) => e.kind === ChunkKind.Key && e.band < level && s.reads(e, level)));
    const a = new Decoder(await open(pmc), level), b = new Decoder(await open(derivedPmc), level);
    for (const f of [...Array(d.header.frameCount).keys(), 13, 3, 9]) {
      await a.seek(f);
      await b.seek(f);
      assert.deepEqual(b.replay.corners, a.replay.corners, `level ${level} frame ${f}: corners`);
      assert.deepEqual(b.current, a.current, `level ${level} frame ${f}: positions`);
    }
    // Only the chunks Reader.reads names are read.
    const r = await open(derivedPmc);
    const allowed = r.index.filter((e) => r.reads(e, level)).reduce((n, e) => n + e.storedLen, 0);
    const p = new Decoder(r, level);
    for (let f = 0; f < r.header.frameCount; f++) await p.seek(f);
    assert.ok(r.bytesRead - r.dataStart <= allowed, `level ${level}: ${r.bytesRead - r.dataStart} > ${allowed}`);
  }
});

test("front-coded frame names (FLAG_NAMES) read as the names the encoder was given, as Rust reads them", async () => {
  const c = await open(pmc);
  assert.ok((c.flags & FLAG_NAMES) !== 0);
  const files = readdirSync(join(dir, "frames")).filter((f) => f.endsWith(".obj")).sort();
  assert.deepEqual(c.header.frameNames, files);
  // The Rust unit test's vectors (format::tests::frame_names_front_code_and_decode).
  const long = "x".repeat(300);
  const names = ["waving-cloth@9", "waving-cloth@10", "", "Dance@1.233s", "Dance@1.267s", "été@1", "été@2", "\u{7f}odd", long, long + "y", "éx", "éy"];
  const coded = ["waving-cloth@9", "\u{d}10", "\u{0}", "\u{0}Dance@1.233s", "\u{9}67s", "\u{0}été@1", "\u{6}2", "\u{0}\u{7f}odd", "\u{0}" + long, "\u{7f}" + "x".repeat(173) + "y", "\u{0}éx", "\u{2}y"];
  assert.deepEqual(frontDecode(coded), names);
  assert.deepEqual(frontDecode(["é", "\u{7f}a", "\u{1}b", "ßc"]), ["é", "éa", "b", "ßc"]);
});

test("damaged files are errors, not crashes", async () => {
  const bytes = new Uint8Array(readFileSync(pmc));
  for (const at of [0, 9, 40, bytes.length - 3]) {
    const b = bytes.slice();
    b[at] ^= 0x5a;
    await assert.rejects(async () => {
      const c = await Reader.open(async (o, n) => b.slice(o, o + n), b.length);
      const p = new Decoder(c, 0);
      for (let f = 0; f < c.header.frameCount; f++) await p.seek(f);
    }, DecodeError, `flip at ${at}`);
  }
});

/** A GLB's JSON and binary chunk. */
function readGlb(path: string): { json: any; bin: Uint8Array } {
  const b = new Uint8Array(readFileSync(path));
  const dv = new DataView(b.buffer, b.byteOffset, b.byteLength);
  const jsonLen = dv.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(b.subarray(20, 20 + jsonLen)));
  const binStart = 20 + jsonLen + 8;
  return { json, bin: b.subarray(binStart, binStart + dv.getUint32(20 + jsonLen, true)) };
}

function accessor(glb: { json: any; bin: Uint8Array }, i: number): Float32Array | Uint32Array | Uint16Array {
  const a = glb.json.accessors[i], v = glb.json.bufferViews[a.bufferView];
  const bytes = glb.bin.slice(v.byteOffset, v.byteOffset + v.byteLength);
  // Indices are 16-bit up to 65,535 vertices (the GLB writer's choice), else 32-bit.
  if (a.componentType === 5123) return new Uint16Array(bytes.buffer);
  return a.componentType === 5125 ? new Uint32Array(bytes.buffer) : new Float32Array(bytes.buffer);
}

test("version 6 appearance: the same texture coordinates, colours, normals and materials as the Rust decoder, bit for bit", async () => {
  const file = join(root, "crates/pmcodec-container/tests/compat/v6-textured-cloth-k4.pmc");
  const c = await open(file);
  assert.equal(c.version, 6);
  const a = c.header.appearance!;
  assert.deepEqual([a.uvSets, a.colors, a.materials, a.images], [1, true, 2, 1]);
  const player = new Decoder(c, 0);
  await player.loadAppearance();
  const images = await player.images();
  assert.equal(images[0].mimeType, "image/png");
  for (const [frame, budget] of [[0, 30], [3, 80], [5, 1000]]) {
    const out = join(dir, `textured-${frame}-${budget}.glb`);
    execFileSync(bin, ["decode", "-q", file, "--frame", String(frame), "--triangles", String(budget), "-o", out]);
    const glb = readGlb(out);
    await player.seek(frame);
    const pos = player.positions();
    player.replay.selectTriangles(budget, player.replay.splitBenefits(pos));
    const mesh = player.texturedMesh(pos);
    const prims = glb.json.meshes[0].primitives;
    const attr = prims[0].attributes;
    const what = `frame ${frame} budget ${budget}`;
    assert.deepEqual(Array.from(mesh.positions), Array.from(accessor(glb, attr.POSITION)), `${what}: positions`);
    assert.deepEqual(Array.from(mesh.normals), Array.from(accessor(glb, attr.NORMAL)), `${what}: normals`);
    assert.deepEqual(Array.from(mesh.uv0!), Array.from(accessor(glb, attr.TEXCOORD_0)), `${what}: texture coordinates`);
    assert.deepEqual(Array.from(mesh.colors!), Array.from(accessor(glb, attr.COLOR_0)), `${what}: colours`);
    // Each vertex's node and chart name its entry: the values drawn are that entry's.
    const nv = mesh.positions.length / 3;
    assert.equal(mesh.nodes.length, nv);
    assert.equal(mesh.charts.length, nv);
    const looks = player.looks!;
    for (let v = 0; v < nv; v++) {
      const e = attributeEntry(a, looks.tables, player.replay.offsets, mesh.nodes[v], mesh.charts[v]);
      assert.ok(e, `${what}: vertex ${v} has no entry`);
      assert.deepEqual([Math.fround(dequantizeUv(a, 0, e[0])), Math.fround(dequantizeUv(a, 1, e[1]))], Array.from(mesh.uv0!.subarray(2 * v, 2 * v + 2)), `${what}: vertex ${v}`);
      assert.deepEqual(Array.from(e.subarray(2, 6), (x) => Math.fround(x / 255)), Array.from(mesh.colors!.subarray(4 * v, 4 * v + 4)), `${what}: vertex ${v} colour`);
      // Positions are the node's.
      assert.deepEqual(Array.from(mesh.positions.subarray(3 * v, 3 * v + 3)), Array.from(pos.subarray(3 * mesh.nodes[v], 3 * mesh.nodes[v] + 3)));
    }
    // A chart out of range, or a node beyond the last level, has no entry.
    assert.equal(attributeEntry(a, looks.tables, player.replay.offsets, mesh.nodes[0], a.charts), null);
    assert.equal(attributeEntry(a, looks.tables, player.replay.offsets, player.replay.nodeCount, 0), null);
    // One primitive per material used, each with that material's triangles in mesh order.
    const used = [...new Set(mesh.triangleMaterial)].sort();
    assert.deepEqual(prims.map((p: any) => p.material), used, `${what}: materials`);
    for (const p of prims) {
      const want: number[] = [];
      mesh.triangleMaterial.forEach((m, t) => { if (m === p.material) want.push(...mesh.indices.subarray(3 * t, 3 * t + 3)); });
      assert.deepEqual(Array.from(accessor(glb, p.indices)), want, `${what}: material ${p.material} triangles`);
    }
  }
});

test("appearance without texture coordinates or colours (RobotExpressive): no Attributes chunks, the same normals and materials as the Rust decoder", async () => {
  const robot = join(root, "../shared/data/gltf/RobotExpressive.glb");
  if (!existsSync(robot)) throw new Error(`${robot} is absent: this test reads the real models in ../shared/data beside the repository`);
  const file = join(dir, "robot.pmc");
  execFileSync(bin, ["encode", "-q", robot, "-o", file, "--keyframe-interval", "8"]);
  const c = await open(file);
  const a = c.header.appearance!;
  assert.deepEqual([a.uvSets, a.colors, a.materials, a.charts], [0, false, 3, 3]);
  assert.ok(!c.index.some((e) => e.kind === ChunkKind.Attributes), "value-less attribute tables were written");
  const player = new Decoder(c, 0);
  await player.loadAppearance();
  for (const [frame, budget] of [[0, 200], [9, 1500], [20, 100000]]) {
    const out = join(dir, `robot-${frame}-${budget}.glb`);
    execFileSync(bin, ["decode", "-q", file, "--frame", String(frame), "--triangles", String(budget), "-o", out]);
    const glb = readGlb(out);
    await player.seek(frame);
    const pos = player.positions();
    player.replay.selectTriangles(budget, player.replay.splitBenefits(pos));
    const mesh = player.texturedMesh(pos);
    const prims = glb.json.meshes[0].primitives;
    const what = `frame ${frame} budget ${budget}`;
    assert.deepEqual(Array.from(mesh.positions), Array.from(accessor(glb, prims[0].attributes.POSITION)), `${what}: positions`);
    assert.deepEqual(Array.from(mesh.normals), Array.from(accessor(glb, prims[0].attributes.NORMAL)), `${what}: normals`);
    assert.equal(mesh.uv0, null);
    assert.deepEqual(prims.map((p: any) => p.material), [...new Set(mesh.triangleMaterial)].sort(), `${what}: materials`);
    for (const p of prims) {
      const want: number[] = [];
      mesh.triangleMaterial.forEach((m, t) => { if (m === p.material) want.push(...mesh.indices.subarray(3 * t, 3 * t + 3)); });
      assert.deepEqual(Array.from(accessor(glb, p.indices)), want, `${what}: material ${p.material} triangles`);
    }
  }
});

test("appearance with band 0's entries derived from the triangles, values from the band above and recent-chart runs, neighbour or grown charts (Fox, Horse): the same texture coordinates, colours and normals as the Rust decoder", async () => {
  for (const name of ["Fox", "Horse"]) {
    const glbIn = join(root, `../shared/data/gltf/${name}.glb`);
    if (!existsSync(glbIn)) throw new Error(`${glbIn} is absent: this test reads the real models in ../shared/data beside the repository`);
    const file = join(dir, `${name}-derived.pmc`);
    execFileSync(bin, ["encode", "-q", glbIn, "-o", file, "--keyframe-interval", "8"]);
    const c = await open(file);
    const a = c.header.appearance!;
    const band0 = await c.chunk(c.find(ChunkKind.Attributes, 0, 0));
    // Mode 1, or 1 | 8 with its residuals entropy-coded (rANS over their bit lengths); the
    // skinned Fox's with its texture coordinates placed by the bind pose (| 4), which reads
    // the Bind chunk of band 0.
    assert.ok(band0.length > 1 && band0[0] === 0 && (band0[1] & 3) === 1, `${name}: band 0 is not coded with derived entries`);
    // (Fox's residuals, small with bind positions, may be shorter as varints.)
    assert.ok(name === "Fox" || (band0[1] & 8) !== 0, `${name}: band 0's residuals are not rANS-coded`);
    assert.equal(needsBind(band0), name === "Fox", `${name}: band 0 ${name === "Fox" ? "does not predict" : "predicts"} from bind positions`);
    // Band 1's values are chart-wise differences (mode 2): the cuts below read that coding too.
    const chartsRaw = await c.chunk(c.find(ChunkKind.Charts, 0, 0));
    assert.ok(chartsRaw[0] === 0 && chartsRaw[1] >= 2 && chartsRaw[1] <= 4, `${name}: the charts are neither recent-chart runs nor neighbour nor grown charts`);
    // Recent-chart runs, neighbour or grown charts (modes 3 and 4, read with the triangles) cut
    // short or damaged: a DecodeError, never a crash; modes 3 and 4 without the triangles, an error.
    const { readCharts } = await import("../src/container/index.js");
    const h = c.header, tris3 = chartsRaw[1] >= 3 ? readTriangles(await c.chunk(c.find(ChunkKind.Triangles, 0, 0)), "t", h.triangleCount, h.vertexCount, c.version) : null;
    if (tris3) assert.throws(() => readCharts(chartsRaw, a, h.triangleCount), /without the triangles/);
    assert.throws(() => readCharts(chartsRaw.subarray(0, chartsRaw.length - 1), a, h.triangleCount, tris3), DecodeError);
    for (let at = 2; at < chartsRaw.length; at += Math.max(1, chartsRaw.length >> 5)) {
      try { readCharts(Uint8Array.from(chartsRaw, (b, i) => (i === at ? b ^ 0x5a : b)), a, h.triangleCount, tris3); } catch (e) { assert.ok(e instanceof DecodeError, `${name} charts byte ${at}: ${e}`); }
    }
    // Bands above 0 predict their values from the band above (mode 3) or chart-wise (mode 2):
    // the cuts below read those codings too.
    const modes: number[] = [];
    for (let j = 1; j < c.header.levelSizes.length; j++) { const b = await c.chunk(c.find(ChunkKind.Attributes, 0, j)); modes.push(b[0] === 0 ? b[1] & 7 : 0); }
    assert.ok(modes.includes(3), `${name}: no band predicted from the band above (${modes})`);
    const player = new Decoder(c, 0);
    await player.loadAppearance();
    for (const [frame, budget] of [[0, 100000], [5, 300], [11, 50]]) {
      const out = join(dir, `${name}-derived-${frame}-${budget}.glb`);
      execFileSync(bin, ["decode", "-q", file, "--frame", String(frame), "--triangles", String(budget), "-o", out]);
      const glb = readGlb(out);
      await player.seek(frame);
      const pos = player.positions();
      player.replay.selectTriangles(budget, player.replay.splitBenefits(pos));
      const mesh = player.texturedMesh(pos);
      const attr = glb.json.meshes[0].primitives[0].attributes;
      const what = `${name} frame ${frame} budget ${budget}`;
      assert.deepEqual(Array.from(mesh.positions), Array.from(accessor(glb, attr.POSITION)), `${what}: positions`);
      assert.deepEqual(Array.from(mesh.normals), Array.from(accessor(glb, attr.NORMAL)), `${what}: normals`);
      assert.deepEqual(Array.from(mesh.uv0!), Array.from(accessor(glb, attr.TEXCOORD_0)), `${what}: texture coordinates`);
      if (a.colors) assert.deepEqual(Array.from(mesh.colors!), Array.from(accessor(glb, attr.COLOR_0)), `${what}: colours`);
    }
    // A damaged residual stream is an error, not a crash: the payload cut short.
    const { readBand0Table } = await import("../src/container/index.js");
    const tris = (player as unknown as { triangles: Uint32Array }).triangles, chartOf = player.looks!.charts.triangleChart;
    // With represented values (mode | 16), band 0 reads band 1's table through frame 0's parents.
    const above = { parent: readKey(await c.chunk(c.find(ChunkKind.Key, 0, 0)), "k", c.header.levelSizes, 0, c.version), table: player.looks!.tables[1]! };
    let bind: BigInt64Array | null = null;
    if (needsBind(band0)) {
      const skins = nodeSkins(c.header.levelSizes[0]);
      readBinds(await c.chunk(c.find(ChunkKind.Bind, 0, 0)), "bind", c.header.levelSizes[0], c.header.skin!.paletteLen, skins, 0);
      bind = skins.bind;
      // Without them: an error, not other values.
      assert.throws(() => readBand0Table(band0, "band 0", c.header.levelSizes[0], a, tris, chartOf, above), /bind positions needed/);
    }
    const whole = readBand0Table(band0, "band 0", c.header.levelSizes[0], a, tris, chartOf, above, bind);
    assert.deepEqual(Array.from(whole.values), Array.from(player.looks!.tables[0]!.values));
    assert.throws(() => readBand0Table(band0.subarray(0, band0.length - 1), "band 0", c.header.levelSizes[0], a, tris, chartOf, above, bind), DecodeError);
    // An unknown coding mode is an error too.
    const odd = band0.slice();
    odd[1] = 7;
    assert.throws(() => readBand0Table(odd, "band 0", c.header.levelSizes[0], a, tris, chartOf, above, bind), /coding 7 unknown/);
  }
});

/**
 * A generated OBJ sequence for the appearance codings: a waving grid of w x h quads, every
 * corner its own `vt` (so charts meet along seams), quads in three materials by patches, and
 * texture coordinates either drawn from a palette of 8 x 8 values (repeated, as a low-poly
 * model on a palette texture) or all distinct. Deterministic from the seed.
 */
function texturedObjSequence(out: string, w: number, h: number, palette: boolean, seed: number): void {
  mkdirSync(out, { recursive: true });
  let x = seed >>> 0 || 1;
  const rnd = (): number => { x ^= x << 13; x >>>= 0; x ^= x >>> 17; x ^= x << 5; x >>>= 0; return x / 4294967296; };
  writeFileSync(join(out, "m.mtl"), "newmtl m0\nKd 1 0 0\nnewmtl m1\nKd 0 1 0\nnewmtl m2\nKd 0 0 1\n");
  const uvs: string[] = [];
  for (let q = 0; q < 4 * w * h; q++) {
    const [u, v] = palette ? [Math.floor(rnd() * 8) / 8, Math.floor(rnd() * 8) / 8] : [rnd(), rnd()];
    uvs.push(`vt ${u} ${v}`);
  }
  for (let f = 0; f < 3; f++) {
    const lines = ["mtllib m.mtl"];
    for (let j = 0; j <= h; j++) for (let i = 0; i <= w; i++) lines.push(`v ${i * 0.1} ${j * 0.1} ${0.2 * Math.sin(i * 0.3 + f * 0.5) * Math.cos(j * 0.2)}`);
    lines.push(...uvs);
    for (let j = 0, n = 1; j < h; j++) {
      for (let i = 0; i < w; i++, n += 4) {
        lines.push(`usemtl m${(Math.floor(i / 10) + Math.floor(j / 7)) % 3}`);
        const v = [j * (w + 1) + i + 1, j * (w + 1) + i + 2, (j + 1) * (w + 1) + i + 2, (j + 1) * (w + 1) + i + 1];
        lines.push(`f ${v[0]}/${n} ${v[1]}/${n + 1} ${v[2]}/${n + 2}`, `f ${v[0]}/${n} ${v[2]}/${n + 2} ${v[3]}/${n + 3}`);
      }
    }
    writeFileSync(join(out, `f${String(f).padStart(3, "0")}.obj`), lines.join("\n") + "\n");
  }
}

test("entropy-coded attribute residuals (mode | 8) on generated meshes with repeated and with all-distinct texture coordinates, seams and three materials: the same texture coordinates as the Rust decoder, bit for bit", async () => {
  let withRans = 0, checked = 0;
  for (const palette of [true, false]) {
    const name = palette ? "palette" : "distinct", frames = join(dir, `obj-${name}`), file = join(dir, `obj-${name}.pmc`);
    texturedObjSequence(frames, 30, 20, palette, palette ? 7 : 11);
    execFileSync(bin, ["encode", "-q", frames, "-o", file]);
    const c = await open(file);
    const a = c.header.appearance!;
    assert.equal(a.materials, 3);
    const modes: number[] = [];
    for (let j = 0; j < c.header.levelSizes.length; j++) { const b = await c.chunk(c.find(ChunkKind.Attributes, 0, j)); modes.push(b[0] === 0 && b.length > 1 ? b[1] : 0); }
    // (Represented values, mode | 16, may leave one input's tables all varints.)
    if (modes.some((m) => (m & 8) !== 0)) withRans++;
    const player = new Decoder(c, 0);
    await player.loadAppearance();
    for (const [frame, budget] of [[0, 100000], [1, 500], [2, 120]]) {
      const out = join(dir, `obj-${name}-${frame}-${budget}.glb`);
      execFileSync(bin, ["decode", "-q", file, "--frame", String(frame), "--triangles", String(budget), "-o", out]);
      const glb = readGlb(out);
      await player.seek(frame);
      const pos = player.positions();
      player.replay.selectTriangles(budget, player.replay.splitBenefits(pos));
      const mesh = player.texturedMesh(pos);
      // One primitive per material in the GLB, all over one vertex buffer.
      const attr = glb.json.meshes[0].primitives[0].attributes, what = `${name} frame ${frame} budget ${budget}`;
      assert.deepEqual(Array.from(mesh.positions), Array.from(accessor(glb, attr.POSITION)), `${what}: positions`);
      assert.deepEqual(Array.from(mesh.uv0!), Array.from(accessor(glb, attr.TEXCOORD_0)), `${what}: texture coordinates`);
    }
    // Every band's table cut short or with a flipped byte in its residuals: an error, never a crash.
    for (let j = 0; j < c.header.levelSizes.length; j++) {
      const raw = await c.chunk(c.find(ChunkKind.Attributes, 0, j));
      // (Tables predicted from the band above or with represented values need that band and
      // frame 0's parents: skipped here, read by the represented-values test.)
      if (!(raw[0] === 0 && (raw[1] & 8)) || (raw[1] & 7) === 3 || (raw[1] & 16)) continue;
      const tris = (player as unknown as { triangles: Uint32Array }).triangles, chartOf = player.looks!.charts.triangleChart;
      const read = (b: Uint8Array): unknown => j === 0
        ? readBand0Table(b, "band 0", c.header.levelSizes[0], a, tris, chartOf)
        : readTable(b, `band ${j}`, c.header.levelSizes[j], a, c.header.triangleCount);
      assert.deepEqual(Array.from((read(raw) as { values: Int32Array }).values), Array.from(player.looks!.tables[j]!.values));
      assert.throws(() => read(raw.subarray(0, raw.length - 1)), DecodeError, `${name} band ${j} cut short`);
      for (let at = 2; at < raw.length; at += Math.max(1, raw.length >> 4)) {
        try { read(Uint8Array.from(raw, (b, i) => (i === at ? b ^ 0x5a : b))); } catch (e) { assert.ok(e instanceof DecodeError, `${name} band ${j} byte ${at}: ${e}`); }
      }
      checked++;
    }
  }
  assert.ok(withRans > 0 && checked > 0, `${withRans} inputs with rANS-coded residuals, ${checked} such tables read alone`);
});

/**
 * A generated OBJ sequence of a UV-mapped cylinder: `seg` x `rings` vertices, its side
 * unrolled with a seam where u wraps from 1 back to 0 (the seam column's own `vt`), bending a
 * little from frame to frame. Deterministic.
 */
function cylinderObjSequence(out: string, seg: number, rings: number): void {
  mkdirSync(out, { recursive: true });
  const vts: string[] = [];
  for (let r = 0; r < rings; r++) for (let s = 0; s <= seg; s++) vts.push(`vt ${s / seg} ${r / (rings - 1)}`);
  for (let f = 0; f < 3; f++) {
    const lines: string[] = [];
    for (let r = 0; r < rings; r++) {
      for (let s = 0; s < seg; s++) {
        const a = (2 * Math.PI * s) / seg, y = r * 0.1;
        lines.push(`v ${Math.cos(a) * 0.5 + 0.05 * f * Math.sin(y)} ${y} ${Math.sin(a) * 0.5}`);
      }
    }
    lines.push(...vts);
    for (let r = 0; r + 1 < rings; r++) {
      for (let s = 0; s < seg; s++) {
        const v = (rr: number, ss: number): number => rr * seg + (ss % seg) + 1, t = (rr: number, ss: number): number => rr * (seg + 1) + ss + 1;
        lines.push(`f ${v(r, s)}/${t(r, s)} ${v(r, s + 1)}/${t(r, s + 1)} ${v(r + 1, s + 1)}/${t(r + 1, s + 1)}`);
        lines.push(`f ${v(r, s)}/${t(r, s)} ${v(r + 1, s + 1)}/${t(r + 1, s + 1)} ${v(r + 1, s)}/${t(r + 1, s)}`);
      }
    }
    writeFileSync(join(out, `f${String(f).padStart(3, "0")}.obj`), lines.join("\n") + "\n");
  }
}

test("represented attribute values (mode | 16) and entries from the band above (mode | 32) on a seamed cylinder, seamed grids with repeated and distinct values and a mesh with colours: every level's tables and a cut's texture coordinates and colours as the Rust decoder's, bit for bit", async () => {
  const horse = join(root, "../shared/data/gltf/Horse.glb");
  if (!existsSync(horse)) throw new Error(`${horse} is absent: this test reads the real models in ../shared/data beside the repository`);
  const cylinder = join(dir, "obj-cylinder"), palette = join(dir, "obj-rep-palette"), distinct = join(dir, "obj-rep-distinct");
  cylinderObjSequence(cylinder, 32, 24);
  texturedObjSequence(palette, 24, 16, true, 5);
  texturedObjSequence(distinct, 24, 16, false, 9);
  let represented = 0, entriesAbove = 0;
  for (const [name, input] of [["cylinder", cylinder], ["palette", palette], ["distinct", distinct], ["horse", horse]]) {
    const file = join(dir, `rep-${name}.pmc`);
    execFileSync(bin, ["encode", "-q", input, "-o", file]);
    const c = await open(file), a = c.header.appearance!, levels = c.header.levelSizes.length;
    const raws: Uint8Array[] = [];
    for (let j = 0; j < levels; j++) raws.push(await c.chunk(c.find(ChunkKind.Attributes, 0, j)));
    const modes = raws.map((b) => (b[0] === 0 && b.length > 1 ? b[1] : 0));
    if (modes.some((m) => (m & 16) !== 0)) represented++;
    if (modes.some((m) => (m & 32) !== 0)) entriesAbove++;
    const player = new Decoder(c, 0);
    await player.loadAppearance();
    for (const [frame, budget] of [[0, 100000], [1, 400], [2, 80]]) {
      const out = join(dir, `rep-${name}-${frame}-${budget}.glb`);
      execFileSync(bin, ["decode", "-q", file, "--frame", String(frame), "--triangles", String(budget), "-o", out]);
      const glb = readGlb(out);
      await player.seek(frame);
      const pos = player.positions();
      player.replay.selectTriangles(budget, player.replay.splitBenefits(pos));
      const mesh = player.texturedMesh(pos);
      const attr = glb.json.meshes[0].primitives[0].attributes, what = `${name} frame ${frame} budget ${budget}`;
      assert.deepEqual(Array.from(mesh.uv0!), Array.from(accessor(glb, attr.TEXCOORD_0)), `${what}: texture coordinates`);
      if (a.colors) assert.deepEqual(Array.from(mesh.colors!), Array.from(accessor(glb, attr.COLOR_0)), `${what}: colours`);
    }
    // Each represented table alone, with the band above and frame 0's parents: the player's
    // values; without the band above, cut short or damaged, an error and never a crash.
    const tris = (player as unknown as { triangles: Uint32Array }).triangles, chartOf = player.looks!.charts.triangleChart;
    for (let j = 0; j < levels; j++) {
      if ((modes[j] & 16) === 0) continue;
      const parent = readKey(await c.chunk(c.find(ChunkKind.Key, 0, j)), "k", c.header.levelSizes, j, c.version);
      const above = { parent, table: player.looks!.tables[j + 1]! };
      // (Values across the band's faces, mode | 64, need them too: the values-across test.)
      const faces = needsFaces(raws[j]) ? bandFaces(tris, chartOf, await frame0Parents(c, j), "f") : null;
      const read = (b: Uint8Array, up: typeof above | null = above): { values: Int32Array } => j === 0
        ? readBand0Table(b, "band 0", c.header.levelSizes[0], a, tris, chartOf, up)
        : readTable(b, `band ${j}`, c.header.levelSizes[j], a, c.header.triangleCount, up, faces);
      assert.deepEqual(Array.from(read(raws[j]).values), Array.from(player.looks!.tables[j]!.values), `${name} band ${j}`);
      assert.throws(() => read(raws[j], null), DecodeError, `${name} band ${j} without the band above`);
      assert.throws(() => read(raws[j].subarray(0, raws[j].length - 1)), DecodeError, `${name} band ${j} cut short`);
      for (let at = 1; at < raws[j].length; at += Math.max(1, raws[j].length >> 5)) {
        try { read(Uint8Array.from(raws[j], (b, i) => (i === at ? b ^ 0x5a : b))); } catch (e) { assert.ok(e instanceof DecodeError, `${name} band ${j} byte ${at}: ${e}`); }
      }
    }
  }
  assert.ok(represented >= 3, `only ${represented} of 4 inputs took represented values`);
  assert.ok(entriesAbove >= 2, `only ${entriesAbove} of 4 inputs took entries from the band above (mode | 32)`);
});

/** Frame 0's parent maps of levels 0..j (its Key chunks of bands 0..j-1), finest first. */
async function frame0Parents(c: Reader, j: number): Promise<Uint32Array[]> {
  const out: Uint32Array[] = [];
  for (let i = 0; i < j; i++) out.push(readKey(await c.chunk(c.find(ChunkKind.Key, 0, i)), `k${i}`, c.header.levelSizes, i, c.version));
  return out;
}

/**
 * A generated OBJ sequence of a grid of w x h quads whose texture is `charts` islands side by
 * side (the grid's columns split into that many charts, each its own `vt`s along the seams),
 * each island mapped smoothly with a gentle distortion, waving from frame to frame. Deterministic.
 */
function islandsObjSequence(out: string, w: number, h: number, charts: number): void {
  mkdirSync(out, { recursive: true });
  const vts: string[] = [], vt = new Map<string, number>();
  const uv = (i: number, j: number, k: number): number => {
    const id = `${i},${j},${k}`;
    if (!vt.has(id)) {
      const u = (k + 0.05 + (0.9 * (i - (k * w) / charts)) / (w / charts + 1) + 0.01 * Math.sin(j * 0.7)) / charts;
      vts.push(`vt ${u} ${(j + 0.3 * Math.sin(i * 0.4)) / (h + 1)}`);
      vt.set(id, vts.length);
    }
    return vt.get(id)!;
  };
  const faces: string[] = [];
  for (let j = 0; j < h; j++) {
    for (let i = 0; i < w; i++) {
      const k = Math.floor((i * charts) / w), v = [j * (w + 1) + i + 1, j * (w + 1) + i + 2, (j + 1) * (w + 1) + i + 2, (j + 1) * (w + 1) + i + 1];
      const t = [uv(i, j, k), uv(i + 1, j, k), uv(i + 1, j + 1, k), uv(i, j + 1, k)];
      faces.push(`f ${v[0]}/${t[0]} ${v[1]}/${t[1]} ${v[2]}/${t[2]}`, `f ${v[0]}/${t[0]} ${v[2]}/${t[2]} ${v[3]}/${t[3]}`);
    }
  }
  for (let f = 0; f < 3; f++) {
    const lines: string[] = [];
    for (let j = 0; j <= h; j++) for (let i = 0; i <= w; i++) lines.push(`v ${i * 0.1} ${j * 0.1} ${0.15 * Math.sin(i * 0.25 + f * 0.4) * Math.cos(j * 0.3)}`);
    writeFileSync(join(out, `f${String(f).padStart(3, "0")}.obj`), [...lines, ...vts, ...faces].join("\n") + "\n");
  }
}

test("attribute values across a band's faces (mode 3 | 64, band 0's 1 | 16 | 64) and neighbour or grown charts (Charts modes 3, 4) on generated seamed meshes with several charts, a cylinder, Horse and Fox: every level's tables and cuts' texture coordinates and colours as the Rust decoder's, bit for bit, at every finest level", async () => {
  const horse = join(root, "../shared/data/gltf/Horse.glb");
  if (!existsSync(horse)) throw new Error(`${horse} is absent: this test reads the real models in ../shared/data beside the repository`);
  const islands = join(dir, "obj-islands"), cylinder = join(dir, "obj-across-cylinder");
  islandsObjSequence(islands, 36, 24, 5);
  cylinderObjSequence(cylinder, 40, 28);
  const fox = join(root, "../shared/data/gltf/Fox.glb");
  if (!existsSync(fox)) throw new Error(`${fox} is absent: this test reads the real models in ../shared/data beside the repository`);
  let across = 0, band0Across = 0, neighbourCharts = 0, grownCharts = 0;
  for (const [name, input] of [["islands", islands], ["cylinder", cylinder], ["horse", horse], ["fox", fox]]) {
    const file = join(dir, `across-${name}.pmc`);
    execFileSync(bin, ["encode", "-q", input, "-o", file]);
    const c = await open(file), a = c.header.appearance!, levels = c.header.levelSizes.length;
    const raws: Uint8Array[] = [];
    for (let j = 0; j < levels; j++) raws.push(await c.chunk(c.find(ChunkKind.Attributes, 0, j)));
    const player = new Decoder(c, 0);
    await player.loadAppearance();
    for (const [frame, budget] of [[0, 100000], [1, 300], [2, 60]]) {
      const out = join(dir, `across-${name}-${frame}-${budget}.glb`);
      execFileSync(bin, ["decode", "-q", file, "--frame", String(frame), "--triangles", String(budget), "-o", out]);
      const glb = readGlb(out);
      await player.seek(frame);
      const pos = player.positions();
      player.replay.selectTriangles(budget, player.replay.splitBenefits(pos));
      const mesh = player.texturedMesh(pos);
      const attr = glb.json.meshes[0].primitives[0].attributes, what = `${name} frame ${frame} budget ${budget}`;
      assert.deepEqual(Array.from(mesh.uv0!), Array.from(accessor(glb, attr.TEXCOORD_0)), `${what}: texture coordinates`);
      if (a.colors) assert.deepEqual(Array.from(mesh.colors!), Array.from(accessor(glb, attr.COLOR_0)), `${what}: colours`);
    }
    // A coarse client (finest level L) reads bands L.. and decodes them as a full one does.
    for (let L = 1; L < levels; L++) {
      const coarse = new Decoder(c, L);
      await coarse.loadAppearance();
      for (let j = L; j < levels; j++) assert.deepEqual(Array.from(coarse.looks!.tables[j]!.values), Array.from(player.looks!.tables[j]!.values), `${name} level ${L} band ${j}`);
    }
    const tris = (player as unknown as { triangles: Uint32Array }).triangles, chartOf = player.looks!.charts.triangleChart;
    const chartsRaw = await c.chunk(c.find(ChunkKind.Charts, 0, 0));
    if (chartsNeedTriangles(chartsRaw)) {
      // Neighbour or grown charts (Charts mode 3 or 4): with the triangles, the player's charts;
      // without, cut short or damaged, a DecodeError.
      neighbourCharts++;
      if (chartsRaw[1] === 4) grownCharts++;
      assert.deepEqual(Array.from(readCharts(chartsRaw, a, c.header.triangleCount, tris).triangleChart), Array.from(chartOf), `${name} charts`);
      assert.throws(() => readCharts(chartsRaw, a, c.header.triangleCount), /without the triangles/);
      assert.throws(() => readCharts(chartsRaw.subarray(0, chartsRaw.length - 1), a, c.header.triangleCount, tris), DecodeError);
      for (let at = 2; at < chartsRaw.length; at += Math.max(1, chartsRaw.length >> 5)) {
        try { readCharts(Uint8Array.from(chartsRaw, (b, i) => (i === at ? b ^ 0x5a : b)), a, c.header.triangleCount, tris); } catch (e) { assert.ok(e instanceof DecodeError, `${name} charts byte ${at}: ${e}`); }
      }
    }
    if (needsFaces(raws[0]) && levels > 1) {
      // Band 0 across the triangles (mode 1 | 16 | 64): derived entries, the band above needed.
      band0Across++;
      assert.equal(raws[0][1] & ~8, 1 | 16 | 64);
      const above = { parent: readKey(await c.chunk(c.find(ChunkKind.Key, 0, 0)), "k", c.header.levelSizes, 0, c.version), table: player.looks!.tables[1]! };
      const read = (b: Uint8Array, up: typeof above | null = above): Int32Array => readBand0Table(b, "band 0", c.header.levelSizes[0], a, tris, chartOf, up).values;
      assert.deepEqual(Array.from(read(raws[0])), Array.from(player.looks!.tables[0]!.values), `${name} band 0`);
      assert.throws(() => read(raws[0], null), DecodeError, `${name} band 0 without the band above`);
      assert.throws(() => read(raws[0].subarray(0, raws[0].length - 1)), DecodeError, `${name} band 0 cut short`);
      for (let at = 1; at < raws[0].length; at += Math.max(1, raws[0].length >> 5)) {
        try { read(Uint8Array.from(raws[0], (b, i) => (i === at ? b ^ 0x5a : b))); } catch (e) { assert.ok(e instanceof DecodeError, `${name} band 0 byte ${at}: ${e}`); }
      }
    }
    for (let j = 1; j < levels; j++) {
      if (!needsFaces(raws[j])) continue;
      across++;
      const parents = await frame0Parents(c, j);
      const parent = readKey(await c.chunk(c.find(ChunkKind.Key, 0, j)), "k", c.header.levelSizes, j, c.version);
      const above = { parent, table: player.looks!.tables[j + 1]! }, faces = bandFaces(tris, chartOf, parents, "f");
      const read = (b: Uint8Array, f: Faces | null = faces): Int32Array => readTable(b, `band ${j}`, c.header.levelSizes[j], a, c.header.triangleCount, above, f).values;
      assert.deepEqual(Array.from(read(raws[j])), Array.from(player.looks!.tables[j]!.values), `${name} band ${j}`);
      assert.throws(() => read(raws[j], null), /without its faces/, `${name} band ${j} without its faces`);
      assert.throws(() => read(raws[j].subarray(0, raws[j].length - 1)), DecodeError, `${name} band ${j} cut short`);
      for (let at = 1; at < raws[j].length; at += Math.max(1, raws[j].length >> 5)) {
        try { read(Uint8Array.from(raws[j], (b, i) => (i === at ? b ^ 0x5a : b))); } catch (e) { assert.ok(e instanceof DecodeError, `${name} band ${j} byte ${at}: ${e}`); }
      }
      // A parent map missing a node is a DecodeError naming it.
      assert.throws(() => bandFaces(tris, chartOf, [parents[0].subarray(0, 3)], "band faces"), /misses a node/);
    }
  }
  assert.ok(across >= 2 && band0Across >= 1, `only ${across} tables above band 0 and ${band0Across} of band 0 took values across their band's faces`);
  assert.ok(neighbourCharts >= 2, `only ${neighbourCharts} of 4 inputs took neighbour or grown charts`);
  assert.ok(grownCharts >= 2, `only ${grownCharts} of 4 inputs took grown charts`);
});

test("a skinned glTF's stream (version 7): every frame's input vertices equal the Rust decoder's, and coarse clients agree", async () => {
  const fox = join(root, "../shared/data/gltf/Fox.glb");
  if (!existsSync(fox)) throw new Error(`${fox} is absent: this test reads the real models in ../shared/data beside the repository`);
  const file = join(dir, "fox.pmc");
  execFileSync(bin, ["encode", "-q", fox, "-o", file, "--keyframe-interval", "8", "--quant-bits", "12"]);
  const c = await sameAsRust(file, "fox");
  assert.equal(c.version, 7);
  assert.ok(c.header.skin !== null && c.header.skin.paletteLen > 0, "the stream carries a skin");
  // Coarse nodes sit at their skinned positions, so most coarse bands' residuals are all zero
  // and coded sparsely (coding 2: the first byte is shift + 64), which sameAsRust has read.
  let sparse = 0, coarseChunks = 0;
  for (const e of c.index.filter((x) => x.kind === ChunkKind.Positions && x.band > 0)) {
    coarseChunks++;
    if (Math.floor((await c.chunk(e))[0] / 32) === 2) sparse++;
  }
  assert.ok(sparse > coarseChunks / 2, `${sparse} of ${coarseChunks} coarse positions chunks sparse`);
  // A client stopping at level 1 decodes the same positions for bands 1.. as a full one.
  const full = new Decoder(c, 0), coarse = new Decoder(c, 1);
  const from = 3 * c.header.levelSizes[0];
  for (let f = 0; f < c.header.frameCount; f += 5) {
    await full.seek(f);
    await coarse.seek(f);
    assert.deepEqual(Array.from(coarse.current.subarray(from)), Array.from(full.current.subarray(from)), `frame ${f}`);
  }
});

test("a fitted skin (encode --fit-skin --keep-skin on an OBJ sequence, issue 19): every frame's input vertices equal the Rust decoder's", async () => {
  const file = join(dir, "tube-fitted.pmc");
  execFileSync(bin, ["encode", "-q", join(dir, "frames"), "-o", file, "--keyframe-interval", "8", "--quant-bits", "12", "--fit-skin", "--keep-skin"]);
  const c = await sameAsRust(file, "fitted");
  assert.ok(c.header.skin !== null && c.header.skin.paletteLen > 1, "the stream carries the fitted bones");
  assert.ok(c.index.some((e) => e.kind === ChunkKind.Joints), "the fitted bones' poses go in Joints chunks");
});

test("sparse positions chunks: listed nodes after their gaps, the rest zero; damage is a DecodeError", () => {
  // Shift 3, two listed nodes of five: node 1 (gap 1) with (1, -1, 0), node 4 (gap 2) with (0, 0, 64).
  const raw = Uint8Array.from([3 + 64, 2, 1, 2, 1, 0, 2, 0, 0, 128, 1]);
  const { shift, res } = readPositions(raw, "p", 5);
  assert.equal(shift, 3);
  assert.deepEqual(Array.from(res), [0, 0, 0, 1, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 64]);
  assert.deepEqual(Array.from(readPositions(Uint8Array.from([64, 0]), "p", 4).res), new Array(12).fill(0));
  assert.throws(() => readPositions(raw, "band 2 positions", 4), /band 2 positions: listed node 4 beyond the band's 4/);
  assert.throws(() => readPositions(Uint8Array.from([64, 9, 0, 0, 0, 0]), "p", 20), /9 listed nodes in 4 bytes/);
  assert.throws(() => readPositions(Uint8Array.from([64, 0, 0]), "p", 20), /1 bytes left over/);
  assert.throws(() => readPositions(Uint8Array.from([96, 0]), "p", 20), /residual coding 3/);
});

test("a lenient textured mesh fills in (node, chart) entries a budget cut reaches but the tables lack, and counts them", async () => {
  const fox = join(root, "../shared/data/gltf/Fox.glb");
  if (!existsSync(fox)) throw new Error(`${fox} is absent: this test reads the real models in ../shared/data beside the repository`);
  const file = join(dir, "fox-lenient.pmc");
  execFileSync(bin, ["encode", "-q", fox, "-o", file]);
  const c = await open(file), a = c.header.appearance!;
  const d = new Decoder(c, 0);
  await d.loadAppearance();
  await d.seek(0);
  const pos = d.positions();
  for (const share of [1, 0.5, 0.25, 0.1]) {
    const budget = Math.round(c.header.triangleCount * share);
    d.replay.selectTriangles(budget, d.replay.splitBenefits(pos));
    const r = d.replay, rep = r.cutNodes(), base = r.offsets[r.minLevel];
    const shown = Uint32Array.from(r.appearing), cut = new Uint32Array(3 * shown.length);
    shown.forEach((t, i) => { for (let k = 0; k < 3; k++) cut[3 * i + k] = rep[base + r.corners[3 * t + k]]; });
    const looks = d.looks!;
    const mesh = texturedMesh(a, looks.charts, looks.tables, r.offsets, pos, shown, cut, { lenient: true });
    const nv = mesh.nodes.length;
    let absent = 0;
    for (let v = 0; v < nv; v++) {
      const e = attributeEntry(a, looks.tables, r.offsets, mesh.nodes[v], mesh.charts[v]);
      if (!e) { absent++; continue; }
      // Present entries are drawn as they are.
      assert.equal(mesh.uv0![2 * v], Math.fround(dequantizeUv(a, 0, e[0])));
    }
    assert.equal(mesh.missing, absent, `budget ${budget}: missing entries counted`);
    assert.equal(mesh.indices.length, 3 * shown.length, "every triangle drawn");
    for (const x of mesh.uv0!) assert.ok(Number.isFinite(x));
    // Strict (the specification's reading): the same mesh when nothing is missing, else a DecodeError.
    if (absent === 0) assert.deepEqual(Array.from(texturedMesh(a, looks.charts, looks.tables, r.offsets, pos, shown, cut).uv0!), Array.from(mesh.uv0!));
    else assert.throws(() => texturedMesh(a, looks.charts, looks.tables, r.offsets, pos, shown, cut), DecodeError);
    if (share === 1) assert.equal(absent, 0, "the whole mesh has every entry");
  }
});

test("skinned streams' palettes: the encoder writes Joints chunks, and streams with the older Palette or Pose chunks still read as Rust reads them", async () => {
  const fox = join(root, "../shared/data/gltf/Fox.glb");
  const file = join(dir, "fox-palette.pmc");
  execFileSync(bin, ["encode", "-q", fox, "-o", file, "--keyframe-interval", "8", "--quant-bits", "12"]);
  const c = await open(file);
  assert.ok(c.index.some((e) => e.kind === ChunkKind.Joints) && !c.index.some((e) => e.kind === ChunkKind.Pose || e.kind === ChunkKind.Palette));
  // Today's files leave empty Delta and Corners chunks out, store small chunks as they are and
  // front-code their frame names (sameAsRust reads the Fox stream so in the test above), and
  // group their index by band (FLAG_BANDS, 8, the default where it is no longer); older files
  // have none of these flags.
  assert.equal(c.flags, 7 | 8);
  assert.ok(c.index.filter((e) => e.kind === ChunkKind.Delta).length < c.header.frameCount * c.header.levelSizes.length);
  assert.ok(c.index.some((e) => e.storedLen === e.rawLen));
  // The top band has one in every frame: it carries the band mask to every client.
  const top = c.header.levelSizes.length - 1;
  assert.equal(c.index.filter((e) => e.kind === ChunkKind.Joints && e.band === top).length, c.header.frameCount);
  const palette = join(root, "crates/pmcodec-container/tests/compat/v6-skinned-palette-tube-k4.pmc");
  const p = await sameAsRust(palette, "old-palette");
  assert.ok(p.index.some((e) => e.kind === ChunkKind.Palette) && !p.index.some((e) => e.kind === ChunkKind.Joints));
  const old = join(root, "crates/pmcodec-container/tests/corpus/valid-skinned-tube-k4.pmc");
  const o = await sameAsRust(old, "old-pose");
  assert.ok(o.index.some((e) => e.kind === ChunkKind.Pose) && !o.index.some((e) => e.kind === ChunkKind.Palette));
  assert.equal(o.flags, 0);
});

test("Joints chunks in the linked and the compact coding (a deep skeleton with rigid mesh nodes) decode as Rust decodes them", async () => {
  const robot = join(root, "../shared/data/gltf/RobotExpressive.glb");
  const file = join(dir, "robot-linked.pmc");
  execFileSync(bin, ["encode", "-q", robot, "-o", file, "--animation", "0", "--fps", "10", "--keyframe-interval", "8", "--quant-bits", "12"]);
  const c = await sameAsRust(file, "robot-linked");
  // Chunks in the linked coding start their bits with 31 after the band mask (one byte here),
  // those in the compact coding with 30; the encoder writes each chunk in the shortest coding.
  let linked = 0, compact = 0;
  for (const e of c.index.filter((x) => x.kind === ChunkKind.Joints)) {
    const tag = (await c.chunk(e))[1] & 31;
    if (tag === 31) linked++;
    if (tag === 30) compact++;
  }
  assert.ok(linked + compact > 0, "some Joints chunks are in the linked codings");
  assert.ok(compact > 0, "some Joints chunks are in the compact coding");
});

test("a damaged Joints chunk is refused with a DecodeError naming it", async () => {
  const fox = join(root, "../shared/data/gltf/Fox.glb");
  const file = join(dir, "fox-joints.pmc");
  execFileSync(bin, ["encode", "-q", fox, "-o", file, "--keyframe-interval", "8", "--quant-bits", "12"]);
  const c = await open(file);
  // Frame 1's Joints chunk of the top band, read past its checksum and cut short or lengthened.
  const e = c.index.find((x) => x.kind === ChunkKind.Joints && x.frame === 1)!;
  assert.ok(e, "frame 1 has Joints chunks");
  const raw = await c.chunk(e);
  const d = new Decoder(c, 0);
  await d.seek(0);
  const skin = (d as unknown as { skin: { readJoints: (...a: unknown[]) => bigint; bands: number[][] } }).skin;
  const out = new BigInt64Array(c.header.skin!.paletteLen * 12), rig = new Array(c.header.skin!.paletteLen).fill(null), links = new Array(c.header.skin!.paletteLen).fill({ reference: -1, pivot: [0n, 0n, 0n] });
  assert.throws(() => skin.readJoints(raw.subarray(0, raw.length - 1), "frame 1 band x joints", skin.bands, e.band, c.header.levelSizes.length, false, out, rig, links), (err: unknown) => err instanceof DecodeError && /frame 1 band x joints: ends inside its bits/.test(String(err)));
  const longer = new Uint8Array(raw.length + 1);
  longer.set(raw);
  assert.throws(() => skin.readJoints(longer, "j", skin.bands, e.band, c.header.levelSizes.length, false, out, rig, links), /1 bytes left over/);
  assert.equal(skin.readJoints(raw, "j", skin.bands, e.band, c.header.levelSizes.length, false, out, rig, links) >= 0n, true);
});

test("banded index (FLAG_BANDS): every frame as the Rust decoder's; a reader opened for a level fetches only its groups and decodes its bands as a whole one; damage to the table or a group is a DecodeError naming it", async () => {
  const frames = join(dir, "frames-banded");
  execFileSync(bin, ["sample", "twisting-tube", "-o", frames, "--frames", "40"]);
  const file = join(dir, "tube-banded.pmc");
  execFileSync(bin, ["encode", "-q", frames, "-o", file, "--keyframe-interval", "8", "--quant-bits", "12", "--banded-index"]);
  const whole = await sameAsRust(file, "banded");
  assert.equal(whole.flags & FLAG_BANDS, FLAG_BANDS, "the encoder bands a 40-frame tube's index");
  const bytes = new Uint8Array(readFileSync(file));
  const levels = whole.header.levelSizes.length;
  assert.ok(levels >= 3, `${levels} levels`);
  for (let level = 1; level < levels; level++) {
    const part = await Reader.open(async (o, n) => bytes.slice(o, o + n), bytes.length, level);
    assert.ok(part.bytesRead < whole.dataStart, `level ${level}: ${part.bytesRead} bytes of preamble, header and index, of ${whole.dataStart}`);
    // It holds the entries of every chunk a client of its level reads.
    for (const e of whole.index.filter((x) => whole.reads(x, level))) assert.ok(part.index.some((x) => JSON.stringify(x) === JSON.stringify(e)), `level ${level}: frame ${e.frame} band ${e.band} ${ChunkKind[e.kind]}`);
    assert.throws(() => new Decoder(part, level - 1), DecodeError);
    const a = new Decoder(await open(file), level), b = new Decoder(part, level);
    const from = 3 * whole.header.levelSizes.slice(0, level).reduce((x, y) => x + y, 0);
    for (let f = 0; f < whole.header.frameCount; f += 3) {
      await a.seek(f);
      await b.seek(f);
      assert.deepEqual(Array.from(b.current.subarray(from)), Array.from(a.current.subarray(from)), `level ${level} frame ${f}`);
    }
  }
  const dv = new DataView(bytes.buffer, bytes.byteOffset);
  const tableAt = 32 + dv.getUint32(12, true), tableLen = dv.getUint32(28, true);
  const rows = parseTable(bytes.subarray(tableAt, tableAt + tableLen), levels);
  const damaged = (at: number): Promise<Reader> => {
    const b = bytes.slice();
    b[at] ^= 1;
    return Reader.open(async (o, n) => b.slice(o, o + n), b.length);
  };
  await assert.rejects(damaged(tableAt + 1), /index table: checksum mismatch/);
  let at = tableAt + tableLen, seen = 0;
  for (let g = 0; g < rows.length; g++) {
    if (rows[g].bodyLen > 0) {
      await assert.rejects(damaged(at + rows[g].bodyLen - 1), new RegExp(`index group ${g} \\(.*\\): checksum mismatch`));
      seen++;
    }
    at += rows[g].bodyLen;
  }
  assert.ok(seen > 3, `${seen} groups`);
});
