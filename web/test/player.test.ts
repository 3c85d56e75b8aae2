// The player's worker side without a browser: the byte-range cache (each byte fetched once,
// adjacent chunks in one request, the memory limit) and the session over a real container
// (one request per frame, loops fetch nothing again, a lowered budget stops fetching finer
// bands at the next keyframe, one normal per vertex); and the built package's entry point.
import { test } from "node:test";
import { pmcodecBin, repoRoot, scratchDir } from "./paths.js";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { ChunkKind, Decoder, NONE, Reader, VERSION } from "../src/container/index.js";
import { morphAttributeStarts } from "../src/geomorph.js";
import type { Materials, TextureRef } from "../src/container/appearance.js";
import { httpRanges, RangeCache, type FetchRanges } from "../src/player/ranges.js";
import { Session } from "../src/player/session.js";

const root = repoRoot();
const bin = pmcodecBin(root);

/**
 * A range source over bytes in memory that answers several ranges at once and records every
 * request: `calls` the ranges of each request, `log` every range asked.
 */
function recorder(bytes: Uint8Array): { fetch: FetchRanges; log: [number, number][]; calls: [number, number][][] } {
  const log: [number, number][] = [], calls: [number, number][][] = [];
  const fetch: FetchRanges = async (ranges) => {
    const asked = ranges.map(([s, e]): [number, number] => [s, Math.min(e, bytes.length)]);
    calls.push(asked);
    log.push(...asked);
    await new Promise((r) => setTimeout(r, 1));
    return { parts: asked.map(([s, e]) => ({ start: s, bytes: bytes.slice(s, e) })), total: bytes.length };
  };
  return { fetch, log, calls };
}

/** Bytes fetched more than once in a request log. */
function twice(log: [number, number][], len: number): number {
  const seen = new Uint8Array(len);
  let again = 0;
  for (const [s, e] of log) for (let i = s; i < e; i++) if (seen[i]++) again++;
  return again;
}

test("range cache: a range that begins inside a held span asks for the rest only, and reads from one span", async () => {
  // The first read of a file ends where its length falls, often inside a chunk.
  const bytes = Uint8Array.from({ length: 1000 }, (_, i) => (i * 7) & 0xff);
  const { fetch, log } = recorder(bytes);
  const c = new RangeCache(fetch, 1 << 20);
  await c.ensure([[0, 100]]);
  await c.ensure([[90, 150]]);
  assert.deepEqual(log, [[0, 100], [100, 150]]);
  assert.deepEqual(Array.from(await c.read(90, 60)), Array.from(bytes.subarray(90, 150)));
  assert.deepEqual(Array.from(await c.read(0, 150)), Array.from(bytes.subarray(0, 150)));
  assert.equal(log.length, 2, "the reads came from the joined span");
  assert.equal(c.size, 150);
});

test("range cache: adjacent ranges share a request, nothing is fetched twice, waiting reads share one request", async () => {
  const bytes = Uint8Array.from({ length: 1000 }, (_, i) => i & 0xff);
  const { fetch, log, calls } = recorder(bytes);
  const c = new RangeCache(fetch, 1 << 20);
  await c.ensure([[10, 20], [20, 35], [50, 60]]);
  assert.deepEqual(calls, [[[10, 35], [50, 60]]], "adjacent ranges merged, disjoint ones in one request");
  // Two readers of one missing range at once: one request.
  const [a, b] = await Promise.all([c.read(100, 10), c.read(102, 4)]);
  assert.deepEqual(Array.from(b), [102, 103, 104, 105]);
  assert.equal(a.length, 10);
  await c.ensure([[10, 35], [12, 14], [50, 60]]);
  assert.equal(calls.length, 2, `requests: ${JSON.stringify(calls)}`);
  assert.equal(c.requests, 2);
  assert.equal(twice(log, bytes.length), 0);
  assert.equal(c.fetched, 25 + 10 + 10);
});

test("range cache: a host that sends the whole file is asked once", async () => {
  const bytes = Uint8Array.from({ length: 5000 }, (_, i) => i & 0xff);
  let calls = 0;
  const c = new RangeCache(async () => { calls++; return { parts: [{ start: 0, bytes: bytes.slice() }], total: bytes.length }; });
  assert.deepEqual(Array.from(await c.read(300, 3)), [300 & 0xff, 301 & 0xff, 302 & 0xff]);
  await c.ensure([[4000, 4100], [10, 20]]);
  assert.deepEqual(Array.from(await c.read(4999, 1)), [4999 & 0xff]);
  assert.equal(calls, 1);
});

