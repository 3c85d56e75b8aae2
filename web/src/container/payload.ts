// The readers of what a file's bytes hold, as `pmcodec_container::payload`: postcard (the
// header and index) and the varint payloads of the chunks (proto/container.md, "Chunks"):
// triangles, keyframe parent maps, faces, corner updates, swaps and position residuals.

import { DecodeError } from "./error.js";
import { decodeResiduals, ESCAPE, MAX_SYMBOLS, rAnsTable } from "./rans.js";
import type { FrameDelta, KeyBand } from "./replay.js";
import { coded, readCornerUpdatesCoded, readDeltaCoded, readFacesCoded, readKeyCoded } from "./topology.js";

/** postcard's wire format, the parts the header and index use. */
export class Postcard {
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

/** Varint payload reader (proto/container.md, "Chunks"), the Rust side's `payload::Cursor`. */
export class Cursor {
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
  /** A 4-byte little-endian value (a CRC-32 in the version 7 index). */
  u32le(): number {
    if (this.pos + 4 > this.b.length) throw new DecodeError(`${this.what}: ends inside a 4-byte value`);
    const v = (this.b[this.pos] | (this.b[this.pos + 1] << 8) | (this.b[this.pos + 2] << 16) | (this.b[this.pos + 3] << 24)) >>> 0;
    this.pos += 4;
    return v;
  }
  finish(): void { if (this.pos !== this.b.length) throw new DecodeError(`${this.what}: ${this.b.length - this.pos} bytes left over`); }
}

/**
 * The triangles chunk: `triangles` input triangles, 3 vertex ids each; from version 7 each as
 * the zigzag-coded difference from the same corner of the triangle before (32-bit wrapping).
 */
export function readTriangles(raw: Uint8Array, what: string, triangles: number, vertices: number, version: number): Uint32Array {
  const start = version >= 7 ? coded(raw, what) : null;
  if (start !== null) {
    // Coding 1: a Faces chunk's coding 1 of every triangle in order (each gap 0).
    const faces = readFacesCoded(raw, start, what, vertices, triangles);
    if (faces.length !== triangles) throw new DecodeError(`${what}: ${faces.length} triangles where the header says ${triangles}`);
    const tris = new Uint32Array(3 * triangles);
    faces.forEach((f, i) => tris.set(f.corners, 3 * i));
    return tris;
  }
  const p = new Cursor(raw, what);
  const n = p.count(triangles, "triangles");
  if (n !== triangles) throw new DecodeError(`${what}: ${n} triangles`);
  if (3 * n > raw.length - p.pos) throw new DecodeError(`${what}: ${n} triangles in ${raw.length - p.pos} bytes`);
  const tris = new Uint32Array(3 * n);
  for (let i = 0; i < 3 * n; i++) {
    if (version < 7) { tris[i] = p.id(vertices, "vertex"); continue; }
    const v = ((i < 3 ? 0 : tris[i - 3]) + p.zigzag()) >>> 0;
    if (v >= vertices) throw new DecodeError(`${what}: vertex ${v} out of range`);
    tris[i] = v;
  }
  p.finish();
  return tris;
}

/** Key coding 3: the changes from frame 0's parent map of the band (proto/container.md, "Key"). */
export const KEY_FROM_FIRST = 3;

/** Whether a Key payload is in coding 3, which `readKey` reads with frame 0's parents. */
export function keyFromFirst(raw: Uint8Array): boolean {
  return raw.length > 2 && raw[0] === 0 && raw[1] === KEY_FROM_FIRST;
}

/**
 * A keyframe's parent map of `band` (empty for the top band); from version 7 each parent as the
 * zigzag-coded difference from the node before's (32-bit wrapping). In coding 3, `first` (the
 * band's parents in frame 0's Key chunk) with the nodes the chunk lists moved.
 */
export function readKey(raw: Uint8Array, what: string, sizes: number[], band: number, version: number, first?: Uint32Array): Uint32Array {
  const top = sizes.length - 1;
  if (version >= 7 && keyFromFirst(raw)) {
    if (band >= top) throw new DecodeError(`${what}: Key coding 3 in the top band`);
    if (!first) throw new DecodeError(`${what}: Key coding 3 read without frame 0's parents (or in frame 0's Key chunk)`);
    if (first.length !== sizes[band]) throw new DecodeError(`${what}: ${first.length} parents of frame 0 for ${sizes[band]} nodes`);
    const parent = Uint32Array.from(first);
    for (const [v, p] of readDeltaCoded(raw, 2, what, sizes[band], sizes[band + 1])) parent[v] = p;
    return parent;
  }
  const start = coded(raw, what);
  if (start !== null) return readKeyCoded(raw, start, what, band < top ? sizes[band] : 0, band < top ? sizes[band + 1] : 0);
  const c = new Cursor(raw, what);
  const n = c.count(sizes[band], "parents");
  if (n !== (band < top ? sizes[band] : 0)) throw new DecodeError(`${what}: ${n} parents`);
  const parent = new Uint32Array(n);
  for (let i = 0; i < n; i++) {
    if (version < 7) { parent[i] = c.id(sizes[band + 1], "parent"); continue; }
    const p = ((i === 0 ? 0 : parent[i - 1]) + c.zigzag()) >>> 0;
    if (p >= sizes[band + 1]) throw new DecodeError(`${what}: parent ${p} out of range`);
    parent[i] = p;
  }
  c.finish();
  return parent;
}

/**
 * Faces (keyframes) of one band: triangle ascending, 3 corners, from version 5 each the zigzag
 * difference from the same corner of the face before; in versions 3 and 4 plain, and corner
 * updates (frames) coded the same way.
 */
export function readFaces(raw: Uint8Array, what: string, size: number, triangles: number, version: number): KeyBand["faces"] {
  // A 0 followed by more bytes: the bit coding (coding 1, topology.ts).
  const start = coded(raw, what);
  if (start !== null) return readFacesCoded(raw, start, what, size, triangles);
  const c = new Cursor(raw, what);
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
export function readCornerUpdates(raw: Uint8Array, what: string, size: number, held: Uint32Array): KeyBand["faces"] {
  const start = coded(raw, what);
  if (start !== null) return readCornerUpdatesCoded(raw, start, what, size, held);
  const c = new Cursor(raw, what);
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

/** The swaps of one band of a frame (node ascending, new parent), appended to `out`. */
export function readDelta(raw: Uint8Array, what: string, sizes: number[], band: number, out: FrameDelta): void {
  const top = sizes.length - 1;
  const start = coded(raw, what);
  if (start !== null) {
    for (const [v, to] of readDeltaCoded(raw, start, what, band < top ? sizes[band] : 0, band < top ? sizes[band + 1] : 0)) out.swaps.push({ level: band, v, to });
    return;
  }
  const c = new Cursor(raw, what);
  const n = c.count(band < top ? sizes[band] : 0, "moves");
  const prev = { v: null as number | null };
  for (let i = 0; i < n; i++) {
    const v = c.ascending(prev, sizes[band], "node");
    out.swaps.push({ level: band, v, to: c.id(sizes[band + 1], "parent") });
  }
  c.finish();
}

/** The largest residual shift a positions chunk may declare. */
export const MAX_SHIFT = 16;

/** A positions chunk: its residual shift and 3 residuals per node (units of 2^shift quanta). */
export function readPositions(raw: Uint8Array, what: string, count: number): { shift: number; res: Int32Array } {
  const p = new Cursor(raw, what);
  // shift + 32 * coding: 0 rANS, 1 plain zigzag varints (small bands, version 5), 2 sparse.
  const first = p.get(), shift = first % 32, coding = Math.floor(first / 32);
  if (shift > MAX_SHIFT) throw new DecodeError(`${what}: residual shift ${shift} beyond ${MAX_SHIFT}`);
  if (coding === 1) {
    const res = new Int32Array(3 * count);
    for (let i = 0; i < 3 * count; i++) res[i] = p.zigzag();
    p.finish();
    return { shift, res };
  }
  if (coding === 2) {
    // Sparse: the listed nodes, each after the count of all-zero nodes skipped to reach it.
    const listed = p.count(count, "listed nodes");
    if (listed * 4 > raw.length - p.pos) throw new DecodeError(`${what}: ${listed} listed nodes in ${raw.length - p.pos} bytes`);
    const res = new Int32Array(3 * count);
    let next = 0;
    for (let k = 0; k < listed; k++) {
      const v = next + p.get();
      if (v >= count) throw new DecodeError(`${what}: listed node ${v} beyond the band's ${count}`);
      for (let a = 0; a < 3; a++) res[3 * v + a] = p.zigzag();
      next = v + 1;
    }
    p.finish();
    return { shift, res };
  }
  if (coding !== 0) throw new DecodeError(`${what}: residual coding ${coding} (0 rANS, 1 varints, 2 sparse)`);
  // One frequency table per axis, then the stream; escapes follow it, read as they are met.
  const tables: Uint32Array[] = [];
  for (let a = 0; a < 3; a++) {
    const n = p.count(MAX_SYMBOLS, "symbols");
    const freqs: number[] = [];
    for (let s = 0; s < n; s++) freqs.push(p.get());
    tables.push(rAnsTable(freqs, what));
  }
  const len = p.count(raw.length, "stream bytes");
  if (p.pos + len > raw.length) throw new DecodeError(`${what}: rANS stream beyond the chunk`);
  const stream = raw.subarray(p.pos, p.pos + len);
  p.pos += len;
  const res = new Int32Array(3 * count);
  decodeResiduals(stream, tables, res, what, () => {
    const z = p.get() + ESCAPE;
    if (z > 0xffffffff) throw new DecodeError(`${what}: escaped residual beyond 32 bits`);
    return z;
  });
  p.finish();
  return { shift, res };
}
