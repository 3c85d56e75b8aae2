// Playback of a pmcodec progressive hierarchy down to a finest level L, mirroring
// `pmcodec_hierarchy::progressive::Replay` (see proto/container.md, "The model the file
// encodes"). In Rust it lives in the hierarchy crate; here only the decoder (decode.ts) and the
// viewer's geomorphs use it, so it sits beside the decoder. Everything is flat typed arrays
// indexed by u32 node and triangle ids.

import { DecodeError } from "./error.js";

export const NONE = 0xffffffff;
/** Degeneration node of a triangle that is not alive at this replay's finest level. */
export const BELOW = 0xfffffffe;

export interface Swap { level: number; v: number; to: number }
export interface CornerUpdate { level: number; t: number; corners: [number, number, number] }
/** Swaps and corner updates; degenerate-set changes are derived (proto/container.md). */
export interface FrameDelta { swaps: Swap[]; corners: CornerUpdate[] }
export interface KeyBand { parent: Uint32Array; faces: { t: number; corners: [number, number, number] }[] }

/** A growable set of u32 with O(1) insert/remove by slot, like the Rust side's Vec + slot map. */
class SlotList {
  items: number[] = [];
}

export class Replay {
  readonly levelSizes: number[];
  readonly offsets: number[];
  readonly minLevel: number;
  readonly triangleCount: number;
  parent: Uint32Array[]; // parent[k][v], k < top
  corners: Uint32Array; // 3 per triangle, level-minLevel corners (NONE or a repeated node if not alive)
  /** Per level-minLevel node (local id): the triangles alive there with a corner at it. */
  incident: number[][] = [];
  nodeOf: Uint32Array;
  private marked: Uint8Array;
  private affected: number[] = [];
  sets: SlotList[];
  slotInSet: Uint32Array;
  children: number[][];
  expanded: Uint8Array;
  /**
   * Nodes a partial split revealed (proto/container.md, "Cuts"): a revealed node is drawn for
   * its unrevealed children; a node every child of which is revealed is expanded.
   */
  revealed: Uint8Array;
  shown: number[] = [];
  slotInShown: Uint32Array;

  constructor(levelSizes: number[], minLevel: number, triangleCount: number) {
    if (levelSizes.length === 0 || minLevel >= levelSizes.length) throw new DecodeError(`bad levels ${levelSizes} / ${minLevel}`);
    this.levelSizes = levelSizes;
    this.offsets = [0];
    for (const s of levelSizes) this.offsets.push(this.offsets[this.offsets.length - 1] + s);
    this.minLevel = minLevel;
    this.triangleCount = triangleCount;
    this.parent = levelSizes.slice(0, -1).map((s) => new Uint32Array(s));
    const total = this.nodeCount;
    this.corners = new Uint32Array(triangleCount * 3).fill(NONE);
    this.nodeOf = new Uint32Array(triangleCount).fill(BELOW);
    this.sets = Array.from({ length: total }, () => new SlotList());
    this.slotInSet = new Uint32Array(triangleCount).fill(NONE);
    this.children = Array.from({ length: total }, () => []);
    this.expanded = new Uint8Array(total);
    this.revealed = new Uint8Array(total);
    this.slotInShown = new Uint32Array(triangleCount).fill(NONE);
    this.marked = new Uint8Array(triangleCount);
  }

  get top(): number { return this.levelSizes.length - 1; }
  get nodeCount(): number { return this.offsets[this.offsets.length - 1]; }

  /** Level of a global node id. */
  levelOf(g: number): number {
    let k = 0;
    while (k + 1 < this.offsets.length && this.offsets[k + 1] <= g) k++;
    return k;
  }

  parentGlobal(g: number): number {
    const k = this.levelOf(g);
    if (k >= this.top) return NONE;
    return this.offsets[k + 1] + this.parent[k][g - this.offsets[k]];
  }