test("range cache: holds at most its limit, forgetting the least recently used", async () => {
  const bytes = new Uint8Array(10_000);
  const { fetch, calls } = recorder(bytes);
  const c = new RangeCache(fetch, 2500);
  for (let i = 0; i < 5; i++) await c.ensure([[1000 * i, 1000 * i + 1000]]);
  assert.ok(c.size <= 2500, `${c.size} bytes held`);
  // The most recent spans are held, the oldest is fetched again.
  await c.read(4000, 10);
  assert.equal(calls.length, 5);
  await c.read(0, 10);
  assert.equal(calls.length, 6);
});

function sample(): string {
  if (!existsSync(bin)) throw new Error(`${bin} is missing: build it with cargo build -p pmcodec (or set PMCODEC_BIN)`);
  const dir = scratchDir("pmc-player-");
  execFileSync(bin, ["sample", "twisting-tube", "-o", join(dir, "frames"), "--frames", "20"]);
  const pmc = join(dir, "tube.pmc");
  execFileSync(bin, ["encode", "-q", join(dir, "frames"), "-o", pmc, "--keyframe-interval", "8"]);
  return pmc;
}
const file = new Uint8Array(readFileSync(sample()));
/** A reader of the whole index (a session's reader of a banded file holds its level's groups). */
const wholeReader = (bytes: Uint8Array) => Reader.open(async (o, n) => bytes.slice(o, o + n), bytes.length);

test("session: one request per frame at full resolution, and a second loop fetches nothing", async () => {
  const { fetch, log, calls } = recorder(file);
  const s = await Session.open(fetch, { readAhead: 0 });
  const frames = s.container.header.frameCount;
  for (let f = 0; f < frames; f++) {
    const before = calls.length;
    const p = await s.frame(f);
    assert.ok(calls.length - before <= 1, `frame ${f}: ${calls.length - before} requests`);
    assert.equal(p.triangles, s.container.header.triangleCount);
    // One unit normal per vertex.
    assert.equal(p.normals.length, p.positions.length);
    for (let i = 0; i < p.normals.length; i += 3) assert.ok(Math.abs(Math.hypot(p.normals[i], p.normals[i + 1], p.normals[i + 2]) - 1) < 1e-4);
  }
  const firstLoop = calls.length;
  for (let f = 0; f < frames; f++) await s.frame(f);
  assert.equal(calls.length, firstLoop, "the second loop made requests");
  assert.equal(twice(log, file.length), 0);
});

test("session: a lowered budget stops fetching finer bands at the next keyframe; a raised one fetches them at once", async () => {
  const { fetch, log } = recorder(file);
  const s = await Session.open(fetch, { readAhead: 4 });
  const c = await wholeReader(file), h = c.header;
  const band0 = c.index.filter((e) => e.kind === ChunkKind.Positions && e.band === 0).map((e) => [c.dataStart + e.offset, c.dataStart + e.offset + e.storedLen]);
  const finest = (from: number) => log.slice(from).filter(([a, b]) => band0.some(([x, y]) => x < b && a < y)).length;
  await s.frame(0);
  await s.frame(1);
  assert.equal(s.level, 0);
  s.budget = s.trianglesPerLevel[h.levelSizes.length - 2];
  const coarse = s.levelFor(s.budget);
  assert.ok(coarse > 0);
  await s.frame(2);
  assert.equal(s.level, 0, "the level holds until the keyframe");
  const key = h.keyframeInterval;
  for (let f = 3; f < key; f++) await s.frame(f);
  const mark = log.length;
  for (let f = key; f < Math.min(h.frameCount, 2 * key); f++) {
    const p = await s.frame(f);
    assert.equal(p.level, coarse);
    assert.ok(p.triangles <= s.budget);
  }
  assert.equal(finest(mark), 0, "band-0 positions fetched after the keyframe");
  s.budget = h.triangleCount;
  const p = await s.frame(2 * key + 1 < h.frameCount ? 2 * key + 1 : h.frameCount - 1);
  assert.equal(p.level, 0);
  assert.ok(finest(mark) > 0);
});

