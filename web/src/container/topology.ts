// Bit-coded Faces and Corners chunks (proto/container.md, "Faces" and "Corners", coding 1), as
// `pmcodec_container::topology` reads them: adaptive Exp-Golomb numbers (the order follows the
// running mean of the numbers coded, as LOCO-I adapts its Golomb parameter), and corner updates
// grouped by transition (corner X of some of the triangles around X becomes Y: the trace, at a
// client's level, of a swap below it; Kircher & Garland 2005, section 4.1).

import { DecodeError } from "./error.js";

/** The coding a coded payload names after its leading 0. */
export const CODING_BITS = 1;
const HALVE_AT = 16;

class Context {
  sum = 1;
  count = 1;
  order(): number {
    let k = 0;
    while (k < 32 && this.count * 2 ** k < this.sum) k++;
    return k;
  }
  update(u: number): void {
    this.sum += u;
    this.count += 1;
    if (this.count >= HALVE_AT) { this.sum = Math.floor(this.sum / 2); this.count = Math.floor(this.count / 2); }
  }
}

class BitReader {
  private bitPos = 0;
  constructor(private b: Uint8Array, private what: string) {}
  bit(): number {
    const byte = this.bitPos >>> 3;
    if (byte >= this.b.length) throw new DecodeError(`${this.what}: bit stream ends early`);
    const v = (this.b[byte] >>> (this.bitPos & 7)) & 1;
    this.bitPos++;
    return v;
  }
  number(ctx: Context): number {
    const k = ctx.order();
    let zeros = 0;
    while (this.bit() === 0) {
      zeros++;
      if (zeros + k > 32) throw new DecodeError(`${this.what}: Exp-Golomb code beyond 32 bits`);
    }
    let v = 1;
    for (let i = 0; i < zeros + k; i++) v = v * 2 + this.bit();
    const u = v - 2 ** k;
    if (u > 0xffffffff) throw new DecodeError(`${this.what}: number beyond 32 bits`);
    ctx.update(u);
    return u;
  }
  finish(): void {
    const used = Math.ceil(this.bitPos / 8);
    if (used !== this.b.length) throw new DecodeError(`${this.what}: ${this.b.length - used} bytes after the bit stream`);
    if (this.bitPos % 8 !== 0 && this.b[used - 1] >>> (this.bitPos % 8) !== 0) throw new DecodeError(`${this.what}: bits set after the bit stream`);
  }
}

const unzigzag = (v: number): number => (v >>> 1) ^ -(v & 1);
const zigzagOf = (u: number): number => unzigzag(u);

/** Where a coded payload's bit stream starts (a leading 0 followed by more bytes), or null for a varint payload. */
export function coded(raw: Uint8Array, what: string): number | null {
  if (raw.length < 2 || raw[0] !== 0) return null;
  // The coding is a varint; any coding but 1 (one byte) is corrupt.
  if (raw[1] !== CODING_BITS) throw new DecodeError(`${what}: topology coding ${raw[1] & 0x7f}${raw[1] & 0x80 ? "+" : ""} (1: bit-coded)`);
  return 2;
}

type Face = { t: number; corners: [number, number, number] };

const RECENT = 16;

/** Moves node c to the front of the recently used nodes (at most RECENT, distinct). */
function touch(recent: number[], c: number): void {
  const p = recent.indexOf(c);
  if (p >= 0) recent.splice(p, 1);
  recent.unshift(c);
  if (recent.length > RECENT) recent.length = RECENT;
}

