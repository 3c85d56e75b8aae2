// A decoder of the .pmc container written from proto/container.md: preamble, postcard header
// and index, zstd chunks with CRC-32, varint payloads, rANS-coded position residuals and
// position prediction. Byte access is
// a callback, so the same code reads a file in Node or HTTP ranges in a browser.

import { decompress } from "fzstd";
import { BELOW, DecodeError, FrameDelta, KeyBand, NONE, Replay } from "./replay.js";

export const MAGIC = [0x89, 0x50, 0x4d, 0x43, 0x0d, 0x0a, 0x1a, 0x0a];
export const PREAMBLE_LEN = 32;
/**
 * The format version this decoder reads, and the oldest it still reads (version 4: no `order`
 * in the header, faces and corners as plain ids; version 3: no `motion` either).
 */
export const VERSION = 5, OLDEST_READABLE = 3;

export enum ChunkKind { Triangles = 0, Key = 1, Delta = 2, Positions = 3, Faces = 4, Corners = 5 }
/** How band 0 is predicted on frames that are not keyframes (proto/container.md, "Positions, band j"). */
export enum Motion { Mean = 0, Affine = 1, KeyframeAffine = 2 }
/** The order band 0 is decoded in (proto/container.md, "Band 0 order"). */
export enum VertexOrder { Input = 0, BreadthFirst = 1 }

/**
 * Whether a client whose finest level is `minLevel` reads chunks of this kind in `band`: every
 * band from its level up, except faces and corners, which only the band of its finest level
 * needs (proto/container.md, "Who reads what").
 */
export function readAt(kind: ChunkKind, band: number, minLevel: number): boolean {
  if (kind === ChunkKind.Triangles) return minLevel === 0;
  if (kind === ChunkKind.Faces || kind === ChunkKind.Corners) return band === minLevel;
  return band >= minLevel;
}

export interface Header {
  vertexCount: number; triangleCount: number; frameCount: number; frameRate: number;
  levelSizes: number[]; branching: number; bboxMin: number[]; bboxMax: number[];
  step: number; keyframeInterval: number; generator: string; frameNames: string[];
  /** Band 0's prediction on inter frames. */
  motion: Motion;
  /** Band 0's decoding order. */
  order: VertexOrder;
}

export interface ChunkEntry { kind: ChunkKind; frame: number; band: number; offset: number; storedLen: number; rawLen: number; crc32: number }

/** Fetches `len` bytes at `offset`. */
export type ReadAt = (offset: number, len: number) => Promise<Uint8Array>;

const CRC_TABLE = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();