test("the built package exports the player and says which container version it reads", async () => {
  const pkg = join(root, "web/packages/pmcodec-three");
  const manifest = JSON.parse(readFileSync(join(pkg, "package.json"), "utf8"));
  assert.equal(Number(manifest.version.split(".")[0]), VERSION, "the package's major version is the container format's");
  assert.ok(manifest.peerDependencies.three, "three.js is a peer dependency");
  const entry = join(pkg, manifest.exports["."].import);
  assert.ok(existsSync(entry), `${entry} is missing: npm run build:package`);
  assert.ok(existsSync(join(pkg, manifest.exports["."].types)), "type declarations");
  const m = await import(entry);
  assert.equal(m.FORMAT_VERSION, VERSION);
  const THREE = await import("three");
  assert.ok(m.PmcPlayer.prototype instanceof THREE.Object3D);
  for (const f of ["buildMaterials", "buildTextures", "decodeImages", "roomEnvironment"]) assert.equal(typeof m[f], "function", `the package exports ${f}`);
});

test("session: after a jump, a coarse cut comes from a coarse decoder, then the budget's at that frame", async () => {
  const { fetch } = recorder(file);
  const s = await Session.open(fetch, { readAhead: 0 });
  const h = s.container.header, target = h.frameCount - 1;
  const before = s.cache.fetched;
  const q = await s.coarse(target);
  assert.ok(q, "no coarse cut");
  assert.equal(q.frame, target);
  assert.ok(q.level > 0 && q.level >= h.levelSizes.length - 3, `coarse level ${q.level}`);
  const coarseBytes = s.cache.fetched - before;
  const p = await s.frame(target);
  assert.equal(p.level, 0);
  assert.ok(p.triangles > q.triangles);
  assert.ok(coarseBytes < (s.cache.fetched - before - coarseBytes) / 2, `coarse cut read ${coarseBytes} bytes`);
  // The budget's cut geomorphs from the coarse one.
  assert.ok(p.starts && p.starts.length === p.positions.length);
  // Stepping on from there needs no coarse cut.
  assert.equal(await s.coarse(target), null);
});

test("session: the whole-mesh shortcut draws the triangles a full budget cut selects, and sends unchanged indices once", async () => {
  const { fetch } = recorder(file);
  const s = await Session.open(fetch, { readAhead: 0 });
  const c = await wholeReader(file), h = c.header;
  const reference = new Decoder(c, 0);
  const triples = (pos: Float32Array, idx: Uint32Array) => {
    const out: string[] = [];
    for (let t = 0; t < idx.length; t += 3) {
      const v = [0, 1, 2].map((k) => Array.from(pos.subarray(3 * idx[t + k], 3 * idx[t + k] + 3)).join(","));
      out.push(v.sort().join(";"));
    }
    return out.sort();
  };
  let omitted = 0;
  const indexOf = new Map<number, Uint32Array>();
  for (let f = 0; f < h.frameCount; f++) {
    const p = await s.frame(f);
    if (p.indices) indexOf.set(p.indexVersion, p.indices); else omitted++;
    const idx = indexOf.get(p.indexVersion)!;
    assert.equal(idx.length, p.indexCount);
    await reference.seek(f);
    const all = reference.positions();
    reference.replay.selectTriangles(h.triangleCount, reference.replay.splitBenefits(all));
    const m = reference.orderedMesh(all);
    assert.deepEqual(triples(p.positions, idx), triples(m.positions, m.indices), `frame ${f}`);
  }
  assert.ok(omitted > 0, "every frame sent its index buffer");
});

test("httpRanges: ranges from a real server, a whole file from one that ignores Range, and an oversized answer refused", async () => {
  const { createServer } = await import("node:http");
  const body = Buffer.from(Uint8Array.from({ length: 3000 }, (_, i) => (i * 7) & 0xff));
  const server = createServer((req, res) => {
    const m = /bytes=(\d+)-(\d+)/.exec(req.headers.range ?? "");
    if (req.url === "/ranges" && m) {
      const a = Number(m[1]), b = Math.min(Number(m[2]), body.length - 1);
      res.writeHead(206, { "Content-Range": `bytes ${a}-${b}/${body.length}`, "Content-Length": b - a + 1 });
      res.end(body.subarray(a, b + 1));
    } else if (req.url === "/whole") {
      res.writeHead(200, { "Content-Length": body.length });
      res.end(body);
    } else {
      // Says more than the range asked for.
      res.writeHead(206, { "Content-Range": `bytes 0-2999/${body.length}`, "Content-Length": body.length });
      res.end(body);
    }
  });
  await new Promise<void>((r) => server.listen(0, "127.0.0.1", r));
  const port = (server.address() as { port: number }).port;
  try {
    const ranged = await httpRanges(`http://127.0.0.1:${port}/ranges`)([[100, 110]]);
    assert.equal(ranged.total, 3000);
    assert.equal(ranged.parts[0].start, 100);
    assert.deepEqual(Array.from(ranged.parts[0].bytes), Array.from(body.subarray(100, 110)));
    const whole = await httpRanges(`http://127.0.0.1:${port}/whole`)([[100, 110]]);
    assert.equal(whole.parts[0].start, 0);
    assert.equal(whole.parts[0].bytes.length, 3000);
    await assert.rejects(httpRanges(`http://127.0.0.1:${port}/liar`)([[0, 10]]), /\/liar: 3000 bytes for a range of 10/);
  } finally {
    server.close();
  }
});