  /** Loads a keyframe: parent maps of bands >= L, and corners from band L (or the input triangles for L = 0). */
  loadKeyframe(bands: KeyBand[], inputTriangles?: Uint32Array): void {
    if (bands.length !== this.levelSizes.length) throw new DecodeError(`keyframe has ${bands.length} bands for ${this.levelSizes.length} levels`);
    for (let j = this.minLevel; j < this.top; j++) {
      const p = bands[j].parent;
      if (p.length !== this.levelSizes[j]) throw new DecodeError(`band ${j}: parent map of ${p.length} for ${this.levelSizes[j]} nodes`);
      for (let i = 0; i < p.length; i++) if (p[i] >= this.levelSizes[j + 1]) throw new DecodeError(`band ${j}: parent out of range`);
      this.parent[j] = Uint32Array.from(p);
    }
    this.corners.fill(NONE);
    if (this.minLevel === 0) {
      if (!inputTriangles || inputTriangles.length !== this.triangleCount * 3) throw new DecodeError("level 0 needs the input triangles");
      for (let i = 0; i < inputTriangles.length; i++) if (inputTriangles[i] >= this.levelSizes[0]) throw new DecodeError("input triangle out of range");
      this.corners.set(inputTriangles);
    } else {
      const size = this.levelSizes[this.minLevel];
      for (const f of bands[this.minLevel].faces) {
        if (f.t >= this.triangleCount || f.corners.some((c) => c >= size)) throw new DecodeError(`band ${this.minLevel}: face ${f.t} out of range`);
        this.corners.set(f.corners, f.t * 3);
      }
    }
    this.rebuild();
  }

  private alive(t: number): boolean {
    const x = this.corners[3 * t], y = this.corners[3 * t + 1], z = this.corners[3 * t + 2];
    return x !== NONE && x !== y && y !== z && x !== z;
  }

  /** Where two of t's corners' ancestor chains first meet (NONE: never; BELOW: not alive at minLevel). */
  private degenerationOf(t: number): number {
    if (!this.alive(t)) return BELOW;
    let x = this.corners[3 * t], y = this.corners[3 * t + 1], z = this.corners[3 * t + 2];
    for (let k = this.minLevel; k < this.top; k++) {
      const p = this.parent[k];
      x = p[x]; y = p[y]; z = p[z];
      if (x === y || x === z) return this.offsets[k + 1] + x;
      if (y === z) return this.offsets[k + 1] + y;
    }
    return NONE;
  }

  private rebuild(): void {
    const L = this.minLevel;
    for (let t = 0; t < this.triangleCount; t++) this.nodeOf[t] = this.degenerationOf(t);
    this.incident = Array.from({ length: this.levelSizes[L] }, () => []);
    for (let t = 0; t < this.triangleCount; t++) {
      if (this.alive(t)) for (let i = 0; i < 3; i++) this.incident[this.corners[3 * t + i]].push(t);
    }
    for (const s of this.sets) s.items.length = 0;
    for (let t = 0; t < this.triangleCount; t++) {
      const g = this.nodeOf[t];
      if (g !== NONE && g !== BELOW) { this.slotInSet[t] = this.sets[g].items.length; this.sets[g].items.push(t); }
    }
    for (const c of this.children) c.length = 0;
    for (let k = L; k < this.top; k++) {
      const p = this.parent[k];
      for (let v = 0; v < p.length; v++) this.children[this.offsets[k + 1] + p[v]].push(this.offsets[k] + v);
    }
    this.expanded.fill(0);
    this.revealed.fill(0);
    this.shown.length = 0;
    this.slotInShown.fill(NONE);
    for (let t = 0; t < this.triangleCount; t++) if (this.nodeOf[t] === NONE) this.show(t);
  }

  private show(t: number): void {
    if (this.slotInShown[t] === NONE) { this.slotInShown[t] = this.shown.length; this.shown.push(t); }
  }

  private hide(t: number): void {
    const slot = this.slotInShown[t];
    if (slot === NONE) return;
    const last = this.shown.pop()!;
    if (last !== t) { this.shown[slot] = last; this.slotInShown[last] = slot; }
    this.slotInShown[t] = NONE;
  }

  expandable(g: number): boolean { return g >= this.offsets[this.minLevel + 1]; }

  expand(g: number): void {
    let x = g;
    while (x !== NONE && this.expandable(x) && !this.expanded[x]) {
      this.expanded[x] = 1;
      for (const t of this.sets[x].items) this.show(t);
      x = this.parentGlobal(x);
    }
  }

  collapse(g: number): void {
    const stack = [g];
    while (stack.length) {
      const x = stack.pop()!;
      if (!this.expanded[x]) continue;
      this.expanded[x] = 0;
      for (const t of this.sets[x].items) this.hide(t);
      for (const c of this.children[x]) stack.push(c);
    }
  }

