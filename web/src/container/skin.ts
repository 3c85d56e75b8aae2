// Skinned streams (format version 6), as `pmcodec_container::skin`: every node's bind position
// and influences (Bind chunks), each frame's joint palette and skinned bands (Pose chunks), and
// the integer linear blend skinning that predicts node positions (proto/container.md,
// "Skinning"). The arithmetic is wrapping 64-bit, done with BigInt so it matches Rust bit for bit.

import { DecodeError } from "./error.js";

export const MAX_PALETTE = 1 << 16;
const MAX_BIND = 1n << 30n, MAX_MATRIX = 1n << 40n, WEIGHT_ONE = 1n << 16n;
const LINEAR_BITS = 15n, TRANSLATION_BITS = 2n;
export const ENTRY = 12;

/** The header's skin fields. */
export interface SkinHeader { paletteLen: number; bindStep: number }

/** Every decoded node's skin: bind position and up to four (entry, weight) influences. */
export interface NodeSkins { bind: BigInt64Array; joints: Uint32Array; weights: BigInt64Array; count: Uint8Array }

export function nodeSkins(n: number): NodeSkins {
  return { bind: new BigInt64Array(3 * n), joints: new Uint32Array(4 * n), weights: new BigInt64Array(4 * n), count: new Uint8Array(n) };
}

/** Varints up to 64 bits (the tenth byte at most 1). */
class Cursor64 {
  pos = 0;
  constructor(private b: Uint8Array, private what: string) {}
  corrupt(detail: string): DecodeError { return new DecodeError(`${this.what}: ${detail}`); }
  get(): bigint {
    let v = 0n;
    for (let shift = 0n; shift < 64n; shift += 7n) {
      if (this.pos >= this.b.length) throw this.corrupt(`ends inside a number at byte ${this.pos}`);
      const byte = this.b[this.pos++];
      if (shift === 63n && byte > 1) throw this.corrupt("number beyond 64 bits");
      v |= BigInt(byte & 0x7f) << shift;
      if (!(byte & 0x80)) return v;
    }
    throw this.corrupt("number longer than 10 bytes");
  }
  signed(): bigint { const z = this.get(); return BigInt.asIntN(64, (z >> 1n) ^ -(z & 1n)); }
  finish(): void { if (this.pos !== this.b.length) throw this.corrupt(`${this.b.length - this.pos} bytes left over`); }
}

const abs = (v: bigint): bigint => (v < 0n ? -v : v);
const MAX_QUATERNION = 1n << 24n, MAX_SCALE = 1n << 48n, SCALE_ONE = 1n << 8n;

/** An entry's rigid parameters (Joints chunks): quaternion w, x, y, z and the uniform scale in 2^-8 linear units. */
export type Rig = bigint[];

/**
 * The integer matrix (row-major) of quaternion `r[0..4]` scaled by `r[4] / 2^8`, as `skin::rig_matrix`:
 * `L[a][c] = floor((2 s N[a][c] + 2^8 n) / (2^9 n))`, exact in BigInt; null for the zero quaternion.
 */
export function rigMatrix(r: Rig): bigint[] | null {
  const [w, x, y, z, s] = r;
  const n = w * w + x * x + y * y + z * z;
  if (n === 0n) return null;
  const num = [
    w * w + x * x - y * y - z * z, 2n * (x * y - w * z), 2n * (x * z + w * y),
    2n * (x * y + w * z), w * w - x * x + y * y - z * z, 2n * (y * z - w * x),
    2n * (x * z - w * y), 2n * (y * z + w * x), w * w - x * x - y * y + z * z,
  ];
  return num.map((m) => {
    const a = 2n * s * m + SCALE_ONE * n, b = 2n * SCALE_ONE * n;
    const q = a / b;
    // BigInt division truncates; the format's is a floor.
    return a % b < 0n ? q - 1n : q;
  });
}

/** Bits, least significant first within each byte, and Exp-Golomb codes of them. */
class Bits {
  bit = 0;
  constructor(private b: Uint8Array, private start: number, private what: string) {}
  corrupt(detail: string): DecodeError { return new DecodeError(`${this.what}: ${detail}`); }
  one(): number {
    const i = this.start + (this.bit >> 3);
    if (i >= this.b.length) throw this.corrupt(`ends inside its bits at byte ${this.b.length - this.start}`);
    const v = (this.b[i] >> (this.bit & 7)) & 1;
    this.bit++;
    return v;
  }
  get(n: number): number { let v = 0; for (let i = 0; i < n; i++) v |= this.one() << i; return v; }
  golomb(k: number): bigint {
    let zeros = 0;
    while (this.one() === 0) if (++zeros + k >= 64) throw this.corrupt("a number beyond 64 bits");
    let v = 1n;
    for (let i = 0; i < zeros + k; i++) v = (v << 1n) | BigInt(this.one());
    return v - (1n << BigInt(k));
  }
  signed(k: number): bigint { const z = this.golomb(k); return BigInt.asIntN(64, (z >> 1n) ^ -(z & 1n)); }
  finish(): void {
    const end = this.start + Math.ceil(this.bit / 8);
    if (end !== this.b.length) throw this.corrupt(`${this.b.length - end} bytes left over`);
    if (this.bit % 8 !== 0 && this.b[end - 1] >> (this.bit % 8) !== 0) throw this.corrupt("bits set after its last number");
  }
}
const wrap = (v: bigint): bigint => BigInt.asIntN(64, v);