test("session: a budget change geomorphs over the next frames, on one morph id, from the cut before it", async () => {
  const { fetch } = recorder(file);
  const s = await Session.open(fetch, { readAhead: 0 });
  const h = s.container.header;
  s.budget = Math.round(h.triangleCount / 4);
  const a = await s.frame(0);
  assert.equal(a.starts, undefined, "the first frame has nothing to morph from");
  s.budget = h.triangleCount;
  const morphs: (number | null)[] = [];
  for (let f = 1; f < h.frameCount; f++) {
    const p = await s.frame(f);
    morphs.push(p.starts ? p.morphId : null);
    if (p.starts) assert.equal(p.starts.length, p.positions.length);
  }
  const carried = morphs.filter((m) => m !== null);
  assert.ok(carried.length > 1 && carried.length < morphs.length, `morph on ${carried.length} of ${morphs.length} frames`);
  assert.ok(carried.every((m) => m === carried[0]), "one morph id");
  assert.notEqual(morphs[0], null, "the morph starts with the change");
});

test("session, authored mode on a stream with appearance: every triangle in the group of its material, texture coordinates and colours per vertex, UVs geomorph from the old cut's", async () => {
  const cloth = new Uint8Array(readFileSync(join(root, "crates/pmcodec-container/tests/compat/v6-textured-cloth-k4.pmc")));
  const s = await Session.open(recorder(cloth).fetch, { readAhead: 0 });
  const h = s.container.header, a = h.appearance!;
  assert.equal(s.info().appearance, true);
  assert.equal(s.colour, "authored");
  const looks = await s.looks();
  assert.ok(looks && looks.materials.materials.length === a.materials && looks.images.length === a.images);
  assert.equal(looks.images[0].bytes.length, looks.materials.images[0].byteLength);
  const reference = new Decoder(s.container, 0);
  await reference.loadAppearance();
  for (const [f, budget] of [[0, h.triangleCount], [2, 40]]) {
    s.budget = budget;
    const p = await s.frame(f);
    const nv = p.positions.length / 3;
    assert.ok(p.uvs && p.uvs.length === 2 * nv, "two texture coordinates per vertex");
    assert.ok(p.colours && p.colours.length === 4 * nv, "RGBA colours per vertex");
    assert.equal(p.normals.length, 3 * nv);
    // Groups tile the index buffer in material order; each triangle's material is its chart's.
    const groups = p.groups!, idx = p.indices!;
    assert.equal(groups[0].start, 0);
    for (let g = 1; g < groups.length; g++) assert.equal(groups[g].start, groups[g - 1].start + groups[g - 1].count);
    assert.equal(groups.at(-1)!.start + groups.at(-1)!.count, p.indexCount);
    assert.ok(groups.every((g, i) => i === 0 || g.material > groups[i - 1].material));
    // The same triangles (as sets of corner positions and UVs) as the decoder's own textured mesh.
    await reference.seek(f);
    const pos = reference.positions();
    reference.replay.selectTriangles(budget, reference.replay.splitBenefits(pos));
    const want = reference.texturedMesh(pos);
    const key = (P: Float32Array, U: Float32Array, i: number[]) => i.map((v) => `${P[3 * v]},${P[3 * v + 1]},${P[3 * v + 2]}/${U[2 * v]},${U[2 * v + 1]}`).sort().join(" ");
    const got = new Map<string, number>();
    for (const g of groups) for (let t = g.start; t < g.start + g.count; t += 3) got.set(key(p.positions, p.uvs, [idx[t], idx[t + 1], idx[t + 2]]), g.material);
    assert.equal(got.size, want.indices.length / 3, `frame ${f} budget ${budget}: triangles`);
    for (let t = 0; t < want.indices.length / 3; t++) {
      const k = key(want.positions, want.uv0!, Array.from(want.indices.subarray(3 * t, 3 * t + 3)));
      assert.equal(got.get(k), want.triangleMaterial[t], `frame ${f} budget ${budget}: triangle ${t} and its material`);
    }
  }
  // Raising the budget again geomorphs: texture coordinates start somewhere else for some
  // vertices (those that come out of a coarser node) and equal their own for the others.
  s.budget = h.triangleCount;
  const m = await s.frame(3);
  assert.ok(m.starts && m.uvStarts && m.uvStarts.length === m.uvs!.length, "a geomorph with texture coordinates");
  let moved = 0;
  for (let i = 0; i < m.uvs!.length; i++) if (m.uvStarts[i] !== m.uvs![i]) moved++;
  assert.ok(moved > 0, "no texture coordinate morphs");
  // Plain mode: no appearance in the frames.
  s.colour = "plain";
  const q = await s.frame(3);
  assert.equal(q.uvs, undefined);
  assert.equal(q.groups, undefined);
  assert.equal(q.colours, undefined);
});

