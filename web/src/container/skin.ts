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

/** No reference (linked Joints coding): the entry is predicted from its own previous frames. */
export const NO_REF = -1;
/** The first 5 bits of a Joints chunk in the linked coding. */
const LINKED = 31;
/** The first 5 bits of a Joints chunk in the compact coding. */
const COMPACT = 30;
/** A class's order in the compact coding that says its numbers in the chunk are all 0. */
const ZERO_CLASS = 31;

/** An entry's link (linked Joints coding): its reference entry (NO_REF: none) and pivot in bind quanta. */
export interface Link { reference: number; pivot: bigint[] }
export const NO_LINK: Link = { reference: NO_REF, pivot: [0n, 0n, 0n] };

/**
 * An entry's prediction: rigid parameters, translations when not linked, whether linked, and
 * when linked the reference's linear values and translations now and the pivot.
 */
interface Predicted { rig: bigint[]; t: bigint[]; linked: boolean; anchor: { l: bigint[]; t: bigint[]; c: bigint[] } | null }

/** The predicted translations of an entry whose linear part is `l`, as `Predicted::translation`. */
function predictedTranslation(p: Predicted, l: bigint[]): bigint[] {
  const an = p.anchor;
  if (an === null) return p.t;
  return [0, 1, 2].map((a) => {
    let dot = 0n;
    for (let k = 0; k < 3; k++) dot += (an.l[3 * a + k] - l[3 * a + k]) * an.c[k];
    // BigInt >> is a floor, as Rust's on i128.
    return wrap(an.t[a] + wrap(dot >> (LINEAR_BITS - TRANSLATION_BITS)));
  });
}

/** Floor division `a / d` rounded half up, `d > 0`: `floor((2a + d) / 2d)`, as `hierarchy::rdiv`. */
function rdiv(a: bigint, d: bigint): bigint {
  const x = 2n * a + d, y = 2n * d;
  const q = x / y;
  return x % y < 0n ? q - 1n : q;
}

function qmul(a: bigint[], b: bigint[]): bigint[] {
  const [aw, ax, ay, az] = a, [bw, bx, by, bz] = b;
  return [
    aw * bw - ax * bx - ay * by - az * bz,
    aw * bx + ax * bw + ay * bz - az * by,
    aw * by - ax * bz + ay * bw + az * bx,
    aw * bz + ax * by - ay * bx + az * bw,
  ];
}
const conj = (q: bigint[]): bigint[] => [q[0], -q[1], -q[2], -q[3]];
const norm2 = (q: bigint[]): bigint => q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];

/** Whether entry `p` is read before entry `e` (a coarser band, or the same band and a smaller index), as `hierarchy::read_before`. */
function readBefore(bands: number[][], p: number, e: number): boolean {
  const bp = bands.findIndex((b) => b.includes(p)), be = bands.findIndex((b) => b.includes(e));
  return bp >= 0 && be >= 0 && (bp > be || (bp === be && p < e));
}

interface Held { palette: BigInt64Array | null; previous: BigInt64Array | null; rig: (Rig | null)[]; rigBefore: (Rig | null)[]; rigAt: (e: number) => bigint[]; predicted: (i: number) => bigint }

