// Position prediction (proto/container.md, "Positions, band j"), as
// `pmcodec_container::predict`: band 0's lower neighbours and stencils in its decoding order,
// the affine motion of a stencil (fitted on the previous frame, or weighted from the
// keyframe). Every operation is the spec's, in its order, so both decoders predict the same
// integers. The per-node prediction itself (predict.rs's `predict`) is inline in decode.ts's
// band loop, where V8 keeps it fast.

import { VertexOrder } from "./format.js";

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