test("geomorph of texture coordinates: a refined vertex starts at its old ancestor's values in its own chart, a coarsened one at its old descendants' mean, a kept one does not move", () => {
  // Nodes 0..3 at level 0; 4 (parent of 0, 1) and 5 (parent of 2, 3) at level 1; 6 the root.
  const parent = [4, 4, 5, 5, 6, 6, NONE];
  const values: Record<string, [number, number]> = {
    "4/0": [0.5, 0.5], "4/1": [0.9, 0.9], "0/0": [0, 0], "1/0": [1, 0], "2/0": [0, 1], "3/1": [1, 1], "5/1": [0.2, 0.2],
  };
  const valueOf = (g: number, chart: number, out: Float32Array, at: number): boolean => {
    const v = values[`${g}/${chart}`];
    if (!v) return false;
    out[at] = v[0]; out[at + 1] = v[1];
    return true;
  };
  // Old cut {4, 2, 3}. New vertices: nodes 0 and 1 refine 4 (chart 0: from 4's values in
  // chart 0; node 1 in chart 1: from 4's in chart 1; node 0 in chart 2, where 4 has none: its
  // own), node 5 coarsens 2 and 3 (chart 0: only 2 has values there; chart 1: only 3), node 3
  // is in both cuts.
  const nodes = Uint32Array.from([0, 1, 1, 0, 5, 5, 3]);
  const charts = Uint32Array.from([0, 0, 1, 2, 0, 1, 1]);
  const own = Float32Array.from([0, 0, 1, 0, 7, 7, 3, 3, 0.3, 0.3, 0.2, 0.2, 1, 1]);
  const s = morphAttributeStarts(nodes, charts, Uint32Array.from([4, 2, 3]), own, 2, (g) => parent[g], valueOf);
  assert.deepEqual(Array.from(s), [0.5, 0.5, 0.5, 0.5, 0.9, 0.9, 3, 3, 0, 1, 1, 1, 1, 1].map(Math.fround));
});