/** Entry `e`'s prediction in the linked coding, as `hierarchy::predict` (proto/container.md, "Joints", "Linked coding"). */
function predictLinked(e: number, link: Link, held: Held, now: BigInt64Array, nowRig: (Rig | null)[]): Predicted {
  const base = e * ENTRY;
  const temporal: Predicted = { rig: held.rigAt(e), t: [3, 7, 11].map((i) => held.predicted(base + i)), linked: false, anchor: null };
  const p = link.reference;
  if (p === NO_REF) return temporal;
  const a = nowRig[p] ?? null;
  if (a === null) return temporal;
  const l: bigint[] = [];
  for (let i = 0; i < 9; i++) l.push(now[p * ENTRY + 4 * Math.floor(i / 3) + (i % 3)] ?? 0n);
  const anchor = { l, t: [3, 7, 11].map((i) => now[p * ENTRY + i] ?? 0n), c: link.pivot };
  if (held.palette === null) return { rig: a.slice(), t: temporal.t, linked: true, anchor };
  const b = held.rig[p] ?? null, c = held.rig[e] ?? null;
  if (b === null || c === null) return temporal;
  let r = qmul(conj(b.slice(0, 4)), c.slice(0, 4));
  if (held.previous !== null) {
    const b2 = held.rigBefore[p] ?? null, c2 = held.rigBefore[e] ?? null;
    if (b2 !== null && c2 !== null) {
      const r2 = qmul(conj(b2.slice(0, 4)), c2.slice(0, 4));
      r = r.map((v, i) => 2n * v - r2[i]);
    }
  }
  let nb = norm2(b.slice(0, 4));
  if (nb < 1n) nb = 1n;
  const q = qmul(a.slice(0, 4), r).map((v) => wrap(rdiv(v, nb)));
  return { rig: [...q, temporal.rig[4]], t: temporal.t, linked: true, anchor };
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
  /** Files with Joints chunks: each entry's link in the linked coding since the last keyframe. */
  links: Link[] = [];
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
   * Reads band `j`'s Joints chunk (carrying `bands[j]`) into `out`, `rig` and `links` (the frame's
   * palette, rigid parameters and links; entries it does not carry left as they are, those
   * of coarser bands already read), predicted from the held palettes, rigid parameters and
   * links; returns the band mask (proto/container.md, "Joints"). Reads the plain coding, the
   * linked one (first 5 bits 31) and the compact one (first 5 bits 30).
   */
  readJoints(raw: Uint8Array, what: string, bands: number[][], j: number, levels: number, intra: boolean, out: BigInt64Array, rig: (Rig | null)[], links: Link[]): bigint {
    const c = new Cursor64(raw, what);
    const mask = c.get();
    if (levels < 64 && mask >> BigInt(levels) !== 0n) throw c.corrupt(`band mask 0x${mask.toString(16)} names bands beyond the file's ${levels}`);
    const entries = bands[j] ?? [];
    const p = intra ? null : this.palette, q = intra ? null : this.previous;
    const predicted = (i: number): bigint => (p === null ? 0n : q === null ? (p[i] ?? 0n) : wrap(2n * (p[i] ?? 0n) - (q[i] ?? 0n)));
    const rigAt = (e: number): bigint[] => {
      const a = p === null ? null : (this.rig[e] ?? null), b = q === null ? null : (this.rigBefore[e] ?? null);
      if (a === null) return [0n, 0n, 0n, 0n, 0n];
      return b === null ? a : a.map((v, i) => wrap(2n * v - b[i]));
    };
    const r = new Bits(raw, c.pos, what);
    const n = Math.floor(out.length / ENTRY);
    for (const e of entries) {
      if (e >= n || e >= rig.length || e >= links.length) throw r.corrupt(`palette entry ${e} beyond the palette of ${n}`);
      links[e] = intra ? NO_LINK : (this.links[e] ?? NO_LINK);
    }
    const first = r.get(5);
    const compact = first === COMPACT;
    const linked = first === LINKED || compact;
    const orders: (number | null)[] = [null, null, null, null, null, null, null];
    if (!linked) {
      orders[0] = first;
      for (let k = 1; k < 4; k++) orders[k] = r.get(5);
    }
    const signed = (cls: number): bigint => {
      let k = orders[cls];
      if (k === null) k = orders[cls] = r.get(5);
      if (compact && k === ZERO_CLASS) return 0n;
      return r.signed(k);
    };
    const allRigid = compact && r.one() === 1;
    // The compact coding's keyframe prediction of an entry without a reference: the rigid entry
    // decoded before it in the chunk; for the chunk's first, the last rigid entry of the nearest
    // coarser band that has one (as `linked::seed`).
    let last: { rig: bigint[]; t: bigint[] } | null = null;
    if (compact && intra) {
      for (let b = j + 1; b < bands.length && last === null; b++) {
        const carried = bands[b];
        for (let i = carried.length - 1; i >= 0; i--) {
          const e = carried[i], g = rig[e] ?? null;
          if (g === null) continue;
          last = { rig: g, t: [3, 7, 11].map((k) => out[e * ENTRY + k] ?? 0n) };
          break;
        }
      }
    }
    if (linked && intra) {
      let width = 0;
      while (2 ** width < n) width++;
      for (const e of entries) {
        if (r.one() === 0) continue;
        const x = r.get(width);
        if (x >= n || x === e || !readBefore(bands, x, e)) throw r.corrupt(`palette entry ${e}: reference ${x} is not an entry read before it`);
        const pivot = [0n, 0n, 0n];
        for (let k = 0; k < 3; k++) {
          pivot[k] = signed(6);
          if (abs(pivot[k]) > MAX_BIND) throw r.corrupt(`palette entry ${e}: pivot coordinate ${pivot[k]} beyond the limit of ${MAX_BIND}`);
        }
        links[e] = { reference: x, pivot };
      }
    }
    for (const e of entries) {
      const base = e * ENTRY;
      if (p !== null && r.one() === 0) {
        for (let i = base; i < base + ENTRY; i++) out[i] = p[i] ?? 0n;
        rig[e] = this.rig[e] ?? null;
        continue;
      }
      const values: bigint[] = new Array(ENTRY);
      if (allRigid || r.one() === 1) {
        let pr: Predicted, exact = false;
        if (linked) {
          pr = predictLinked(e, links[e], { palette: p, previous: q, rig: this.rig, rigBefore: this.rigBefore, rigAt, predicted }, out, rig);
          exact = r.one() === 1;
        } else pr = { rig: rigAt(e), t: [3, 7, 11].map((i) => predicted(base + i)), linked: false, anchor: null };
        if (compact && intra && last !== null && !pr.linked) pr = { rig: last.rig.slice(), t: last.t.slice(), linked: false, anchor: null };
        const [qc, tc] = pr.linked ? [4, 5] : [0, 2];
        const g = pr.rig.slice();
        if (!exact) for (let i = 0; i < 5; i++) g[i] = wrap(pr.rig[i] + signed(i < 4 ? qc : 1));
        if (g.slice(0, 4).some((v) => abs(v) > MAX_QUATERNION)) throw r.corrupt(`palette entry ${e}: quaternion [${g.slice(0, 4).join(", ")}] beyond the limit of ${MAX_QUATERNION}`);
        if (abs(g[4]) > MAX_SCALE) throw r.corrupt(`palette entry ${e}: scale ${g[4]} beyond the limit of ${MAX_SCALE}`);
        const m = rigMatrix(g);
        if (m === null) throw r.corrupt(`palette entry ${e}: the zero quaternion`);
        const t = predictedTranslation(pr, m).slice();
        if (!exact) for (let a = 0; a < 3; a++) t[a] = wrap(t[a] + signed(tc));
        for (let a = 0; a < 3; a++) {
          for (let k = 0; k < 3; k++) values[4 * a + k] = m[3 * a + k];
          values[4 * a + 3] = t[a];
        }
        rig[e] = g;
        last = { rig: g, t: [values[3], values[7], values[11]] };
      } else {
        for (let i = 0; i < ENTRY; i++) values[i] = wrap(predicted(base + i) + signed(3));
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

  advance(palette: BigInt64Array, intra: boolean, mask: bigint, rig: (Rig | null)[] = [], links: Link[] = []): void {
    this.links = links;
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
