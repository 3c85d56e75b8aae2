// Playing a file, as `pmcodec_container::Decoder`: keyframes and frame deltas replayed down to
// a finest level (Replay), node positions predicted and corrected band by band, and the cut a
// triangle budget selects, ordered as the Rust decoder orders it.

import { DecodeError } from "./error.js";
import { ChunkKind, Motion } from "./format.js";
import { readCornerUpdates, readDelta, readFaces, readKey, readPositions, readTriangles } from "./payload.js";
import { LowerNeighbours, affineMotion, keyedMotion, lowerNeighbours, stencilWeights } from "./predict.js";
import type { Reader } from "./read.js";
import { FrameDelta, KeyBand, Replay } from "./replay.js";

/** Plays a container down to a finest level: hierarchy (Replay) and quantized node positions. */
export class Decoder {
  replay: Replay;
  frame = -1;
  current: Int32Array;
  previous: Int32Array;
  private triangles: Uint32Array | null = null;
  /** Level-0 lower neighbours (proto/container.md, "Positions, band j"). */
  private lower: LowerNeighbours | null = null;
  /** Band 0's stencil weights from the last keyframe (keyframe affine motion). */
  private weights: Float64Array | null = null;

  constructor(readonly reader: Reader, readonly minLevel: number) {
    const h = reader.header;
    if (minLevel >= h.levelSizes.length) throw new DecodeError(`level ${minLevel}: the file has ${h.levelSizes.length} levels`);
    this.replay = new Replay(h.levelSizes, minLevel, h.triangleCount);
    const total = h.levelSizes.reduce((a, b) => a + b, 0);
    this.current = new Int32Array(total * 3);
    this.previous = new Int32Array(total * 3);
  }

  async seek(f: number): Promise<void> {
    const h = this.reader.header;
    if (f < 0 || f >= h.frameCount) throw new DecodeError(`frame ${f} is beyond the ${h.frameCount} frames`);
    const key = this.reader.keyframeBefore(f);
    let start: number;
    if (this.frame >= key && this.frame <= f) start = this.frame;
    else { await this.loadKeyframe(key); start = key; }
    for (let g = start + 1; g <= f; g++) await this.step(g);
  }

  private async loadKeyframe(k: number): Promise<void> {
    const c = this.reader, h = c.header;
    const bands: KeyBand[] = h.levelSizes.map(() => ({ parent: new Uint32Array(0), faces: [] }));
    for (let j = h.levelSizes.length - 1; j >= this.minLevel; j--) {
      bands[j].parent = readKey(await c.chunk(c.find(ChunkKind.Key, k, j)), `frame ${k} band ${j} keyframe`, h.levelSizes, j);
    }
    const L = this.minLevel;
    if (L > 0) bands[L].faces = readFaces(await c.chunk(c.find(ChunkKind.Faces, k, L)), `frame ${k} band ${L} faces`, h.levelSizes[L], h.triangleCount, c.version);
    if (this.minLevel === 0 && !this.triangles) {
      const raw = await c.chunk(c.find(ChunkKind.Triangles, 0, 0));
      this.triangles = readTriangles(raw, "triangles chunk", h.triangleCount, h.vertexCount);
      this.lower = lowerNeighbours(h.vertexCount, this.triangles, h.order);
    }
    this.replay.loadKeyframe(bands, this.triangles ?? undefined);
    await this.decodePositions(k, true);
    if (h.motion === Motion.KeyframeAffine && this.lower) this.weights = stencilWeights(this.lower, this.current, h.vertexCount);
    this.frame = k;
  }

  private async step(f: number): Promise<void> {
    const c = this.reader, h = c.header;
    const delta: FrameDelta = { swaps: [], corners: [] };
    for (let j = h.levelSizes.length - 1; j >= this.minLevel; j--) {
      readDelta(await c.chunk(c.find(ChunkKind.Delta, f, j)), `frame ${f} band ${j} delta`, h.levelSizes, j, delta);
    }
    const L = this.minLevel;
    if (L > 0) {
      const raw = await c.chunk(c.find(ChunkKind.Corners, f, L)), what = `frame ${f} band ${L} corners`;
      const updates = c.version >= 5
        ? readCornerUpdates(raw, what, h.levelSizes[L], this.replay.corners)
        : readFaces(raw, what, h.levelSizes[L], h.triangleCount, c.version);
      for (const u of updates) delta.corners.push({ level: L, t: u.t, corners: u.corners });
    }
    this.replay.apply(delta);
    [this.previous, this.current] = [this.current, this.previous];
    await this.decodePositions(f, false);
    this.frame = f;
  }

  /**
   * Positions of bands top..minLevel (proto/container.md, "Positions, band j"): each node's
   * prediction plus its residual. The prediction is inline rather than a function as in
   * predict.rs: V8 does not inline a call this size, and with a call per node decoding measured
   * up to 10% slower (CPU time, horse, node bench).
   */
  private async decodePositions(f: number, fromKey: boolean): Promise<void> {
    const h = this.reader.header, r = this.replay;
    const intra = fromKey || this.reader.isKeyframe(f);
    const cur = this.current, prev = this.previous;
    const top = h.levelSizes.length - 1;
    for (let j = top; j >= this.minLevel; j--) {
      const what = `frame ${f} band ${j} positions`;
      const { shift, res } = readPositions(await this.reader.chunk(this.reader.find(ChunkKind.Positions, f, j)), what, h.levelSizes[j]);
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
    const h = this.reader.header;
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