  /** Applies one frame's delta (bands >= minLevel). Throws DecodeError on data that does not fit. */
  apply(delta: FrameDelta): void {
    const froms: number[] = [];
    const moved: number[] = [];
    for (const s of delta.swaps) {
      const k = s.level;
      if (k < this.minLevel) continue;
      if (k >= this.top || s.v >= this.levelSizes[k] || s.to >= this.levelSizes[k + 1]) throw new DecodeError(`swap out of range at level ${k}`);
      const from = this.parent[k][s.v];
      if (from === s.to) continue;
      const gv = this.offsets[k] + s.v, ga = this.offsets[k + 1] + from, gb = this.offsets[k + 1] + s.to;
      this.parent[k][s.v] = s.to;
      const ch = this.children[ga];
      const i = ch.indexOf(gv);
      if (i >= 0) { ch[i] = ch[ch.length - 1]; ch.pop(); }
      this.children[gb].push(gv);
      froms.push(ga);
      moved.push(gv);
      if (this.expanded[gv] && !this.expanded[gb]) this.collapse(gv);
    }
    for (const ga of froms) if (this.children[ga].length === 0) throw new DecodeError(`swaps left cluster ${ga} empty`);
    const L = this.minLevel;
    if (L > 0) {
      const size = this.levelSizes[L];
      for (const c of delta.corners) {
        if (c.level !== L) continue;
        const t = c.t;
        if (t >= this.triangleCount || c.corners.some((x) => x >= size)) throw new DecodeError(`corner update out of range: ${t}`);
        if (this.alive(t)) {
          for (let i = 0; i < 3; i++) {
            const list = this.incident[this.corners[3 * t + i]];
            const at = list.indexOf(t);
            if (at >= 0) { list[at] = list[list.length - 1]; list.pop(); }
          }
        }
        this.corners.set(c.corners, 3 * t);
        if (this.alive(t)) for (let i = 0; i < 3; i++) this.incident[c.corners[i]].push(t);
        this.mark(t);
      }
    }
    // Triangles with a level-L corner under a moved node: their ancestor chains changed.
    const levelBase = this.offsets[L], below = this.offsets[L + 1];
    const stack: number[] = [];
    for (const gv of moved) {
      stack.push(gv);
      while (stack.length) {
        const x = stack.pop()!;
        if (x < below) { for (const t of this.incident[x - levelBase]) this.mark(t); }
        else for (const c of this.children[x]) stack.push(c);
      }
    }
    for (const t of this.affected) {
      this.marked[t] = 0;
      this.setDegeneration(t, this.degenerationOf(t));
    }
    this.affected.length = 0;
  }

  private mark(t: number): void {
    if (!this.marked[t]) { this.marked[t] = 1; this.affected.push(t); }
  }

  /** Moves t into D_g (g may be NONE or BELOW) and shows or hides it. */
  private setDegeneration(t: number, g: number): void {
    const old = this.nodeOf[t];
    if (old === g) return;
    if (old !== NONE && old !== BELOW) {
      const items = this.sets[old].items;
      const slot = this.slotInSet[t];
      const last = items.pop()!;
      if (last !== t && slot < items.length) { items[slot] = last; this.slotInSet[last] = slot; }
    }
    if (g !== NONE && g !== BELOW) { this.slotInSet[t] = this.sets[g].items.length; this.sets[g].items.push(t); }
    else this.slotInSet[t] = NONE;
    this.nodeOf[t] = g;
    if (g === NONE || (g !== BELOW && this.expanded[g])) this.show(t); else this.hide(t);
  }

  /**
   * For every node at minLevel and above, the cut node standing for it (NONE if expanded): its
   * deepest ancestor (itself included) that is a top-level node, a child of an expanded node or
   * revealed by a partial split.
   */
  cutNodes(): Uint32Array {
    const rep = new Uint32Array(this.nodeCount).fill(NONE);
    for (let k = this.top; k >= this.minLevel; k--) {
      for (let v = 0; v < this.levelSizes[k]; v++) {
        const g = this.offsets[k] + v;
        const p = k === this.top ? NONE : this.offsets[k + 1] + this.parent[k][v];
        const shownHere = p === NONE || this.expanded[p] || this.revealed[g];
        rep[g] = !shownHere ? rep[p] : this.expanded[g] ? NONE : g;
      }
    }
    return rep;
  }