export function crc32(b: Uint8Array): number {
  let c = 0xffffffff;
  for (let i = 0; i < b.length; i++) c = CRC_TABLE[(c ^ b[i]) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

/** postcard's wire format, the parts the header and index use. */
class Postcard {
  pos = 0;
  private view: DataView;
  constructor(private b: Uint8Array, private what: string) { this.view = new DataView(b.buffer, b.byteOffset, b.byteLength); }
  private need(n: number): void { if (this.pos + n > this.b.length) throw new DecodeError(`${this.what}: ends early`); }
  varint(): number {
    let v = 0, mul = 1;
    for (let i = 0; i < 10; i++) {
      this.need(1);
      const byte = this.b[this.pos++];
      v += (byte & 0x7f) * mul;
      if (!(byte & 0x80)) { if (v > Number.MAX_SAFE_INTEGER) throw new DecodeError(`${this.what}: number too large`); return v; }
      mul *= 128;
    }
    throw new DecodeError(`${this.what}: varint too long`);
  }
  u8(): number { this.need(1); return this.b[this.pos++]; }
  bool(): boolean { const v = this.u8(); if (v > 1) throw new DecodeError(`${this.what}: bad bool`); return v === 1; }
  f32(): number { this.need(4); const v = this.view.getFloat32(this.pos, true); this.pos += 4; return v; }
  f64(): number { this.need(8); const v = this.view.getFloat64(this.pos, true); this.pos += 8; return v; }
  str(): string { const n = this.varint(); this.need(n); const s = new TextDecoder().decode(this.b.subarray(this.pos, this.pos + n)); this.pos += n; return s; }
  seq<T>(item: () => T, max: number): T[] {
    const n = this.varint();
    if (n > max) throw new DecodeError(`${this.what}: ${n} items is too many`);
    return Array.from({ length: n }, item);
  }
  option<T>(item: () => T): T | null { return this.bool() ? item() : null; }
}

/** Varint payload reader (proto/container.md, "Chunks"). */
class Payload {
  pos = 0;
  constructor(private b: Uint8Array, private what: string) {}
  get(): number {
    let v = 0, mul = 1;
    for (let i = 0; i < 5; i++) {
      if (this.pos >= this.b.length) throw new DecodeError(`${this.what}: ends inside a number`);
      const byte = this.b[this.pos++];
      v += (byte & 0x7f) * mul;
      if (!(byte & 0x80)) { if (v > 0xffffffff) throw new DecodeError(`${this.what}: number beyond 32 bits`); return v; }
      mul *= 128;
    }
    throw new DecodeError(`${this.what}: number longer than 5 bytes`);
  }
  id(limit: number, name: string): number { const v = this.get(); if (v >= limit) throw new DecodeError(`${this.what}: ${name} ${v} out of range`); return v; }
  count(limit: number, name: string): number { const v = this.get(); if (v > limit) throw new DecodeError(`${this.what}: ${v} ${name}`); return v; }
  ascending(prev: { v: number | null }, limit: number, name: string): number {
    const d = this.get();
    const v = prev.v === null ? d : prev.v + d + 1;
    if (v >= limit) throw new DecodeError(`${this.what}: ${name} ${v} out of range`);
    prev.v = v;
    return v;
  }
  zigzag(): number { const v = this.get(); return (v >>> 1) ^ -(v & 1); }
  finish(): void { if (this.pos !== this.b.length) throw new DecodeError(`${this.what}: ${this.b.length - this.pos} bytes left over`); }
}

export class Container {
  private constructor(readonly readAt: ReadAt, readonly version: number, readonly header: Header, readonly index: ChunkEntry[], readonly dataStart: number, readonly fileLen: number) {}
  bytesRead = 0;

  static async open(readAt: ReadAt, fileLen: number): Promise<Container> {
    if (fileLen < PREAMBLE_LEN) throw new DecodeError("not a .pmc file (too short)");
    const pre = await readAt(0, PREAMBLE_LEN);
    for (let i = 0; i < 8; i++) if (pre[i] !== MAGIC[i]) throw new DecodeError("not a .pmc file (bad magic number)");
    const dv = new DataView(pre.buffer, pre.byteOffset, pre.byteLength);
    const version = dv.getUint16(8, true);
    if (version < OLDEST_READABLE || version > VERSION) throw new DecodeError(`container version ${version} is not supported (this decoder reads versions ${OLDEST_READABLE} to ${VERSION})`);
    const headerLen = dv.getUint32(12, true), indexLen = dv.getUint32(16, true);
    const headerCrc = dv.getUint32(20, true), indexCrc = dv.getUint32(24, true);
    const dataStart = PREAMBLE_LEN + headerLen + indexLen;
    if (dataStart > fileLen || headerLen > 64 << 20 || indexLen > 64 << 20) throw new DecodeError("header and index: the file ends before they do");
    const tables = await readAt(PREAMBLE_LEN, headerLen + indexLen);
    const hb = tables.subarray(0, headerLen), ib = tables.subarray(headerLen);
    if (crc32(hb) !== headerCrc) throw new DecodeError("header: checksum mismatch");
    if (crc32(ib) !== indexCrc) throw new DecodeError("index: checksum mismatch");
    const p = new Postcard(hb, "header");
    const header: Header = {
      vertexCount: p.varint(), triangleCount: p.varint(), frameCount: p.varint(), frameRate: p.f32(),
      levelSizes: p.seq(() => p.varint(), 64), branching: p.varint(),
      bboxMin: [p.f32(), p.f32(), p.f32()], bboxMax: [p.f32(), p.f32(), p.f32()],
      step: p.f32(), keyframeInterval: p.varint(), generator: "", frameNames: [], motion: Motion.Mean, order: VertexOrder.Input,
    };
    // encoded_with: informative, read and dropped.
    p.str(); p.str(); p.f64(); p.f64(); p.varint(); p.bool(); p.bool(); p.option(() => p.f64()); p.option(() => p.u8());
    header.generator = p.str();
    header.frameNames = p.seq(() => p.str(), 1 << 20);
    header.motion = version >= 4 ? p.varint() : Motion.Mean;
    if (header.motion > (version >= 5 ? Motion.KeyframeAffine : Motion.Affine)) throw new DecodeError(`header: unknown band-0 motion ${header.motion}`);
    header.order = version >= 5 ? p.varint() : VertexOrder.Input;
    if (header.order > VertexOrder.BreadthFirst) throw new DecodeError(`header: unknown band-0 order ${header.order}`);
    const q = new Postcard(ib, "index");
    const index = q.seq((): ChunkEntry => {
      const kind = q.varint();
      if (kind > 5) throw new DecodeError(`index: chunk kind ${kind}`);
      return { kind, frame: q.varint(), band: q.varint(), offset: q.varint(), storedLen: q.varint(), rawLen: q.varint(), crc32: q.varint() };
    }, 1 << 24);
    const h = header;
    if (h.levelSizes.length === 0 || h.levelSizes[0] !== h.vertexCount || h.frameCount === 0 || !(h.step > 0)) throw new DecodeError("header: inconsistent counts");
    if (h.levelSizes.some((s, i) => i > 0 && (s === 0 || s > h.levelSizes[i - 1]))) throw new DecodeError(`header: level sizes ${h.levelSizes} do not shrink`);
    // Declared sizes are capped, so what a player allocates from them is bounded (proto/container.md, "Limits").
    const nodes = h.levelSizes.reduce((a, b) => a + b, 0);
    if (h.vertexCount > MAX_VERTICES || h.triangleCount > MAX_TRIANGLES || nodes > MAX_NODES || h.frameCount > MAX_FRAMES) {
      throw new DecodeError(`header: ${h.vertexCount} vertices, ${h.triangleCount} triangles, ${nodes} nodes, ${h.frameCount} frames: beyond the limits`);
    }
    let end = 0;
    for (const e of index) {
      if (e.offset + e.storedLen > fileLen - dataStart) throw new DecodeError(`${describe(e)}: the file ends before it does`);
      end = Math.max(end, e.offset + e.storedLen);
      if (e.kind !== ChunkKind.Triangles && (e.frame >= h.frameCount || e.band >= h.levelSizes.length)) throw new DecodeError(`${describe(e)}: frame or band beyond the header's counts`);
      const [least, most] = rawLenRange(h, e.kind, e.band);
      if (e.rawLen < least || e.rawLen > most) throw new DecodeError(`${describe(e)}: declared size ${e.rawLen} outside ${least}..${most}`);
    }
    if (end < fileLen - dataStart) throw new DecodeError(`${fileLen - dataStart - end} bytes after the end of the container`);
    const c = new Container(readAt, version, header, index, dataStart, fileLen);
    c.bytesRead = PREAMBLE_LEN + headerLen + indexLen;
    return c;
  }

  isKeyframe(f: number): boolean { return f === 0 || (this.header.keyframeInterval > 0 && f % this.header.keyframeInterval === 0); }
  keyframeBefore(f: number): number { const k = this.header.keyframeInterval; return k === 0 ? 0 : f - (f % k); }

  find(kind: ChunkKind, frame: number, band: number): ChunkEntry {
    const e = this.index.find((x) => x.kind === kind && x.frame === frame && x.band === band && (kind !== ChunkKind.Triangles || true));
    if (!e) throw new DecodeError(`frame ${frame} band ${band} ${ChunkKind[kind]}: missing from the index`);
    return e;
  }

  async chunk(e: ChunkEntry): Promise<Uint8Array> {
    const stored = await this.readAt(this.dataStart + e.offset, e.storedLen);
    this.bytesRead += stored.length;
    if (crc32(stored) !== e.crc32) throw new DecodeError(`${describe(e)}: checksum mismatch`);
    let raw: Uint8Array;
    try {
      raw = decompress(stored, new Uint8Array(e.rawLen));
    } catch (err) {
      // fzstd throws plain Errors on a frame that does not fit or does not parse.
      throw new DecodeError(`${describe(e)}: zstd: ${err instanceof Error ? err.message : String(err)}`);
    }
    if (raw.length !== e.rawLen) throw new DecodeError(`${describe(e)}: ${raw.length} bytes where the index says ${e.rawLen}`);
    return raw;
  }
}

/** Caps on a header's declared sizes (proto/container.md, "Limits"). */
export const MAX_VERTICES = 1 << 24, MAX_TRIANGLES = 1 << 25, MAX_NODES = 1 << 25, MAX_FRAMES = 1 << 20;

/** The decompressed sizes a chunk may declare (proto/container.md, "Limits"). */
function rawLenRange(h: Header, kind: ChunkKind, band: number): [number, number] {
  const t = h.triangleCount, n = h.levelSizes[band] ?? 0, belowTop = band < h.levelSizes.length - 1;
  switch (kind) {
    case ChunkKind.Triangles: return [1 + 3 * t, 5 + 15 * t];
    case ChunkKind.Key: return belowTop ? [1 + n, 5 + 5 * n] : [1, 5];
    case ChunkKind.Delta: return [1, 5 + 10 * n];
    case ChunkKind.Faces: return [1, 5 + 20 * t];
    case ChunkKind.Corners: return [1, 5 + 25 * t];
    default: return [1, 1024 + 24 * n];
  }
}

export function describe(e: ChunkEntry): string {
  return e.kind === ChunkKind.Triangles ? "triangles chunk" : `frame ${e.frame} band ${e.band} ${ChunkKind[e.kind].toLowerCase()}`;
}

function readKey(raw: Uint8Array, what: string, sizes: number[], band: number): Uint32Array {
  const c = new Payload(raw, what);
  const top = sizes.length - 1;
  const n = c.count(sizes[band], "parents");
  if (n !== (band < top ? sizes[band] : 0)) throw new DecodeError(`${what}: ${n} parents`);
  const parent = new Uint32Array(n);
  for (let i = 0; i < n; i++) parent[i] = c.id(sizes[band + 1], "parent");
  c.finish();
  return parent;
}

/**
 * Faces (keyframes) of one band: triangle ascending, 3 corners, from version 5 each the zigzag
 * difference from the same corner of the face before; in versions 3 and 4 plain, and corner
 * updates (frames) coded the same way.
 */
function readFaces(raw: Uint8Array, what: string, size: number, triangles: number, version: number): KeyBand["faces"] {
  const c = new Payload(raw, what);
  const m = c.count(triangles, "faces");
  const faces: KeyBand["faces"] = [];
  const prev = { v: null as number | null };
  let last: [number, number, number] = [0, 0, 0];
  for (let i = 0; i < m; i++) {
    const t = c.ascending(prev, triangles, "triangle");
    const corners: [number, number, number] = [0, 0, 0];
    for (let k = 0; k < 3; k++) {
      corners[k] = version >= 5 ? (last[k] + c.zigzag()) >>> 0 : c.get();
      if (corners[k] >= size) throw new DecodeError(`${what}: corner ${corners[k]} out of range`);
    }
    last = corners;
    faces.push({ t, corners });
  }
  c.finish();
  return faces;
}

/**
 * Corner updates of one band from version 5, against the corners the reader holds (`held`, 3
 * per triangle): for a triangle alive before, a mask of the corners that change and their
 * zigzag differences; otherwise its three new corners.
 */
function readCornerUpdates(raw: Uint8Array, what: string, size: number, held: Uint32Array): KeyBand["faces"] {
  const c = new Payload(raw, what);
  const triangles = held.length / 3;
  const m = c.count(triangles, "corner updates");
  const out: KeyBand["faces"] = [];
  const prev = { v: null as number | null };
  for (let i = 0; i < m; i++) {
    const t = c.ascending(prev, triangles, "triangle");
    const corners: [number, number, number] = [held[3 * t], held[3 * t + 1], held[3 * t + 2]];
    const alive = corners[0] !== corners[1] && corners[1] !== corners[2] && corners[0] !== corners[2];
    if (alive) {
      const mask = c.get();
      if (mask < 1 || mask > 7) throw new DecodeError(`${what}: triangle ${t}: corner mask ${mask} (1 to 7)`);
      for (let k = 0; k < 3; k++) {
        if (!(mask & (1 << k))) continue;
        corners[k] = (corners[k] + c.zigzag()) >>> 0;
        if (corners[k] >= size) throw new DecodeError(`${what}: corner ${corners[k]} out of range`);
      }
    } else {
      for (let k = 0; k < 3; k++) corners[k] = c.id(size, "corner");
    }
    out.push({ t, corners });
  }
  c.finish();
  return out;
}

function readDelta(raw: Uint8Array, what: string, sizes: number[], band: number, out: FrameDelta): void {
  const c = new Payload(raw, what);
  const top = sizes.length - 1;
  const n = c.count(band < top ? sizes[band] : 0, "moves");
  const prev = { v: null as number | null };
  for (let i = 0; i < n; i++) {
    const v = c.ascending(prev, sizes[band], "node");
    out.swaps.push({ level: band, v, to: c.id(sizes[band + 1], "parent") });
  }
  c.finish();
}

/** Plays a container down to a finest level: hierarchy (Replay) and quantized node positions. */
export class Player {
  replay: Replay;
  frame = -1;
  current: Int32Array;
  previous: Int32Array;
  private triangles: Uint32Array | null = null;
  /** Level-0 lower neighbours (proto/container.md, "Positions, band j"). */
  private lower: LowerNeighbours | null = null;
  /** Band 0's stencil weights from the last keyframe (keyframe affine motion). */
  private weights: Float64Array | null = null;

  constructor(readonly c: Container, readonly minLevel: number) {
    const h = c.header;
    if (minLevel >= h.levelSizes.length) throw new DecodeError(`level ${minLevel}: the file has ${h.levelSizes.length} levels`);
    this.replay = new Replay(h.levelSizes, minLevel, h.triangleCount);
    const total = h.levelSizes.reduce((a, b) => a + b, 0);
    this.current = new Int32Array(total * 3);
    this.previous = new Int32Array(total * 3);
  }

  async seek(f: number): Promise<void> {
    const h = this.c.header;
    if (f < 0 || f >= h.frameCount) throw new DecodeError(`frame ${f} is beyond the ${h.frameCount} frames`);
    const key = this.c.keyframeBefore(f);
    let start: number;
    if (this.frame >= key && this.frame <= f) start = this.frame;
    else { await this.loadKeyframe(key); start = key; }
    for (let g = start + 1; g <= f; g++) await this.step(g);
  }

  private async loadKeyframe(k: number): Promise<void> {
    const h = this.c.header;
    const bands: KeyBand[] = h.levelSizes.map(() => ({ parent: new Uint32Array(0), faces: [] }));
    for (let j = h.levelSizes.length - 1; j >= this.minLevel; j--) {
      bands[j].parent = readKey(await this.c.chunk(this.c.find(ChunkKind.Key, k, j)), `frame ${k} band ${j} keyframe`, h.levelSizes, j);
    }
    const L = this.minLevel;
    if (L > 0) bands[L].faces = readFaces(await this.c.chunk(this.c.find(ChunkKind.Faces, k, L)), `frame ${k} band ${L} faces`, h.levelSizes[L], h.triangleCount, this.c.version);
    if (this.minLevel === 0 && !this.triangles) {
      const raw = await this.c.chunk(this.c.find(ChunkKind.Triangles, 0, 0));
      const p = new Payload(raw, "triangles chunk");
      const n = p.count(h.triangleCount, "triangles");
      if (n !== h.triangleCount) throw new DecodeError(`triangles chunk: ${n} triangles`);
      const tris = new Uint32Array(3 * n);
      for (let i = 0; i < 3 * n; i++) tris[i] = p.id(h.vertexCount, "vertex");
      p.finish();
      this.triangles = tris;
      this.lower = lowerNeighbours(h.vertexCount, tris, h.order);
    }
    this.replay.loadKeyframe(bands, this.triangles ?? undefined);
    await this.decodePositions(k, true);
    if (h.motion === Motion.KeyframeAffine && this.lower) this.weights = stencilWeights(this.lower, this.current, h.vertexCount);
    this.frame = k;
  }

  private async step(f: number): Promise<void> {
    const h = this.c.header;
    const delta: FrameDelta = { swaps: [], corners: [] };
    for (let j = h.levelSizes.length - 1; j >= this.minLevel; j--) {
      readDelta(await this.c.chunk(this.c.find(ChunkKind.Delta, f, j)), `frame ${f} band ${j} delta`, h.levelSizes, j, delta);
    }
    const L = this.minLevel;
    if (L > 0) {
      const raw = await this.c.chunk(this.c.find(ChunkKind.Corners, f, L)), what = `frame ${f} band ${L} corners`;
      const updates = this.c.version >= 5
        ? readCornerUpdates(raw, what, h.levelSizes[L], this.replay.corners)
        : readFaces(raw, what, h.levelSizes[L], h.triangleCount, this.c.version);
      for (const u of updates) delta.corners.push({ level: L, t: u.t, corners: u.corners });
    }
    this.replay.apply(delta);
    [this.previous, this.current] = [this.current, this.previous];
    await this.decodePositions(f, false);
    this.frame = f;
  }

  /** Positions of bands top..minLevel (proto/container.md, "Positions, band j"). */
  private async decodePositions(f: number, fromKey: boolean): Promise<void> {
    const h = this.c.header, r = this.replay;
    const intra = fromKey || this.c.isKeyframe(f);
    const cur = this.current, prev = this.previous;
    const top = h.levelSizes.length - 1;
    for (let j = top; j >= this.minLevel; j--) {
      const what = `frame ${f} band ${j} positions`;
      const { shift, res } = readPositions(await this.c.chunk(this.c.find(ChunkKind.Positions, f, j)), what, h.levelSizes[j]);
      const lower = j === 0 ? this.lower : null;
      // Motion sums of the band's decoded nodes per parent (inter frames), exact in doubles.
      const nParents = j < top ? h.levelSizes[j + 1] : 0;
      const sibSum = new Float64Array(3 * nParents), sibCount = new Uint32Array(nParents);
      const fit = new Int32Array(3), inter0 = j === 0 && !intra;
      const affineBand = inter0 && h.motion === Motion.Affine, keyedBand = inter0 && h.motion === Motion.KeyframeAffine && this.weights !== null;
      // Band 0 in its decoding order, coarser bands in node order; `before`: the node decoded last.
      const sequence = lower ? lower.sequence : null;
      let before = -1;
      for (let k = 0; k < h.levelSizes[j]; k++) {
        const v = sequence ? sequence[k] : k;
        const g = r.offsets[j] + v;
        const local = j < top ? r.parent[j][v] : -1;
        const parent = j < top ? r.offsets[j + 1] + local : -1;
        const lo = lower ? lower.offsets[v] : 0, hi = lower ? lower.offsets[v + 1] : 0;
        const sib = !intra && local >= 0 && hi === lo ? sibCount[local] : 0;
        // Band 0 on inter frames: the affine motion of the vertex's stencil, when it fits.
        const affine = hi > lo && ((affineBand && affineMotion(lower!, v, cur, prev, fit)) || (keyedBand && keyedMotion(lower!, this.weights!, v, cur, prev, fit)));
        for (let a = 0; a < 3; a++) {
          let pred: number;
          if (affine) {
            pred = fit[a];
          } else if (sib > 0) {
            pred = (prev[3 * g + a] + Math.floor((2 * sibSum[3 * local + a] + sib) / (2 * sib))) | 0;
          } else if (hi > lo) {
            // Mean over the lower neighbours, rounded half up: floor((2 sum + c) / (2 c)).
            // Sums stay far below 2^53, so double arithmetic is exact here.
            const c = hi - lo, items = lower!.items;
            let sum = 0;
            if (intra) for (let i = lo; i < hi; i++) sum += cur[3 * items[i] + a];
            else for (let i = lo; i < hi; i++) sum += cur[3 * items[i] + a] - prev[3 * items[i] + a];
            const mean = Math.floor((2 * sum + c) / (2 * c));
            pred = intra ? mean | 0 : (prev[3 * g + a] + mean) | 0;
          } else if (intra) pred = parent >= 0 ? cur[3 * parent + a] : before >= 0 ? cur[3 * before + a] : 0;
          else pred = parent >= 0 ? prev[3 * g + a] + cur[3 * parent + a] - prev[3 * parent + a] : prev[3 * g + a];
          cur[3 * g + a] = (pred + (res[3 * k + a] << shift)) | 0;
          if (local >= 0) sibSum[3 * local + a] += cur[3 * g + a] - prev[3 * g + a];
        }
        if (local >= 0) sibCount[local]++;
        before = g;
      }
    }
  }

  /** Dequantized positions of every node (3 floats per global id). */
  positions(): Float32Array {
    const h = this.c.header;
    const out = new Float32Array(this.current.length);
    // f32 arithmetic, as the Rust decoder: lo + (q as f32) * step.
    for (let i = 0; i < out.length; i++) out[i] = Math.fround(h.bboxMin[i % 3] + Math.fround(this.current[i] * h.step));
    return out;
  }

  /**
   * The mesh of the cut the last `selectTriangles` chose, ordered as the Rust decoder orders a
   * budget cut: triangles in order of appearance, vertices in order of first use.
   */
  orderedMesh(positions: Float32Array): { positions: Float32Array; indices: Uint32Array; nodes: Uint32Array } {
    const r = this.replay;
    const rep = r.cutNodes();
    const base = r.offsets[r.minLevel];
    const indices = new Uint32Array(r.appearing.length * 3);
    const indexOf = new Map<number, number>();
    const nodes: number[] = [];
    r.appearing.forEach((t, i) => {
      for (let c = 0; c < 3; c++) {
        const g = rep[base + r.corners[3 * t + c]];
        let slot = indexOf.get(g);
        if (slot === undefined) { slot = nodes.length; indexOf.set(g, slot); nodes.push(g); }
        indices[3 * i + c] = slot;
      }
    });
    const pos = new Float32Array(nodes.length * 3);
    nodes.forEach((g, i) => pos.set(positions.subarray(3 * g, 3 * g + 3), 3 * i));
    return { positions: pos, indices, nodes: Uint32Array.from(nodes) };
  }
}

export { BELOW };

/**
 * For each input vertex, the distinct vertices sharing a triangle with it and decoded before it
 * in band 0's order (rows in decoding order), and its stencil: its row and the row of its row's
 * last vertex, merged (in decoding order, distinct). `sequence`: band 0's vertices in decoding
 * order (proto/container.md, "Band 0 order").
 */
export interface LowerNeighbours { sequence: Uint32Array; offsets: Uint32Array; items: Uint32Array; stencilOffsets: Uint32Array; stencilItems: Uint32Array }

/** Scratch for affineMotion's fit. */
const FIT = new Float64Array(8);

/**
 * The part of a stencil's affine fit that its positions `at` give (proto/container.md, "Affine
 * motion", up to `inv`), with `o` the vertex's position there: writes z0 z1 z2 k t det inv m
 * into `out`. Every operation is the spec's, in its order.
 */
function solveFit(items: Uint32Array, lo: number, hi: number, at: Int32Array, o0: number, o1: number, o2: number, out: Float64Array): void {
  let sa0 = 0, sa1 = 0, sa2 = 0, s00 = 0, s01 = 0, s02 = 0, s11 = 0, s12 = 0, s22 = 0;
  for (let i = lo; i < hi; i++) {
    const w = 3 * items[i];
    const a0 = at[w] - o0, a1 = at[w + 1] - o1, a2 = at[w + 2] - o2;
    sa0 += a0; sa1 += a1; sa2 += a2;
    s00 += a0 * a0; s01 += a0 * a1; s02 += a0 * a2; s11 += a1 * a1; s12 += a1 * a2; s22 += a2 * a2;
  }
  const m = hi - lo, im = 1 / m;
  let m00 = m * s00 - sa0 * sa0;
  const m01 = m * s01 - sa0 * sa1, m02 = m * s02 - sa0 * sa2;
  let m11 = m * s11 - sa1 * sa1;
  const m12 = m * s12 - sa1 * sa2;
  let m22 = m * s22 - sa2 * sa2;
  const t = (m00 + m11 + m22) * im * 0.015625 + m;
  m00 += t; m11 += t; m22 += t;
  const c00 = m11 * m22 - m12 * m12, c01 = m02 * m12 - m01 * m22, c02 = m01 * m12 - m02 * m11;
  const c11 = m00 * m22 - m02 * m02, c12 = m01 * m02 - m00 * m12, c22 = m00 * m11 - m01 * m01;
  const det = m00 * c00 + m01 * c01 + m02 * c02;
  const z0 = c00 * sa0 + c01 * sa1 + c02 * sa2;
  const z1 = c01 * sa0 + c11 * sa1 + c12 * sa2;
  const z2 = c02 * sa0 + c12 * sa1 + c22 * sa2;
  out[0] = z0; out[1] = z1; out[2] = z2;
  out[3] = sa0 * z0 + sa1 * z1 + sa2 * z2;
  out[4] = t; out[5] = det; out[6] = 1 / (det * m); out[7] = m;
}

/**
 * Band 0, inter frames, files encoded with affine motion (proto/container.md, "Affine
 * motion"): the affine map that best carries vertex v's stencil from the previous frame to
 * this one, applied to v, into `out`. False when the result does not fit an i32 (broken
 * input): the caller uses the mean motion. Every operation is the spec's, in its order (the
 * Rust decoder splits them in two passes, with the same results); doubles without fused
 * multiply-adds make the same bits.
 */
export function affineMotion(lower: LowerNeighbours, v: number, cur: Int32Array, prev: Int32Array, out: Int32Array): boolean {
  const lo = lower.stencilOffsets[v], hi = lower.stencilOffsets[v + 1], items = lower.stencilItems;
  if (hi === lo) return false;
  const o0 = prev[3 * v], o1 = prev[3 * v + 1], o2 = prev[3 * v + 2];
  // The previous frame's part.
  const f = FIT;
  solveFit(items, lo, hi, prev, o0, o1, o2, f);
  const z0 = f[0], z1 = f[1], z2 = f[2], k = f[3], t = f[4], det = f[5], inv = f[6], m = f[7];
  // This frame's part.
  let sb0 = 0, sb1 = 0, sb2 = 0, g0 = 0, g1 = 0, g2 = 0;
  for (let i = lo; i < hi; i++) {
    const w = 3 * items[i];
    const s = (prev[w] - o0) * z0 + (prev[w + 1] - o1) * z1 + (prev[w + 2] - o2) * z2;
    const b0 = cur[w] - o0, b1 = cur[w + 1] - o1, b2 = cur[w + 2] - o2;
    sb0 += b0; g0 += b0 * s;
    sb1 += b1; g1 += b1 * s;
    sb2 += b2; g2 += b2 * s;
  }
  const e0 = (sb0 * det - (m * g0 - sb0 * k + t * z0)) * inv + 0.5;
  const e1 = (sb1 * det - (m * g1 - sb1 * k + t * z1)) * inv + 0.5;
  const e2 = (sb2 * det - (m * g2 - sb2 * k + t * z2)) * inv + 0.5;
  // Also false for NaN.
  if (!(Math.abs(e0) < 2147483648 && Math.abs(e1) < 2147483648 && Math.abs(e2) < 2147483648)) return false;
  out[0] = (o0 + Math.floor(e0)) | 0;
  out[1] = (o1 + Math.floor(e1)) | 0;
  out[2] = (o2 + Math.floor(e2)) | 0;
  return true;
}

/** Rows of the triangles' edges (a, b) with keep(a, b), per a: distinct b, ascending. */
function neighbourRows(n: number, tris: Uint32Array, keep: (a: number, b: number) => boolean): { offsets: Uint32Array; items: Uint32Array } {
  const counts = new Uint32Array(n + 1);
  const pairs = (f: (a: number, b: number) => void) => {
    for (let t = 0; t + 2 < tris.length; t += 3) {
      for (let k = 0; k < 3; k++) {
        const a = tris[t + k], b = tris[t + ((k + 1) % 3)];
        if (a === b || a >= n || b >= n) continue;
        if (keep(a, b)) f(a, b);
        if (keep(b, a)) f(b, a);
      }
    }
  };
  pairs((a) => { counts[a + 1]++; });
  for (let i = 0; i < n; i++) counts[i + 1] += counts[i];
  const fill = counts.slice();
  const items = new Uint32Array(counts[n]);
  pairs((a, b) => { items[fill[a]++] = b; });
  const offsets = new Uint32Array(n + 1);
  let w = 0;
  for (let v = 0; v < n; v++) {
    const row = items.subarray(counts[v], counts[v + 1]).sort();
    const start = w;
    for (let i = 0; i < row.length; i++) if (w === start || items[w - 1] !== row[i]) items[w++] = row[i];
    offsets[v + 1] = w;
  }
  return { offsets, items: items.slice(0, w) };
}

/** Breadth first over the triangles' edges: from the smallest vertex not yet reached, FIFO, neighbours ascending. */
function breadthFirst(n: number, tris: Uint32Array): Uint32Array {
  const { offsets, items } = neighbourRows(n, tris, () => true);
  const seen = new Uint8Array(n), order = new Uint32Array(n);
  let len = 0;
  for (let start = 0; start < n; start++) {
    if (seen[start]) continue;
    seen[start] = 1;
    let head = len;
    order[len++] = start;
    while (head < len) {
      const v = order[head++];
      for (let i = offsets[v]; i < offsets[v + 1]; i++) {
        const u = items[i];
        if (!seen[u]) { seen[u] = 1; order[len++] = u; }
      }
    }
  }
  return order;
}

export function lowerNeighbours(n: number, tris: Uint32Array, order: VertexOrder = VertexOrder.Input): LowerNeighbours {
  const sequence = order === VertexOrder.BreadthFirst ? breadthFirst(n, tris) : Uint32Array.from({ length: n }, (_, i) => i);
  const rank = new Uint32Array(n);
  sequence.forEach((v, k) => { rank[v] = k; });
  const { offsets, items: rows } = neighbourRows(n, tris, (a, b) => rank[b] < rank[a]);
  const byRank = (x: number, y: number) => rank[x] - rank[y];
  for (let v = 0; v < n; v++) rows.subarray(offsets[v], offsets[v + 1]).sort(byRank);
  // Stencils: each vertex's row and its last lower neighbour's row, in decoding order, distinct.
  const mark = new Uint32Array(n).fill(0xffffffff);
  const stencilOffsets = new Uint32Array(n + 1);
  const stencil: number[] = [];
  const row: number[] = [];
  for (let v = 0; v < n; v++) {
    row.length = 0;
    // The row of v, and the row of its last (most recently decoded) lower neighbour.
    const lastAt = offsets[v + 1] - 1;
    for (let i = offsets[v]; i < offsets[v + 1]; i++) {
      const u = rows[i];
      if (mark[u] !== v) { mark[u] = v; row.push(u); }
      if (i !== lastAt) continue;
      for (let k = offsets[u]; k < offsets[u + 1]; k++) {
        const x = rows[k];
        if (mark[x] !== v) { mark[x] = v; row.push(x); }
      }
    }
    row.sort(byRank);
    for (const x of row) stencil.push(x);
    stencilOffsets[v + 1] = stencil.length;
  }
  return { sequence, offsets, items: rows, stencilOffsets, stencilItems: Uint32Array.from(stencil) };
}

/**
 * Keyframe affine motion (proto/container.md, "Keyframe affine motion"): from the keyframe's
 * band 0 `key`, one weight per stencil entry, lambda_w = (det - m (a_w . z) + k) / (det m), with
 * the fit's quantities computed as affineMotion computes them from the previous frame.
 */
export function stencilWeights(lower: LowerNeighbours, key: Int32Array, n: number): Float64Array {
  const items = lower.stencilItems, out = new Float64Array(items.length), f = new Float64Array(8);
  for (let v = 0; v < n; v++) {
    const lo = lower.stencilOffsets[v], hi = lower.stencilOffsets[v + 1];
    if (hi === lo) continue;
    const o0 = key[3 * v], o1 = key[3 * v + 1], o2 = key[3 * v + 2];
    solveFit(items, lo, hi, key, o0, o1, o2, f);
    const z0 = f[0], z1 = f[1], z2 = f[2], k = f[3], det = f[5], inv = f[6], m = f[7];
    for (let i = lo; i < hi; i++) {
      const w = 3 * items[i];
      const s = (key[w] - o0) * z0 + (key[w + 1] - o1) * z1 + (key[w + 2] - o2) * z2;
      out[i] = (det - m * s + k) * inv;
    }
  }
  return out;
}

/** Band 0, inter frames, keyframe affine motion: v's previous position plus its stencil's weighted motions, into `out`; false when it does not fit an i32. */
export function keyedMotion(lower: LowerNeighbours, weights: Float64Array, v: number, cur: Int32Array, prev: Int32Array, out: Int32Array): boolean {
  const lo = lower.stencilOffsets[v], hi = lower.stencilOffsets[v + 1], items = lower.stencilItems;
  if (hi === lo) return false;
  let e0 = 0, e1 = 0, e2 = 0;
  for (let i = lo; i < hi; i++) {
    const w = 3 * items[i], l = weights[i];
    e0 += l * (cur[w] - prev[w]);
    e1 += l * (cur[w + 1] - prev[w + 1]);
    e2 += l * (cur[w + 2] - prev[w + 2]);
  }
  e0 += 0.5; e1 += 0.5; e2 += 0.5;
  // Also false for NaN.
  if (!(Math.abs(e0) < 2147483648 && Math.abs(e1) < 2147483648 && Math.abs(e2) < 2147483648)) return false;
  out[0] = (prev[3 * v] + Math.floor(e0)) | 0;
  out[1] = (prev[3 * v + 1] + Math.floor(e1)) | 0;
  out[2] = (prev[3 * v + 2] + Math.floor(e2)) | 0;
  return true;
}

// rANS (proto/container.md, "Positions, band j"): 12-bit frequencies, states in [2^23, 2^31),
// three interleaved states. Every product freq * (x >>> 12) is below 2^31, so plain JS
// numbers and 32-bit operators compute it exactly.
const RANS_M = 4096, RANS_L = 1 << 23, RANS_SYMBOLS = 32, RANS_ESCAPE = 31, MAX_SHIFT = 16;

/** A positions chunk: its residual shift and 3 residuals per node (units of 2^shift quanta). */
export function readPositions(raw: Uint8Array, what: string, count: number): { shift: number; res: Int32Array } {
  const p = new Payload(raw, what);
  // shift + 32 * coding: 0 rANS, 1 plain zigzag varints (small bands, version 5).
  const first = p.get(), shift = first % 32, coding = Math.floor(first / 32);
  if (shift > MAX_SHIFT) throw new DecodeError(`${what}: residual shift ${shift} beyond ${MAX_SHIFT}`);
  if (coding === 1) {
    const res = new Int32Array(3 * count);
    for (let i = 0; i < 3 * count; i++) res[i] = p.zigzag();
    p.finish();
    return { shift, res };
  }
  if (coding !== 0) throw new DecodeError(`${what}: residual coding ${coding} (0 rANS, 1 varints)`);
  const tables: Uint32Array[] = [];
  for (let a = 0; a < 3; a++) {
    const n = p.count(RANS_SYMBOLS, "symbols");
    const freqs: number[] = [];
    let sum = 0;
    for (let s = 0; s < n; s++) { const f = p.get(); freqs.push(f); sum += f; }
    if (n === 0 || sum !== RANS_M) throw new DecodeError(`${what}: frequency table does not add up to 4096`);
    // Per slot: frequency (bits 0..12), offset in the symbol's range (13..24), symbol (25..29).
    const t = new Uint32Array(RANS_M);
    let at = 0;
    for (let s = 0; s < n; s++) { for (let k = 0; k < freqs[s]; k++) t[at + k] = freqs[s] | (k << 13) | (s << 25); at += freqs[s]; }
    tables.push(t);
  }
  const len = p.count(raw.length, "stream bytes");
  if (p.pos + len > raw.length) throw new DecodeError(`${what}: rANS stream beyond the chunk`);
  const stream = raw.subarray(p.pos, p.pos + len);
  p.pos += len;
  if (len < 12) throw new DecodeError(`${what}: rANS stream shorter than its states`);
  const x = [0, 0, 0];
  for (let w = 0; w < 3; w++) {
    x[w] = ((stream[4 * w] << 24) >>> 0) + (stream[4 * w + 1] << 16) + (stream[4 * w + 2] << 8) + stream[4 * w + 3];
    if (x[w] < RANS_L || x[w] >= 2 ** 31) throw new DecodeError(`${what}: rANS state out of range`);
  }
  let pos = 12, overrun = false;
  const res = new Int32Array(3 * count);
  for (let i = 0; i < 3 * count; i++) {
    const w = i % 3, t = tables[w];
    let s = x[w];
    const e = t[s & (RANS_M - 1)];
    s = (e & 0x1fff) * (s >>> 12) + ((e >>> 13) & 0xfff);
    while (s < RANS_L) {
      if (pos >= len) { overrun = true; s = RANS_L; break; }
      s = (s << 8) | stream[pos++];
    }
    x[w] = s;
    let z = e >>> 25;
    if (z === RANS_ESCAPE) {
      z = p.get() + RANS_ESCAPE;
      if (z > 0xffffffff) throw new DecodeError(`${what}: escaped residual beyond 32 bits`);
    }
    res[i] = (z >>> 1) ^ -(z & 1);
  }
  if (overrun) throw new DecodeError(`${what}: rANS stream ends early`);
  if (pos !== len || x[0] !== RANS_L || x[1] !== RANS_L || x[2] !== RANS_L) throw new DecodeError(`${what}: rANS stream does not end where it should`);
  p.finish();
  return { shift, res };
}