test("pmcodec-three's materials: glTF's metallic-roughness materials as GLTFLoader builds them (maps, colour spaces, coordinate sets, texture transforms, samplers, alpha modes, sides, flat shading)", async () => {
  const THREE = await import("three");
  const { ALPHA_BLEND, ALPHA_MASK, ALPHA_OPAQUE, buildMaterials, buildTextures } = await import("../src/player/appearance.js");
  const ref = (texture: number, texCoord = 0, transform: TextureRef["transform"] = null): TextureRef => ({ texture, texCoord, transform });
  const base = {
    name: null, baseColorFactor: [1, 1, 1, 1], baseColorTexture: null, metallicFactor: 1, roughnessFactor: 1, metallicRoughnessTexture: null,
    normalTexture: null, normalScale: 1, occlusionTexture: null, occlusionStrength: 1, emissiveTexture: null, emissiveFactor: [0, 0, 0],
    alphaMode: ALPHA_OPAQUE, alphaCutoff: 0.5, doubleSided: false,
  };
  const materials: Materials = {
    materials: [
      { ...base, name: "skin", baseColorFactor: [0.5, 0.25, 1, 0.75], baseColorTexture: ref(0), metallicFactor: 0.1, roughnessFactor: 0.9, metallicRoughnessTexture: ref(1, 1),
        normalTexture: ref(1), normalScale: 0.5, occlusionTexture: ref(1, 1), occlusionStrength: 0.3, emissiveTexture: ref(0, 0, { offset: [0.25, 0.5], rotation: 0.5, scale: [2, 3], texCoord: 1 }),
        emissiveFactor: [1, 0.5, 0], alphaMode: ALPHA_MASK, alphaCutoff: 0.3, doubleSided: true },
      { ...base, alphaMode: ALPHA_BLEND },
    ],
    textures: [{ image: 0, sampler: 0 }, { image: 0, sampler: null }],
    samplers: [{ magFilter: 9728, minFilter: 9984, wrapS: 33071, wrapT: 33648 }],
    images: [{ name: "albedo", mimeType: "image/png", byteLength: 4 }],
  };
  // Any image object will do for three.js outside a browser: nothing is uploaded.
  const textures = buildTextures(materials, [{ width: 1, height: 1 } as unknown as HTMLCanvasElement]);
  assert.equal(textures[0]!.magFilter, THREE.NearestFilter);
  assert.equal(textures[0]!.minFilter, THREE.NearestMipmapNearestFilter);
  assert.equal(textures[0]!.wrapS, THREE.ClampToEdgeWrapping);
  assert.equal(textures[0]!.wrapT, THREE.MirroredRepeatWrapping);
  // glTF's defaults where the texture has no sampler.
  assert.equal(textures[1]!.minFilter, THREE.LinearMipmapLinearFilter);
  assert.equal(textures[1]!.wrapS, THREE.RepeatWrapping);
  assert.equal(textures[0]!.flipY, false);
  const [skin, glass] = buildMaterials(materials, textures, { vertexColors: true, flatShading: true });
  assert.ok(skin instanceof THREE.MeshStandardMaterial);
  assert.equal(skin.name, "skin");
  // Factors are linear: the colour keeps them as they are.
  assert.deepEqual([skin.color.r, skin.color.g, skin.color.b, skin.opacity], [0.5, 0.25, 1, 0.75]);
  assert.deepEqual([skin.metalness, skin.roughness, skin.aoMapIntensity], [0.1, 0.9, 0.3]);
  assert.deepEqual([skin.emissive.r, skin.emissive.g, skin.emissive.b], [1, 0.5, 0]);
  assert.equal(skin.map!.colorSpace, THREE.SRGBColorSpace);
  assert.equal(skin.emissiveMap!.colorSpace, THREE.SRGBColorSpace);
  assert.equal(skin.normalMap!.colorSpace, THREE.NoColorSpace);
  assert.equal(skin.metalnessMap, skin.roughnessMap, "one texture: roughness in G, metalness in B");
  assert.equal(skin.metalnessMap!.channel, 1);
  assert.equal(skin.aoMap!.channel, 1);
  assert.equal(skin.map!.channel, 0);
  // The texture transform: offset, rotation, scale, and its own coordinate set.
  assert.deepEqual([skin.emissiveMap!.offset.x, skin.emissiveMap!.offset.y, skin.emissiveMap!.rotation, skin.emissiveMap!.repeat.x, skin.emissiveMap!.repeat.y, skin.emissiveMap!.channel], [0.25, 0.5, 0.5, 2, 3, 1]);
  assert.equal(skin.map!.offset.x, 0, "a transform on one use leaves the others alone");
  // No tangents: the derivative frame's bitangent is flipped, as GLTFLoader flips it.
  assert.deepEqual([skin.normalScale.x, skin.normalScale.y], [0.5, -0.5]);
  assert.deepEqual([skin.alphaTest, skin.transparent, skin.side, skin.vertexColors, skin.flatShading], [0.3, false, THREE.DoubleSide, true, true]);
  assert.deepEqual([glass.transparent, glass.depthWrite, glass.alphaTest, glass.side, glass.map], [true, false, 0, THREE.FrontSide, null]);
  // An image that did not decode leaves its uses untextured.
  const [plain] = buildMaterials(materials, buildTextures(materials, [null]));
  assert.equal(plain.map, null);
  assert.deepEqual([plain.normalScale.x, plain.normalScale.y], [1, 1]);
});