  /**
   * Split priorities (proto/container.md, "Cuts"): plane quadrics of the triangles alive at
   * minLevel (a third of each one's area to each corner), summed over clusters; a node's own
   * error is sqrt(Q(x) / area) at its position, its priority the largest own error in its
   * subtree. Every operation in the Rust decoder's order, in doubles, so both pick the same cut.
   */
  nodeErrors(positions: Float32Array): Float64Array {
    const nodes = this.nodeCount, err = new Float64Array(nodes), q = this.clusterQuadrics(positions);
    for (let g = this.offsets[this.minLevel + 1] ?? nodes; g < nodes; g++) {
      const e = quadricAt(q, g, positions, g);
      err[g] = q[11 * g + 10] > 0 && e > 0 ? Math.sqrt(e / q[11 * g + 10]) : 0;
    }
    this.subtreeMax(err);
    return err;
  }

  /**
   * Budget priorities (proto/container.md, "Cuts"), what `selectTriangles` is given for the
   * spec's whole splits: a node's own benefit is sqrt(Q(x) / sqrt(area)), its RMS error scaled
   * by the fourth root of its cluster's area (a wide cluster outranks a tiny one as far off),
   * its priority the largest in its subtree. Every operation in the Rust decoder's order.
   */
  splitBenefits(positions: Float32Array): Float64Array {
    const nodes = this.nodeCount, out = new Float64Array(nodes), q = this.clusterQuadrics(positions);
    for (let g = this.offsets[this.minLevel + 1] ?? nodes; g < nodes; g++) {
      const e = quadricAt(q, g, positions, g), area = q[11 * g + 10];
      out[g] = area > 0 && e > 0 ? Math.sqrt(e / Math.sqrt(area)) : 0;
    }
    this.subtreeMax(out);
    return out;
  }

  /**
   * Reveal priorities (proto/container.md, "Partial splits"), what `selectTriangles` is given
   * with `partial`: revealing
   * child c of node P is worth dQ = Q_c(x_P) - Q_c(x_c) with c's cluster quadric (Garland &
   * Heckbert's cost of collapsing c into P), as sqrt(dQ / sqrt(area)); a node's priority is the
   * largest in its subtree. Every operation in the Rust decoder's order.
   */
  revealBenefits(positions: Float32Array): Float64Array {
    const out = new Float64Array(this.nodeCount), q = this.clusterQuadrics(positions);
    for (let k = this.minLevel; k < this.top; k++) {
      const p = this.parent[k];
      for (let v = 0; v < p.length; v++) {
        const c = this.offsets[k] + v, a = this.offsets[k + 1] + p[v], area = q[11 * c + 10];
        const dq = quadricAt(q, c, positions, a) - quadricAt(q, c, positions, c);
        out[c] = area > 0 && dq > 0 ? Math.sqrt(dq / Math.sqrt(area)) : 0;
      }
    }
    this.subtreeMax(out);
    return out;
  }

  /** Plane quadrics of the level-L faces summed over clusters, 11 numbers per node. */
  private clusterQuadrics(positions: Float32Array): Float64Array {
    const nodes = this.nodeCount;
    // 11 per node: a00 a01 a02 a11 a12 a22 b0 b1 b2 c, area.
    const q = new Float64Array(11 * nodes);
    const base = this.offsets[this.minLevel], size = this.levelSizes[this.minLevel], cs = this.corners;
    const plane = new Float64Array(11);
    for (let t = 0; t < this.triangleCount; t++) {
      const c0 = cs[3 * t], c1 = cs[3 * t + 1], c2 = cs[3 * t + 2];
      if (c0 === c1 || c1 === c2 || c0 === c2 || c0 >= size || c1 >= size || c2 >= size) continue;
      const i0 = 3 * (base + c0), i1 = 3 * (base + c1), i2 = 3 * (base + c2);
      const p0x = positions[i0], p0y = positions[i0 + 1], p0z = positions[i0 + 2];
      const e1x = positions[i1] - p0x, e1y = positions[i1 + 1] - p0y, e1z = positions[i1 + 2] - p0z;
      const e2x = positions[i2] - p0x, e2y = positions[i2 + 1] - p0y, e2z = positions[i2 + 2] - p0z;
      const nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
      const len = Math.sqrt(nx * nx + ny * ny + nz * nz);
      if (!(len > 0 && len < Infinity)) continue;
      const ux = nx / len, uy = ny / len, uz = nz / len;
      const d = -(ux * p0x + uy * p0y + uz * p0z);
      const w = len / 6;
      plane[0] = w * (ux * ux); plane[1] = w * (ux * uy); plane[2] = w * (ux * uz);
      plane[3] = w * (uy * uy); plane[4] = w * (uy * uz); plane[5] = w * (uz * uz);
      plane[6] = w * (d * ux); plane[7] = w * (d * uy); plane[8] = w * (d * uz);
      plane[9] = w * (d * d); plane[10] = w;
      for (const c of [c0, c1, c2]) {
        const o = 11 * (base + c);
        for (let i = 0; i < 11; i++) q[o + i] += plane[i];
      }
    }
    for (let k = this.minLevel; k < this.top; k++) {
      const p = this.parent[k];
      for (let v = 0; v < p.length; v++) {
        const c = 11 * (this.offsets[k] + v), a = 11 * (this.offsets[k + 1] + p[v]);
        for (let i = 0; i < 11; i++) q[a + i] += q[c + i];
      }
    }
    return q;
  }