/** Reads a Bind chunk of `count` nodes into `out` from node `offset` on. */
export function readBinds(raw: Uint8Array, what: string, count: number, palette: number, out: NodeSkins, offset: number): void {
  const c = new Cursor64(raw, what);
  if (count * 4 > raw.length) throw c.corrupt(`${count} nodes in ${raw.length} bytes`);
  const before = [0n, 0n, 0n];
  for (let v = 0; v < count; v++) {
    const g = offset + v;
    for (let a = 0; a < 3; a++) {
      const b = wrap(before[a] + c.signed());
      if (abs(b) > MAX_BIND) throw c.corrupt(`node ${v}: bind coordinate ${b} beyond the limit of ${MAX_BIND}`);
      before[a] = b;
      out.bind[3 * g + a] = b;
    }
    const k = c.get();
    if (k > 4n) throw c.corrupt(`node ${v}: ${k} influences, more than 4`);
    const n = Number(k);
    for (let s = 0; s < n; s++) {
      const j = c.get();
      if (j >= BigInt(palette)) throw c.corrupt(`node ${v} influence ${s}: joint ${j} beyond the palette of ${palette}`);
      out.joints[4 * g + s] = Number(j);
    }
    let left = WEIGHT_ONE;
    for (let s = 0; s < n; s++) {
      let w = s + 1 === n ? left : c.get();
      if (w > WEIGHT_ONE + 1n) w = WEIGHT_ONE + 1n;
      if (w <= 0n || w > left) throw c.corrupt(`node ${v}: weights do not sum to ${WEIGHT_ONE} with every one positive`);
      out.weights[4 * g + s] = w;
      left -= w;
    }
    out.count[g] = n;
  }
  c.finish();
}

/**
 * The palette entries each band's Palette chunk carries: those some node of the band uses and
 * no node of a coarser band does, ascending (bands below `minLevel` get none), as
 * `skin::band_entries`.
 */
export function bandEntries(nodes: NodeSkins, levelSizes: number[], minLevel: number, paletteLen: number): number[][] {
  const taken = new Uint8Array(paletteLen);
  const out: number[][] = levelSizes.map(() => []);
  const offsets = [0];
  for (const n of levelSizes) offsets.push(offsets[offsets.length - 1] + n);
  for (let j = levelSizes.length - 1; j >= minLevel; j--) {
    for (let g = offsets[j]; g < offsets[j + 1]; g++) {
      for (let k = 0; k < nodes.count[g]; k++) {
        const e = nodes.joints[4 * g + k];
        if (nodes.weights[4 * g + k] > 0n && e < paletteLen && !taken[e]) { taken[e] = 1; out[j].push(e); }
      }
    }
    out[j].sort((a, b) => a - b);
  }
  return out;
}

/** Whether band `j` has a Palette chunk in each frame: the top band always, another when it has entries. */
export function hasPaletteChunk(bands: number[][], j: number): boolean {
  return j + 1 === bands.length || (bands[j]?.length ?? 0) > 0;
}

/** The palettes a decoder holds: the current frame's, and the previous frame's unless the current is a keyframe. */
export class SkinState {
  palette: BigInt64Array | null = null;
  previous: BigInt64Array | null = null;
  mask = 0n;
  /** Files with Palette or Joints chunks: each band's entries (`bandEntries`); null: one Pose chunk per frame. */
  bands: number[][] | null = null;
  /** The file's palettes are in Joints chunks. */
  joints = false;
  /** Files with Joints chunks: each entry's rigid parameters in the current and the previous frame (null: not rigid). */
  rig: (Rig | null)[] = [];
  rigBefore: (Rig | null)[] = [];
  constructor(readonly nodes: NodeSkins) {}

  uses(j: number): boolean { return j < 64 && ((this.mask >> BigInt(j)) & 1n) === 1n; }