test("GPU skinning (gpuSkin): frames carry the cut's skin with each new cut, the palette, and offsets (whole or changed) that, rebuilt as the page does and skinned in floats, pose each vertex within a quantum of its exact position", async () => {
  const file = join(scratchDir("pmc-gpuskin-"), "fox.pmc");
  const fox = join(root, "../shared/data/gltf/Fox.glb");
  if (!existsSync(fox)) throw new Error(`${fox} is absent: this test reads the real models in ../shared/data beside the repository`);
  execFileSync(bin, ["encode", "-q", fox, "-o", file, "--keyframe-interval", "8", "--quant-bits", "12"]);
  const bytes = new Uint8Array(readFileSync(file));
  const gpu = await Session.open(recorder(bytes).fetch, { gpuSkin: true });
  const cpu = await Session.open(recorder(bytes).fetch);
  const h = gpu.container.header;
  assert.ok(gpu.info().gpuSkinJoints > 0 && cpu.info().gpuSkinJoints === 0);
  gpu.colour = "plain";
  // The exact positions of every node, from the default decoder.
  const exact = new Decoder(await wholeReader(bytes), 0);
  // The page's side: skins and offsets by version, offsets given as changes applied to the last.
  const skins = new Map<number, NonNullable<Awaited<ReturnType<Session["frame"]>>["skin"]>>(), offsets = new Map<number, Float32Array>();
  let sparse = 0, kept = 0, skinsSent = 0, indicesSent = 0;
  const check = async (g: Awaited<ReturnType<Session["frame"]>>, f: number, what: string) => {
    await exact.seek(f);
    const want = exact.positions();
    // Each vertex's node: what the session put in the frame (its cut's nodes, in vertex order).
    const nodes = (gpu as unknown as { skinSent: { nodes: Uint32Array } }).skinSent.nodes;
    const k = g.skin!;
    assert.equal(g.positions.length, 0, `${what}: no posed positions`);
    if (k.bind) { skins.set(k.version, k); skinsSent++; }
    if (g.indices) indicesSent++;
    if (k.offsets) offsets.set(k.offsetsVersion, k.offsets);
    else if (k.changed) {
      const o = offsets.get(k.offsetsVersion - 1)!.slice();
      k.changed.forEach((v, i) => o.set(k.values!.subarray(3 * i, 3 * i + 3), 3 * v));
      offsets.set(k.offsetsVersion, o);
      sparse++;
    } else kept++;
    const s = skins.get(k.version)!, o = offsets.get(k.offsetsVersion)!;
    assert.equal(s.bind!.length, 3 * nodes.length, `${what}: vertices`);
    assert.equal(g.triangles, h.triangleCount);
    for (let v = 0; v < nodes.length; v++) {
      for (let a = 0; a < 3; a++) {
        let p = o[3 * v + a];
        for (let i = 0; i < 4; i++) {
          const w = s.weights![4 * v + i], m = 16 * s.joints![4 * v + i], b = s.bind!.subarray(3 * v, 3 * v + 3);
          if (w > 0) p += w * (k.palette[m + a] * b[0] + k.palette[m + 4 + a] * b[1] + k.palette[m + 8 + a] * b[2] + k.palette[m + 12 + a]);
        }
        const q = want[3 * nodes[v] + a];
        assert.ok(Math.abs(p - q) <= 1.001 * h.step, `${what} vertex ${v}: ${p} vs ${q}`);
      }
    }
  };
  for (let f = 0; f < h.frameCount; f++) await check(await gpu.frame(f), f, `frame ${f}`);
  // The cut's skin goes with a new cut only (here, when its triangles change: at keyframes).
  assert.equal(skinsSent, indicesSent, "skins sent with new index buffers");
  assert.ok(skinsSent < h.frameCount / 4, `${skinsSent} skins sent in ${h.frameCount} frames`);
  console.log(`fox: ${h.frameCount} frames, cut's skin sent ${skinsSent} times; offsets sent whole ${h.frameCount - sparse - kept}, as changes ${sparse}, unchanged ${kept}`);
  // A lower budget: a new cut, whose skin is sent, and a geomorph from the old one.
  gpu.budget = Math.round(h.triangleCount / 3);
  const g = await gpu.frame(h.frameCount - 1);
  assert.ok(g.skin!.bind && g.skin!.startBind && g.skin!.startOffsets, "the new cut's skin and the geomorph's starts");
  assert.equal(g.skin!.startBind!.length, g.skin!.bind!.length);
});