  /** Each node's value raised to the largest in its subtree, finest level first. */
  private subtreeMax(values: Float64Array): void {
    for (let k = this.minLevel; k < this.top; k++) {
      const p = this.parent[k];
      for (let v = 0; v < p.length; v++) {
        const c = this.offsets[k] + v, a = this.offsets[k + 1] + p[v];
        if (values[c] > values[a]) values[a] = values[c];
      }
    }
  }

  /**
   * Triangles in the order the last `selectTriangles` made them appear: those shown at the
   * coarsest cut (ascending), then each split's degenerate set (ascending). Meshes listed in
   * this order are the Rust decoder's (proto/container.md, "Cuts").
   */
  appearing: number[] = [];

  /**
   * Replaces the cut by the longest prefix of the frame's split order that shows at most
   * `budget` triangles: by default whole splits greedy by `benefits` (budget priorities,
   * `splitBenefits`: the spec's cut, proto/container.md "Cuts"); with `partial`, partial splits
   * greedy by reveal priorities (an option, "Partial splits"): reveals
   * are taken until the first one that does not fit. A reveal of child c of P also reveals P's
   * last unrevealed child when only that one would be left; the triangles of D_P that then have
   * at most one corner under an unrevealed child of P appear. With `partial` "levels", whole
   * splits level-major (an option, Rust's `BudgetCut::LevelSplits`): every splittable node of a
   * level before any of the finer level, so a budget at a level's count gets that level.
   */
  selectTriangles(budget: number, benefits: Float64Array, partial: boolean | "levels" = false): void {
    if (partial !== true) { this.selectWhole(budget, benefits, partial === "levels"); return; }
    this.expanded.fill(0);
    this.revealed.fill(0);
    for (const t of [...this.shown]) if (this.nodeOf[t] !== NONE) this.hide(t);
    this.appearing = [...this.shown].sort((a, b) => a - b);
    let used = this.shown.length;
    const heap = new MaxHeap();
    for (let g = this.offsets[this.top]; g < this.offsets[this.top + 1]; g++) {
      if (this.expandable(g)) for (const c of this.children[g]) heap.push(benefits[c], c);
    }
    const fresh: number[] = [];
    while (heap.size > 0) {
      const c = heap.pop();
      if (this.revealed[c]) continue;
      const p = this.parentGlobal(c);
      let last = NONE, left = 0;
      for (const x of this.children[p]) if (x !== c && !this.revealed[x]) { left++; last = x; }
      this.revealed[c] = 1;
      if (left === 1) this.revealed[last] = 1;
      fresh.length = 0;
      for (const t of this.sets[p].items) if (!this.isShown(t) && this.hiddenCorners(t, p) <= 1) fresh.push(t);
      if (used + fresh.length > budget) {
        this.revealed[c] = 0;
        if (left === 1) this.revealed[last] = 0;
        break;
      }
      fresh.sort((a, b) => a - b);
      for (const t of fresh) { this.show(t); this.appearing.push(t); }
      used += fresh.length;
      if (left <= 1) this.expanded[p] = 1;
      for (const x of left === 1 ? [c, last] : [c]) {
        if (this.expandable(x)) for (const y of this.children[x]) heap.push(benefits[y], y);
      }
    }
  }