  /** Reads a Pose chunk predicted from the held palettes; returns the palette and mask, not yet applied. */
  readPose(raw: Uint8Array, what: string, entries: number, levels: number, intra: boolean): { palette: BigInt64Array; mask: bigint } {
    const c = new Cursor64(raw, what);
    const mask = c.get();
    if (levels < 64 && mask >> BigInt(levels) !== 0n) throw c.corrupt(`band mask 0x${mask.toString(16)} names bands beyond the file's ${levels}`);
    const n = entries * ENTRY;
    if (n > raw.length) throw c.corrupt(`${entries} palette entries in ${raw.length} bytes`);
    const p = intra ? null : this.palette, q = intra ? null : this.previous;
    const out = new BigInt64Array(n);
    for (let i = 0; i < n; i++) {
      const predicted = p === null ? 0n : q === null ? (p[i] ?? 0n) : wrap(2n * (p[i] ?? 0n) - (q[i] ?? 0n));
      const v = wrap(predicted + c.signed());
      if (abs(v) > MAX_MATRIX) throw c.corrupt(`palette entry ${Math.floor(i / ENTRY)} ${i % 4 === 3 ? "translation" : "linear value"} ${v} beyond the limit of ${MAX_MATRIX}`);
      out[i] = v;
    }
    c.finish();
    return { palette: out, mask };
  }

  /**
   * Reads a Palette chunk carrying `entries` into `out` (the frame's palette, entries it does not
   * carry left as they are), predicted from the held palettes; returns the band mask.
   */
  readPalette(raw: Uint8Array, what: string, entries: number[], levels: number, intra: boolean, out: BigInt64Array): bigint {
    const c = new Cursor64(raw, what);
    const mask = c.get();
    if (levels < 64 && mask >> BigInt(levels) !== 0n) throw c.corrupt(`band mask 0x${mask.toString(16)} names bands beyond the file's ${levels}`);
    const p = intra ? null : this.palette, q = intra ? null : this.previous;
    const moved = new Uint8Array(entries.length).fill(1);
    if (p !== null) {
      const n = Math.ceil(entries.length / 8);
      if (c.pos + n > raw.length) throw c.corrupt(`ends inside the bits of its ${entries.length} entries`);
      for (let k = 0; k < entries.length; k++) moved[k] = (raw[c.pos + (k >> 3)] >> (k & 7)) & 1;
      if (entries.length % 8 !== 0 && raw[c.pos + n - 1] >> (entries.length % 8) !== 0) throw c.corrupt(`bits set beyond its ${entries.length} entries`);
      c.pos += n;
    }
    const changed = moved.reduce((a, b) => a + b, 0);
    if (changed * ENTRY > raw.length - c.pos) throw c.corrupt(`${changed} entries' values in ${raw.length - c.pos} bytes`);
    for (let k = 0; k < entries.length; k++) {
      const e = entries[k];
      for (let i = e * ENTRY; i < (e + 1) * ENTRY; i++) {
        let v: bigint;
        if (p !== null && !moved[k]) v = p[i] ?? 0n;
        else {
          const predicted = p === null ? 0n : q === null ? (p[i] ?? 0n) : wrap(2n * (p[i] ?? 0n) - (q[i] ?? 0n));
          v = wrap(predicted + c.signed());
        }
        if (abs(v) > MAX_MATRIX) throw c.corrupt(`palette entry ${e} ${i % 4 === 3 ? "translation" : "linear value"} ${v} beyond the limit of ${MAX_MATRIX}`);
        if (i >= out.length) throw c.corrupt(`palette entry ${e} beyond the palette of ${out.length / ENTRY}`);
        out[i] = v;
      }
    }
    c.finish();
    return mask;
  }

