// Playing a file, as `pmcodec_container::Decoder`: keyframes and frame deltas replayed down to
// a finest level (Replay), node positions predicted and corrected band by band, and the cut a
// triangle budget selects, ordered as the Rust decoder orders it.

import { Charts, Materials, Table, TexturedMesh, needsAbove, readBand0Table, readCharts, readMaterials, readTable, texturedMesh } from "./appearance.js";
import { DecodeError } from "./error.js";
import { ChunkKind, Motion, channels } from "./format.js";
import { readCornerUpdates, readDelta, readFaces, readKey, readPositions, readTriangles } from "./payload.js";
import { LowerNeighbours, affineMotion, keyedMotion, lowerNeighbours, stencilWeights } from "./predict.js";
import type { Reader } from "./read.js";
import { FrameDelta, KeyBand, Replay } from "./replay.js";
import { Link, NO_LINK, Rig, SkinState, bandEntries, hasPaletteChunk, nodeSkins, readBinds } from "./skin.js";

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
  /** The appearance chunks (version 6), read by `loadAppearance`. */
  looks: { charts: Charts; tables: (Table | null)[]; materials: Materials } | null = null;
  /** The skin of a skinned file, once its bind chunks are read. */
  private skin: SkinState | null = null;

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
      bands[j].parent = readKey(await c.chunk(c.find(ChunkKind.Key, k, j)), `frame ${k} band ${j} keyframe`, h.levelSizes, j, c.version);
    }
    const L = this.minLevel;
    if (L > 0) bands[L].faces = readFaces(await c.chunk(c.find(ChunkKind.Faces, k, L)), `frame ${k} band ${L} faces`, h.levelSizes[L], h.triangleCount, c.version);
    if (this.minLevel === 0 && !this.triangles) {
      const raw = await c.chunk(c.find(ChunkKind.Triangles, 0, 0));
      this.triangles = readTriangles(raw, "triangles chunk", h.triangleCount, h.vertexCount, c.version);
      this.lower = lowerNeighbours(h.vertexCount, this.triangles, h.order);
    }
    if (h.skin && !this.skin) {
      const nodes = nodeSkins(h.levelSizes.reduce((a, b) => a + b, 0));
      let offset = 0;
      for (let j = 0; j < h.levelSizes.length; j++) {
        if (j >= this.minLevel) readBinds(await c.chunk(c.find(ChunkKind.Bind, 0, j)), `band ${j} bind`, h.levelSizes[j], h.skin.paletteLen, nodes, offset);
        offset += h.levelSizes[j];
      }
      this.skin = new SkinState(nodes);
      // Files written since the Palette chunk have no Pose chunks; since the Joints chunk,
      // Joints chunks where they had Palette chunks.
      this.skin.joints = c.index.some((e) => e.kind === ChunkKind.Joints);
      if (!c.index.some((e) => e.kind === ChunkKind.Pose)) this.skin.bands = bandEntries(nodes, h.levelSizes, this.minLevel, h.skin.paletteLen);
    }
    const pose = await this.readPose(k, true);
    this.replay.loadKeyframe(bands, this.triangles ?? undefined);
    if (pose) this.skin!.advance(pose.palette, true, pose.mask, pose.rig, pose.links);
    await this.decodePositions(k, true);
    if (h.motion === Motion.KeyframeAffine && this.lower) this.weights = stencilWeights(this.lower, this.current, h.vertexCount);
    this.frame = k;
  }

  private async step(f: number): Promise<void> {
    const c = this.reader, h = c.header;
    const delta: FrameDelta = { swaps: [], corners: [] };
    for (let j = h.levelSizes.length - 1; j >= this.minLevel; j--) {
      readDelta(await c.chunkAt(ChunkKind.Delta, f, j), `frame ${f} band ${j} delta`, h.levelSizes, j, delta);
    }
    const pose = await this.readPose(f, false);
    const L = this.minLevel;
    if (L > 0) {
      const raw = await c.chunkAt(ChunkKind.Corners, f, L), what = `frame ${f} band ${L} corners`;
      const updates = c.version >= 5
        ? readCornerUpdates(raw, what, h.levelSizes[L], this.replay.corners)
        : readFaces(raw, what, h.levelSizes[L], h.triangleCount, c.version);
      for (const u of updates) delta.corners.push({ level: L, t: u.t, corners: u.corners });
    }
    this.replay.apply(delta);
    if (pose) this.skin!.advance(pose.palette, false, pose.mask, pose.rig, pose.links);
    [this.previous, this.current] = [this.current, this.previous];
    await this.decodePositions(f, false);
    this.frame = f;
  }

  /** Frame `f`'s pose (skinned files), read and checked but not yet applied. */
  private async readPose(f: number, intra: boolean): Promise<{ palette: BigInt64Array; mask: bigint; rig: (Rig | null)[]; links: Link[] } | null> {
    const c = this.reader, h = c.header;
    if (!h.skin || !this.skin) return null;
    const bands = this.skin.bands, levels = h.levelSizes.length;
    if (bands !== null) {
      // Entries of bands this decoder does not read stay 0: none of its nodes uses them.
      const palette = new BigInt64Array(h.skin.paletteLen * 12);
      const joints = this.skin.joints;
      const rig: (Rig | null)[] = joints ? new Array(h.skin.paletteLen).fill(null) : [];
      const links: Link[] = joints ? new Array(h.skin.paletteLen).fill(NO_LINK) : [];
      let mask: bigint | null = null;
      for (let j = levels - 1; j >= this.minLevel; j--) {
        if (!hasPaletteChunk(bands, j)) continue;
        const what = `frame ${f} band ${j} ${joints ? "joints" : "palette"}`;
        const raw = await c.chunk(c.find(joints ? ChunkKind.Joints : ChunkKind.Palette, f, j));
        const m = joints ? this.skin.readJoints(raw, what, bands, j, levels, intra, palette, rig, links) : this.skin.readPalette(raw, what, bands[j], levels, intra, palette);
        if (mask !== null && m !== mask) throw new DecodeError(`${what}: band mask 0x${m.toString(16)} where the band above says otherwise`);
        mask = m;
      }
      return { palette, mask: mask ?? 0n, rig, links };
    }
    return { ...this.skin.readPose(await c.chunk(c.find(ChunkKind.Pose, f, 0)), `frame ${f} pose`, h.skin.paletteLen, h.levelSizes.length, intra), rig: [], links: [] };
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
      const skin = this.skin !== null && this.skin.uses(j) ? this.skin : null;
      const skinned = new Int32Array(3), scratch = new Int32Array(3);
      let before = -1;
      for (let k = 0; k < h.levelSizes[j]; k++) {
        const v = sequence ? sequence[k] : k;
        const g = r.offsets[j] + v;
        const local = j < top ? r.parent[j][v] : -1;
        const parent = j < top ? r.offsets[j + 1] + local : -1;
        const lo = lower ? lower.offsets[v] : 0, hi = lower ? lower.offsets[v + 1] : 0;
        const sib = !intra && local >= 0 && hi === lo ? sibCount[local] : 0;
        // Band 0 on inter frames: the affine motion of the vertex's stencil, when it fits.
        if (skin) skin.predict(g, intra, prev, skinned, scratch);
        const affine = hi > lo && !skin && ((affineBand && affineMotion(lower!, v, cur, prev, fit)) || (keyedBand && keyedMotion(lower!, this.weights!, v, cur, prev, fit)));
        for (let a = 0; a < 3; a++) {
          let pred: number;
          if (skin) {
            pred = skinned[a];
          } else if (affine) {
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

  /** Reads the Charts, Materials and this decoder's Attributes chunks once (version 6). */
  async loadAppearance(): Promise<void> {
    const c = this.reader, h = c.header, a = h.appearance;
    if (this.looks || !a) return;
    const charts = readCharts(await c.chunk(c.find(ChunkKind.Charts, 0, 0)), a, h.triangleCount);
    const materials = readMaterials(await c.chunk(c.find(ChunkKind.Materials, 0, 0)), a);
    const tables: (Table | null)[] = h.levelSizes.map(() => null);
    // Without channels there is nothing to look up: no Attributes chunks in files since
    // 2026-11-26, and older files' value-less tables are not read.
    const lowest = channels(a) === 0 ? h.levelSizes.length : this.minLevel;
    for (let j = h.levelSizes.length - 1; j >= lowest; j--) {
      const raw = await c.chunk(c.find(ChunkKind.Attributes, 0, j)), what = `band ${j} attributes`;
      if (needsAbove(raw)) {
        // Bands go top down: the band above is read; frame 0's parents from its Key chunk.
        const parent = readKey(await c.chunk(c.find(ChunkKind.Key, 0, j)), `frame 0 band ${j} keyframe`, h.levelSizes, j, c.version);
        const table = tables[j + 1];
        tables[j] = readTable(raw, what, h.levelSizes[j], a, h.triangleCount, table ? { parent, table } : null);
        continue;
      }
      if (j > 0) { tables[j] = readTable(raw, what, h.levelSizes[j], a, h.triangleCount); continue; }
      // Band 0's entries may be derived from the triangles (a level-0 client's own).
      const triangles = this.triangles ?? readTriangles(await c.chunk(c.find(ChunkKind.Triangles, 0, 0)), "triangles chunk", h.triangleCount, h.vertexCount, c.version);
      tables[j] = readBand0Table(raw, what, h.levelSizes[j], a, triangles, charts.triangleChart);
    }
    this.looks = { charts, tables, materials };
  }

  /** The images' encoded bytes with their MIME types, in order (version 6). */
  async images(): Promise<{ name: string | null; mimeType: string; bytes: Uint8Array }[]> {
    await this.loadAppearance();
    const out = [];
    for (const [i, d] of (this.looks?.materials.images ?? []).entries()) {
      const bytes = await this.reader.chunk(this.reader.find(ChunkKind.Image, 0, i));
      if (bytes.length !== d.byteLength) throw new DecodeError(`image ${i} chunk: ${bytes.length} bytes where the materials chunk says ${d.byteLength}`);
      out.push({ name: d.name, mimeType: d.mimeType, bytes });
    }
    return out;
  }

  /**
   * The cut the last selection chose with its appearance (after `loadAppearance`), triangles
   * in `orderedMesh`'s order: one vertex per (cut node, chart, group), texture coordinates and
   * colours from the tables, normals from `positions` (proto/container.md, "Drawing a cut's
   * appearance").
   */
  texturedMesh(positions: Float32Array): TexturedMesh {
    const a = this.reader.header.appearance, looks = this.looks;
    if (!a || !looks) throw new DecodeError("the file has no appearance, or it is not loaded");
    const r = this.replay, rep = r.cutNodes(), base = r.offsets[r.minLevel];
    const shown = Uint32Array.from(r.appearing), cut = new Uint32Array(3 * shown.length);
    shown.forEach((t, i) => { for (let c = 0; c < 3; c++) cut[3 * i + c] = rep[base + r.corners[3 * t + c]]; });
    return texturedMesh(a, looks.charts, looks.tables, r.offsets, positions, shown, cut);
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