/** A coded Faces chunk: count, then per face its triangle's gap and three corners, each a recently used node or a difference. */
export function readFacesCoded(raw: Uint8Array, start: number, what: string, size: number, triangles: number): Face[] {
  const r = new BitReader(raw.subarray(start), what);
  const count = new Context(), gap = new Context(), hit = new Context(), corner = [new Context(), new Context(), new Context()];
  const m = r.number(count);
  if (m > triangles || m > (raw.length - start) * 2) throw new DecodeError(`${what}: ${m} faces in ${raw.length - start} bytes for ${triangles} triangles`);
  const faces: Face[] = [];
  const recent: number[] = [];
  let prev: number | null = null;
  let last: [number, number, number] = [0, 0, 0];
  for (let i = 0; i < m; i++) {
    const d = r.number(gap);
    const t: number = prev === null ? d : prev + d + 1;
    if (t >= triangles) throw new DecodeError(`${what}: triangle ${t} out of range (< ${triangles})`);
    prev = t;
    const c: [number, number, number] = [0, 0, 0];
    for (let k = 0; k < 3; k++) {
      const u = r.number(hit);
      if (u === 0) c[k] = (last[k] + zigzagOf(r.number(corner[k]))) >>> 0;
      else if (u - 1 < recent.length) c[k] = recent[u - 1];
      else throw new DecodeError(`${what}: recent node ${u} of ${recent.length}`);
      if (c[k] >= size) throw new DecodeError(`${what}: corner ${c[k]} out of range (< ${size})`);
      touch(recent, c[k]);
    }
    last = c;
    faces.push({ t, corners: c });
  }
  r.finish();
  return faces;
}

const alive = (h: Uint32Array, t: number, size: number): boolean => {
  const x = h[3 * t], y = h[3 * t + 1], z = h[3 * t + 2];
  return x !== y && y !== z && x !== z && x < size && y < size && z < size;
};

/** The level-j mesh the reader holds: per node, its alive triangles (ascending) and neighbours (ascending, distinct). */
function heldMesh(held: Uint32Array, size: number): { tris: (n: number) => Uint32Array; nbs: (n: number) => Uint32Array } {
  const T = held.length / 3;
  const triStart = new Uint32Array(size + 1);
  for (let t = 0; t < T; t++) if (alive(held, t, size)) for (let i = 0; i < 3; i++) triStart[held[3 * t + i] + 1]++;
  for (let i = 0; i < size; i++) triStart[i + 1] += triStart[i];
  const fill = triStart.slice();
  const tris = new Uint32Array(triStart[size]);
  for (let t = 0; t < T; t++) if (alive(held, t, size)) for (let i = 0; i < 3; i++) tris[fill[held[3 * t + i]]++] = t;
  const nbStart = new Uint32Array(size + 1);
  const nbs: number[] = [];
  for (let x = 0; x < size; x++) {
    const row: number[] = [];
    for (let p = triStart[x]; p < triStart[x + 1]; p++) for (let i = 0; i < 3; i++) { const y = held[3 * tris[p] + i]; if (y !== x) row.push(y); }
    row.sort((a, b) => a - b);
    for (let i = 0; i < row.length; i++) if (i === 0 || row[i] !== row[i - 1]) nbs.push(row[i]);
    nbStart[x + 1] = nbs.length;
  }
  const nbArr = Uint32Array.from(nbs);
  return { tris: (n) => tris.subarray(triStart[n], triStart[n + 1]), nbs: (n) => nbArr.subarray(nbStart[n], nbStart[n + 1]) };
}