  /**
   * Reads a Joints chunk carrying `entries` into `out` and `rig` (the frame's palette and rigid
   * parameters; entries it does not carry left as they are), predicted from the held palettes
   * and rigid parameters; returns the band mask (proto/container.md, "Joints").
   */
  readJoints(raw: Uint8Array, what: string, entries: number[], levels: number, intra: boolean, out: BigInt64Array, rig: (Rig | null)[]): bigint {
    const c = new Cursor64(raw, what);
    const mask = c.get();
    if (levels < 64 && mask >> BigInt(levels) !== 0n) throw c.corrupt(`band mask 0x${mask.toString(16)} names bands beyond the file's ${levels}`);
    const p = intra ? null : this.palette, q = intra ? null : this.previous;
    const predicted = (i: number): bigint => (p === null ? 0n : q === null ? (p[i] ?? 0n) : wrap(2n * (p[i] ?? 0n) - (q[i] ?? 0n)));
    const rigAt = (e: number): bigint[] => {
      const a = p === null ? null : (this.rig[e] ?? null), b = q === null ? null : (this.rigBefore[e] ?? null);
      if (a === null) return [0n, 0n, 0n, 0n, 0n];
      return b === null ? a : a.map((v, i) => wrap(2n * v - b[i]));
    };
    const r = new Bits(raw, c.pos, what);
    const orders = [r.get(5), r.get(5), r.get(5), r.get(5)];
    for (const e of entries) {
      const base = e * ENTRY;
      if (base + ENTRY > out.length || e >= rig.length) throw r.corrupt(`palette entry ${e} beyond the palette of ${out.length / ENTRY}`);
      if (p !== null && r.one() === 0) {
        for (let i = base; i < base + ENTRY; i++) out[i] = p[i] ?? 0n;
        rig[e] = this.rig[e] ?? null;
        continue;
      }
      const values: bigint[] = new Array(ENTRY);
      if (r.one() === 1) {
        const pr = rigAt(e);
        const g = pr.map((v, i) => wrap(v + r.signed(orders[i < 4 ? 0 : 1])));
        if (g.slice(0, 4).some((v) => abs(v) > MAX_QUATERNION)) throw r.corrupt(`palette entry ${e}: quaternion [${g.slice(0, 4).join(", ")}] beyond the limit of ${MAX_QUATERNION}`);
        if (abs(g[4]) > MAX_SCALE) throw r.corrupt(`palette entry ${e}: scale ${g[4]} beyond the limit of ${MAX_SCALE}`);
        const m = rigMatrix(g);
        if (m === null) throw r.corrupt(`palette entry ${e}: the zero quaternion`);
        for (let a = 0; a < 3; a++) {
          for (let k = 0; k < 3; k++) values[4 * a + k] = m[3 * a + k];
          values[4 * a + 3] = wrap(predicted(base + 4 * a + 3) + r.signed(orders[2]));
        }
        rig[e] = g;
      } else {
        for (let i = 0; i < ENTRY; i++) values[i] = wrap(predicted(base + i) + r.signed(orders[3]));
        rig[e] = null;
      }
      for (let i = 0; i < ENTRY; i++) {
        if (abs(values[i]) > MAX_MATRIX) throw r.corrupt(`palette entry ${e} ${i % 4 === 3 ? "translation" : "linear value"} ${values[i]} beyond the limit of ${MAX_MATRIX}`);
        out[base + i] = values[i];
      }
    }
    r.finish();
    return mask;
  }

  advance(palette: BigInt64Array, intra: boolean, mask: bigint, rig: (Rig | null)[] = []): void {
    this.previous = intra ? null : this.palette;
    this.palette = palette;
    this.mask = mask;
    this.rigBefore = intra ? [] : this.rig;
    this.rig = rig;
  }

  /** Node `g` posed by `palette`, in position quanta, written to out[0..3]. */
  lbs(g: number, palette: BigInt64Array, out: Int32Array): void {
    const s = this.nodes;
    let ax = 0n, ay = 0n, az = 0n;
    const b0 = s.bind[3 * g], b1 = s.bind[3 * g + 1], b2 = s.bind[3 * g + 2];
    for (let k = 0; k < s.count[g]; k++) {
      const w = s.weights[4 * g + k], m = s.joints[4 * g + k] * ENTRY;
      if (m + ENTRY > palette.length) continue;
      const y = (a: number): bigint => {
        const r = m + 4 * a;
        const dot = wrap(wrap(wrap(palette[r] * b0) + wrap(palette[r + 1] * b1)) + wrap(palette[r + 2] * b2));
        return wrap((dot >> (LINEAR_BITS - TRANSLATION_BITS)) + palette[r + 3]);
      };
      ax = wrap(ax + wrap(w * y(0)));
      ay = wrap(ay + wrap(w * y(1)));
      az = wrap(az + wrap(w * y(2)));
    }
    const round = 1n << (15n + TRANSLATION_BITS), shift = 16n + TRANSLATION_BITS;
    out[0] = Number(BigInt.asIntN(32, wrap(ax + round) >> shift));
    out[1] = Number(BigInt.asIntN(32, wrap(ay + round) >> shift));
    out[2] = Number(BigInt.asIntN(32, wrap(az + round) >> shift));
  }

  /** The skinning prediction of node `g` (proto/container.md, "Skinning") into out[0..3]. */
  predict(g: number, intra: boolean, prev: Int32Array, out: Int32Array, scratch: Int32Array): void {
    if (this.palette === null) throw new DecodeError("skin: no pose read");
    this.lbs(g, this.palette, out);
    if (intra) return;
    this.lbs(g, this.previous ?? new BigInt64Array(0), scratch);
    for (let a = 0; a < 3; a++) out[a] = (prev[3 * g + a] + ((out[a] - scratch[a]) | 0)) | 0;
  }
}