  /**
   * The longest prefix of the frame's order of whole splits (greedy by `priorities`) that shows
   * at most `budget` triangles: splits are taken until the first one that does not fit.
   * `levelMajor` holds the finer level's candidates back until the coarser level is exhausted.
   */
  private selectWhole(budget: number, priorities: Float64Array, levelMajor = false): void {
    this.revealed.fill(0);
    for (let g = 0; g < this.nodeCount; g++) if (this.expanded[g]) this.collapse(g);
    for (const t of [...this.shown]) if (this.nodeOf[t] !== NONE) this.hide(t);
    this.appearing = [...this.shown].sort((a, b) => a - b);
    let used = this.shown.length;
    const heap = new MaxHeap();
    for (let g = this.offsets[this.top]; g < this.offsets[this.top + 1]; g++) if (this.expandable(g)) heap.push(priorities[g], g);
    let pending: number[] = [];
    for (;;) {
      if (heap.size === 0) {
        for (const c of pending) heap.push(priorities[c], c);
        pending = [];
      }
      if (heap.size === 0) break;
      const g = heap.pop();
      const set = this.sets[g].items;
      if (used + set.length > budget) break;
      this.expand(g);
      used += set.length;
      for (const t of [...set].sort((a, b) => a - b)) this.appearing.push(t);
      for (const c of this.children[g]) {
        if (!this.expandable(c)) continue;
        if (levelMajor) pending.push(c); else heap.push(priorities[c], c);
      }
    }
  }

  /** Whether triangle t is shown. */
  isShown(t: number): boolean { return this.slotInShown[t] !== NONE; }

  /** Corners of triangle t under a child of p that is not revealed (at most 3). */
  private hiddenCorners(t: number, p: number): number {
    let hidden = 0;
    for (let i = 0; i < 3; i++) {
      let k = this.minLevel, v = this.corners[3 * t + i];
      // Up to the child of p on the corner's chain (none when p is not its ancestor).
      while (k < this.top) {
        const up = this.offsets[k + 1] + this.parent[k][v];
        if (up === p) { if (!this.revealed[this.offsets[k] + v]) hidden++; break; }
        v = this.parent[k][v]; k++;
      }
    }
    return hidden;
  }
}

/** x^T A x + 2 b.x + c of node g's quadric at node at's position, in the Rust decoder's operation order. */
function quadricAt(q: Float64Array, g: number, positions: Float32Array, at: number): number {
  const m = 11 * g, x = positions[3 * at], y = positions[3 * at + 1], z = positions[3 * at + 2];
  const ax = q[m] * x + q[m + 1] * y + q[m + 2] * z;
  const ay = q[m + 1] * x + q[m + 3] * y + q[m + 4] * z;
  const az = q[m + 2] * x + q[m + 4] * y + q[m + 5] * z;
  return x * ax + y * ay + z * az + 2 * (q[m + 6] * x + q[m + 7] * y + q[m + 8] * z) + q[m + 9];
}

/** A binary max-heap of (key, id), ties broken by the smaller id (matching the Rust side). */
export class MaxHeap {
  private keys: number[] = [];
  private ids: number[] = [];
  get size(): number { return this.keys.length; }
  private better(i: number, j: number): boolean {
    return this.keys[i] > this.keys[j] || (this.keys[i] === this.keys[j] && this.ids[i] < this.ids[j]);
  }
  private swap(i: number, j: number): void {
    [this.keys[i], this.keys[j]] = [this.keys[j], this.keys[i]];
    [this.ids[i], this.ids[j]] = [this.ids[j], this.ids[i]];
  }
  push(key: number, id: number): void {
    this.keys.push(key); this.ids.push(id);
    let i = this.keys.length - 1;
    while (i > 0) { const p = (i - 1) >> 1; if (!this.better(i, p)) break; this.swap(i, p); i = p; }
  }
  pop(): number {
    const id = this.ids[0];
    const lastK = this.keys.pop()!, lastI = this.ids.pop()!;
    if (this.keys.length > 0) {
      this.keys[0] = lastK; this.ids[0] = lastI;
      let i = 0;
      for (;;) {
        const l = 2 * i + 1, r = l + 1;
        let b = i;
        if (l < this.keys.length && this.better(l, b)) b = l;
        if (r < this.keys.length && this.better(r, b)) b = r;
        if (b === i) break;
        this.swap(i, b); i = b;
      }
    }
    return id;
  }
}