/** A coded Corners chunk: transitions over the triangles alive before, then the others' new corners. */
export function readCornerUpdatesCoded(raw: Uint8Array, start: number, what: string, size: number, held: Uint32Array): Face[] {
  const r = new BitReader(raw.subarray(start), what);
  const triangles = held.length / 3;
  const bits = (raw.length - start) * 8;
  const count = new Context(), gap = new Context(), to = new Context(), diff = new Context();
  const n = r.number(count);
  if (n * 3 > bits) throw new DecodeError(`${what}: ${n} transitions in ${raw.length - start} bytes`);
  const mesh = heldMesh(held, size);
  const out = new Map<number, [number, number, number]>();
  let lastX = 0;
  for (let e = 0; e < n; e++) {
    const x = lastX + r.number(gap);
    if (x >= size) throw new DecodeError(`${what}: transition from node ${x} out of range (< ${size})`);
    lastX = x;
    const nb = mesh.nbs(x);
    const u = r.number(to);
    const y = u < nb.length ? nb[u] : (x + unzigzag((u - nb.length) >>> 0)) >>> 0;
    if (y >= size || y === x) throw new DecodeError(`${what}: transition from node ${x} to ${y} (< ${size}, another node)`);
    let any = false;
    for (const t of mesh.tris(x)) {
      if (!r.bit()) continue;
      any = true;
      const b: [number, number, number] = [held[3 * t], held[3 * t + 1], held[3 * t + 2]];
      let c = out.get(t);
      if (!c) { c = [b[0], b[1], b[2]]; out.set(t, c); }
      const i = b[0] === x ? 0 : b[1] === x ? 1 : 2;
      if (c[i] !== b[i]) throw new DecodeError(`${what}: triangle ${t}: corner ${i} changed twice`);
      c[i] = y;
    }
    if (!any) throw new DecodeError(`${what}: transition from node ${x} to ${y} carries no triangle`);
  }
  const m = r.number(count);
  if (m > triangles || m * 4 > bits) throw new DecodeError(`${what}: ${m} updates of triangles not alive in ${raw.length - start} bytes`);
  let prev: number | null = null;
  let last: [number, number, number] = [0, 0, 0];
  for (let i = 0; i < m; i++) {
    const d = r.number(gap);
    const t: number = prev === null ? d : prev + d + 1;
    if (t >= triangles) throw new DecodeError(`${what}: triangle ${t} out of range (< ${triangles})`);
    prev = t;
    if (alive(held, t, size)) throw new DecodeError(`${what}: triangle ${t} was alive: its update belongs to a transition`);
    const c: [number, number, number] = [0, 0, 0];
    for (let k = 0; k < 3; k++) {
      c[k] = (last[k] + zigzagOf(r.number(diff))) >>> 0;
      if (c[k] >= size) throw new DecodeError(`${what}: corner ${c[k]} out of range (< ${size})`);
    }
    last = c;
    out.set(t, c);
  }
  r.finish();
  return [...out.entries()].sort((a, b) => a[0] - b[0]).map(([t, corners]) => ({ t, corners }));
}

/** A coded Key chunk: count, then each parent a recently used one or a difference from the node before's. */
export function readKeyCoded(raw: Uint8Array, start: number, what: string, expected: number, limit: number): Uint32Array {
  const r = new BitReader(raw.subarray(start), what);
  const count = new Context(), hit = new Context(), diff = new Context();
  const n = r.number(count);
  if (n !== expected || n > (raw.length - start) * 8) throw new DecodeError(`${what}: ${n} parents for ${expected} nodes in ${raw.length - start} bytes`);
  const parent = new Uint32Array(n);
  const recent: number[] = [];
  let last = 0;
  for (let i = 0; i < n; i++) {
    const u = r.number(hit);
    let p: number;
    if (u === 0) p = (last + zigzagOf(r.number(diff))) >>> 0;
    else if (u - 1 < recent.length) p = recent[u - 1];
    else throw new DecodeError(`${what}: recent parent ${u} of ${recent.length}`);
    if (p >= limit) throw new DecodeError(`${what}: parent ${p} out of range (< ${limit})`);
    touch(recent, p);
    parent[i] = p;
    last = p;
  }
  r.finish();
  return parent;
}

/** A coded Delta chunk: count, then per move the node's gap and its parent's difference from the move before's. */
export function readDeltaCoded(raw: Uint8Array, start: number, what: string, nodes: number, parents: number): [number, number][] {
  const r = new BitReader(raw.subarray(start), what);
  const count = new Context(), gap = new Context(), diff = new Context();
  const n = r.number(count);
  if (n > nodes || n > (raw.length - start) * 4) throw new DecodeError(`${what}: ${n} moves in ${raw.length - start} bytes for ${nodes} nodes`);
  const moves: [number, number][] = [];
  let prev: number | null = null, last = 0;
  for (let i = 0; i < n; i++) {
    const d = r.number(gap);
    const v: number = prev === null ? d : prev + d + 1;
    if (v >= nodes) throw new DecodeError(`${what}: node ${v} out of range (< ${nodes})`);
    prev = v;
    const to = (last + zigzagOf(r.number(diff))) >>> 0;
    if (to >= parents) throw new DecodeError(`${what}: parent ${to} out of range (< ${parents})`);
    last = to;
    moves.push([v, to]);
  }
  r.finish();
  return moves;
}
