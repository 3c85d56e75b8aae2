// Playing a file, as `pmcodec_container::Decoder`: keyframes and frame deltas replayed down to
// a finest level (Replay), node positions predicted and corrected band by band, and the cut a
// triangle budget selects, ordered as the Rust decoder orders it.

import { Charts, Materials, Table, TexturedMesh, bandFaces, chartsNeedTriangles, needsAbove, needsBind, needsFaces, readBand0Table, readCharts, readMaterials, readTable, texturedMesh } from "./appearance.js";
import { Below, isDerived } from "./derive.js";
import { DecodeError } from "./error.js";
import { ChunkKind, Motion, channels } from "./format.js";
import { keyFromFirst, readCornerUpdates, readDelta, readFaces, readKey, readPositions, readTriangles } from "./payload.js";
import { LowerNeighbours, affineMotion, keyedMotion, lowerNeighbours, stencilWeights } from "./predict.js";
import type { Reader } from "./read.js";
import { FrameDelta, KeyBand, Replay } from "./replay.js";
import { Link, NO_LINK, Rig, SkinState, bandEntries, hasPaletteChunk, nodeSkins, readBinds } from "./skin.js";

export interface DecoderOptions {
  /**
   * Skinned files: keep each node's offset from its skinned position, `o_f = pos_f - s(v, M_f)`,
   * instead of its position, so frames whose bands are all predicted by skinning decode without
   * any linear blend skinning on the CPU (a GPU skins the bind positions; see `skinAttributes`,
   * `paletteMatrices`, `offsets`). Default false: `current` holds positions, bit for bit as the
   * Rust decoder's.
   */
  skinOffsets?: boolean;
}

/** Per node (global id): bind position in bind quanta, up to four palette entries and weights (0: unused). */
export interface SkinAttributes { bind: Float32Array; joints: Uint16Array; weights: Float32Array }

/** Which positions a partial-split cut's reveal priorities come from (`Decoder.revealBenefits`). */
export type RevealFrom = "frame" | "keyframe" | "banded1" | "banded2";

/**
 * The key a banded partial-split cut ranks reveals by (proto/container.md, "Partial splits"):
 * the band of the frame's priority `current` in `perOctave` steps per factor 2, read off the
 * double's exponent and mantissa (exact, as Rust's `banded_priority`), plus the keyframe's
 * priority `held` squashed into [0, 1).
 */
export function bandedPriority(current: number, held: number, perOctave: number): number {
  const k = Math.max(1, perOctave);
  let band: number;
  if (current > 0 && Number.isFinite(current)) {
    const view = new DataView(new ArrayBuffer(8));
    view.setFloat64(0, current);
    const hi = view.getUint32(0), e = (hi >>> 20) & 0x7ff;
    if (e === 0) band = -2100 * k;
    else {
      view.setUint32(0, (hi & 0xfffff) | (1023 << 20));
      band = (e - 1023) * k + Math.floor((view.getFloat64(0) - 1) * k);
    }
  } else band = -2200 * k;
  const h = held >= 0 && Number.isFinite(held) ? held : 0;
  return band + h / (1 + h);
}

/** Plays a container down to a finest level: hierarchy (Replay) and quantized node positions. */
export class Decoder {
  replay: Replay;
  frame = -1;
  current: Int32Array;
  previous: Int32Array;
  private triangles: Uint32Array | null = null;
  /** The input triangles, read above level 0 for deriving faces (derive.ts). */
  private fine: Uint32Array | null = null;
  /** The levels below minLevel while the keyframe interval derives band minLevel's faces. */
  private below: Below | null = null;
  /** Level-0 lower neighbours (proto/container.md, "Positions, band j"). */
  private lower: LowerNeighbours | null = null;
  /** Band 0's stencil weights from the last keyframe (keyframe affine motion). */
  private weights: Float64Array | null = null;
  /** The appearance chunks (version 6), read by `loadAppearance`. */
  looks: { charts: Charts; tables: (Table | null)[]; materials: Materials } | null = null;
  /** The skin of a skinned file, once its bind chunks are read. */
  private skin: SkinState | null = null;

  /** See DecoderOptions.skinOffsets. */
  readonly skinOffsets: boolean;
  private attributes: SkinAttributes | null = null;
  /** Frames decoded with skinning on the CPU while holding offsets (a band not predicted by skinning). */
  exactFrames = 0;
  /** Nodes skinned on the CPU by the decoding itself while holding offsets (`positions()` not counted). */
  cpuSkins = 0;
  /** With offsets held: the last keyframe's band 0 offsets and palette, until its stencil weights are computed. */
  private keyPending: { key: Int32Array; palette: BigInt64Array | null } | null = null;
  /** With offsets held: the bands whose `current` holds positions while a frame decodes. */
  private exactCur: Uint8Array;
  /** Dequantized positions of the current interval's keyframe: what a partial-split cut with held priorities ranks reveals by. */
  private keyPositions: Float32Array | null = null;

  constructor(readonly reader: Reader, readonly minLevel: number, opts: DecoderOptions = {}) {
    this.skinOffsets = opts.skinOffsets ?? false;
    const h = reader.header;
    if (minLevel >= h.levelSizes.length) throw new DecodeError(`level ${minLevel}: the file has ${h.levelSizes.length} levels`);
    if (minLevel < reader.level) throw new DecodeError(`level ${minLevel}: the reader holds the index of levels ${reader.level}.. only`);
    this.replay = new Replay(h.levelSizes, minLevel, h.triangleCount);
    this.exactCur = new Uint8Array(h.levelSizes.length);
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

  /** Band j's parent map at keyframe k; a Key chunk in coding 3 reads frame 0's of the band too. */
  private async readParents(k: number, j: number): Promise<Uint32Array> {
    const c = this.reader, sizes = c.header.levelSizes;
    const raw = await c.chunk(c.find(ChunkKind.Key, k, j));
    let first: Uint32Array | undefined;
    if (k > 0 && keyFromFirst(raw)) first = readKey(await c.chunk(c.find(ChunkKind.Key, 0, j)), `frame 0 band ${j} keyframe`, sizes, j, c.version);
    return readKey(raw, `frame ${k} band ${j} keyframe`, sizes, j, c.version, first);
  }

  private async loadKeyframe(k: number): Promise<void> {
    const c = this.reader, h = c.header;
    const bands: KeyBand[] = h.levelSizes.map(() => ({ parent: new Uint32Array(0), faces: [] }));
    for (let j = h.levelSizes.length - 1; j >= this.minLevel; j--) {
      const parent = bands[j].parent = await this.readParents(k, j);
      // Clusters are never empty (proto/container.md, "The model the file encodes"): a parent
      // map that leaves one empty is not a hierarchy an encoder wrote (as the Rust decoder).
      const above = h.levelSizes[j + 1];
      if (above !== undefined) {
        const used = new Uint8Array(above);
        for (const p of parent) used[p] = 1;
        const empty = used.indexOf(0);
        if (empty >= 0) throw new DecodeError(`frame ${k} band ${j} keyframe: level ${j + 1} node ${empty} has no children`);
      }
    }
    const L = this.minLevel;
    let below: Below | null = null;
    if (L > 0) {
      const raw = await c.chunk(c.find(ChunkKind.Faces, k, L));
      if (isDerived(raw)) {
        // Faces coding 2: from the input triangles and the keyframe's parent maps below L.
        this.fine ??= readTriangles(await c.chunk(c.find(ChunkKind.Triangles, 0, 0)), "triangles chunk", h.triangleCount, h.vertexCount, c.version);
        const parents: Uint32Array[] = [];
        for (let j = 0; j < L; j++) parents.push(await this.readParents(k, j));
        below = new Below(this.fine, parents);
        bands[L].faces = below.faces();
      } else bands[L].faces = readFaces(raw, `frame ${k} band ${L} faces`, h.levelSizes[L], h.triangleCount, c.version);
    }
    this.below = below;
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
    if (h.motion === Motion.KeyframeAffine && this.lower) {
      // With offsets held, the stencils (which read band 0's key positions) are computed when a
      // frame first predicts band 0 otherwise than by skinning, if one does.
      if (this.holdsOffsets) { this.weights = null; this.keyPending = { key: this.current.slice(0, 3 * h.vertexCount), palette: this.skin!.palette }; }
      else this.weights = stencilWeights(this.lower, this.current, h.vertexCount);
    }
    // With offsets held the player ranks by the bind pose instead (session.ts): no CPU skinning for it.
    this.keyPositions = this.holdsOffsets ? null : this.positions();
    this.frame = k;
  }

  /**
   * Reveal priorities for a partial-split cut (an option, proto/container.md "Partial splits";
   * `selectTriangles(budget, benefits, true)`), from the positions `from` names: the frame's
   * own, the keyframe's at or before the frame (held through its interval, on the frame's own
   * hierarchy), or banded with 1 or 2 bands per factor 2 (the band of the frame's priority,
   * then the keyframe's): the Rust decoder's `BudgetPriorities`, bit for bit. With offsets
   * held, the frame's positions for all.
   */
  revealBenefits(from: RevealFrom = "frame"): Float64Array {
    const key = this.keyPositions;
    if (from === "frame" || !key) return this.replay.revealBenefits(this.positions());
    if (from === "keyframe") return this.replay.revealBenefits(key);
    const now = this.replay.revealBenefits(this.positions()), held = this.replay.revealBenefits(key);
    const perOctave = from === "banded1" ? 1 : 2;
    for (let g = 0; g < now.length; g++) now[g] = bandedPriority(now[g], held[g], perOctave);
    return now;
  }

  private async step(f: number): Promise<void> {
    const c = this.reader, h = c.header;
    const delta: FrameDelta = { swaps: [], corners: [] };
    for (let j = h.levelSizes.length - 1; j >= this.minLevel; j--) {
      readDelta(await c.chunkAt(ChunkKind.Delta, f, j), `frame ${f} band ${j} delta`, h.levelSizes, j, delta);
    }
    // A derived interval: the moves below minLevel too, whose effect on its corners replaces its
    // Corners chunk (which must say nothing).
    const below: FrameDelta = { swaps: [], corners: [] };
    if (this.below) for (let j = this.minLevel - 1; j >= 0; j--) readDelta(await c.chunkAt(ChunkKind.Delta, f, j), `frame ${f} band ${j} delta`, h.levelSizes, j, below);
    const pose = await this.readPose(f, false);
    const L = this.minLevel;
    if (this.below) {
      const raw = await c.chunkAt(ChunkKind.Corners, f, L);
      if (raw.length !== 1 || raw[0] !== 0) throw new DecodeError(`frame ${f} band ${L} corners: corner updates in an interval whose faces are derived`);
      for (const u of this.below.apply(below.swaps)) delta.corners.push({ level: L, t: u.t, corners: u.corners });
    } else if (L > 0) {
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
    if (!this.holdsOffsets) return this.decodeExact(f, fromKey);
    this.exactCur.fill(0);
    await this.decodeExact(f, fromKey);
    // Bands posed for a band that skinning did not predict go back to offsets.
    let any = false;
    for (let j = this.minLevel; j < this.exactCur.length; j++) if (this.exactCur[j]) { any = true; this.posedBand(this.current, j, true, -1); }
    if (any) this.exactFrames++;
  }

  /**
   * With offsets held: band j's node positions from offsets (pos = o + s(v, M)) with sign +1, or
   * offsets from positions with sign -1, under this frame's palette (`now`) or the previous one.
   */
  private posedBand(a: Int32Array, j: number, now: boolean | BigInt64Array | null, sign: 1 | -1): void {
    const s = this.skin!, p = new Int32Array(3);
    const palette = (now === true ? s.palette : now === false ? s.previous : now) ?? new BigInt64Array(0);
    this.cpuSkins += this.replay.offsets[j + 1] - this.replay.offsets[j];
    for (let g = this.replay.offsets[j]; g < this.replay.offsets[j + 1]; g++) {
      s.lbs(g, palette, p);
      for (let k = 0; k < 3; k++) a[3 * g + k] = (a[3 * g + k] + sign * p[k]) | 0;
    }
  }

  /**
   * Before decoding band j, which skinning does not predict this frame, with offsets held: what
   * its prediction reads, posed (proto/container.md, "Positions, band j": its own previous
   * positions, its parents' current and previous ones, band 0's lower neighbours, which are band
   * 0's own nodes, decoded before them). Skinned bands above stay offsets unless read so.
   */
  private poseFor(j: number, intra: boolean): void {
    const top = this.reader.header.levelSizes.length - 1;
    if (!intra) this.posedBand(this.previous, j, false, 1);
    this.exactCur[j] = 1;
    const pending = this.keyPending;
    if (j === 0 && pending && this.lower) {
      this.posedBand(pending.key, 0, pending.palette, 1);
      this.weights = stencilWeights(this.lower, pending.key, this.reader.header.vertexCount);
      this.keyPending = null;
    }
    if (j < top && !this.exactCur[j + 1]) {
      this.posedBand(this.current, j + 1, true, 1);
      if (!intra) this.posedBand(this.previous, j + 1, false, 1);
      this.exactCur[j + 1] = 1;
    }
  }

  /**
   * Offsets of band j, which skinning predicts this frame (proto/container.md, "Skinning"): with
   * pos_f = s_f + res on keyframes and pos_f = pos_(f-1) + s_f - s_(f-1) + res otherwise,
   * o_f = pos_f - s_f is res, or o_(f-1) + res, in the same 32-bit wrapping arithmetic: no
   * skinning on the CPU.
   */
  private offsetBand(j: number, intra: boolean, shift: number, res: Int32Array): void {
    const cur = this.current, prev = this.previous, base = this.replay.offsets[j];
    // Band 0's residuals come in its decoding order.
    const sequence = j === 0 && this.lower ? this.lower.sequence : null;
    for (let k = 0; k < this.reader.header.levelSizes[j]; k++) {
      const g = 3 * (base + (sequence ? sequence[k] : k));
      for (let a = 0; a < 3; a++) cur[g + a] = ((intra ? 0 : prev[g + a]) + (res[3 * k + a] << shift)) | 0;
    }
  }

  /** Whether `current` holds offsets from skinned positions (DecoderOptions.skinOffsets on a skinned file). */
  get holdsOffsets(): boolean { return this.skinOffsets && this.skin !== null; }

  /**
   * Whether budgets may take partial splits (an option, proto/container.md "Partial splits"):
   * not on files with attribute tables (texture coordinates or colours), whose entries cover
   * only the charts around a node at its own level; there they keep whole splits.
   */
  get partialSplits(): boolean {
    const a = this.reader.header.appearance;
    return !a || channels(a) === 0;
  }

  /** Whether the file is skinned (known once a frame is decoded). */
  get skinned(): boolean { return this.skin !== null; }

  /**
   * Decoded nodes' positions from offsets `o`: s(v, M) + o with M this frame's palette (`now`)
   * or the previous frame's, into `out` (a new array unless given).
   */
  private posed(o: Int32Array, now: boolean, out: Int32Array = new Int32Array(o.length)): Int32Array {
    const s = this.skin!, palette = (now ? s.palette : s.previous) ?? new BigInt64Array(0), p = new Int32Array(3);
    for (let g = this.replay.offsets[this.minLevel]; 3 * g < o.length; g++) {
      s.lbs(g, palette, p);
      for (let a = 0; a < 3; a++) out[3 * g + a] = (o[3 * g + a] + p[a]) | 0;
    }
    return out;
  }

  /**
   * Every node's skin for drawing (skinned files, after the first frame): bind position in bind
   * quanta, palette entries and weights (in units of 1; a node without influence has weights 0
   * and its offset carries the box's minimum corner, see `offsets`).
   */
  skinAttributes(): SkinAttributes | null {
    const s = this.skin;
    if (!s) return null;
    if (this.attributes) return this.attributes;
    const n = s.nodes.count.length, out: SkinAttributes = { bind: new Float32Array(3 * n), joints: new Uint16Array(4 * n), weights: new Float32Array(4 * n) };
    for (let g = 0; g < n; g++) {
      for (let a = 0; a < 3; a++) out.bind[3 * g + a] = Number(s.nodes.bind[3 * g + a]);
      for (let k = 0; k < s.nodes.count[g]; k++) {
        out.joints[4 * g + k] = s.nodes.joints[4 * g + k];
        out.weights[4 * g + k] = Number(s.nodes.weights[4 * g + k]) / 65536;
      }
    }
    return (this.attributes = out);
  }

  /**
   * The frame's palette as 4x4 matrices (16 floats per entry, column-major as three.js's
   * Matrix4.elements) from bind quanta to the stream's coordinates: linear part
   * step * L / 2^15, translation bbox_min + step * T / 4 (proto/container.md, "Skinning": L in
   * 2^-15 position quanta per bind quantum, T in 2^-2 quanta from bbox_min). Skinning with them
   * in floating point, sum over k of w_k M_k b, differs from the integer s(v, M) by under a
   * position quantum (the integer version floors each product's low bits and rounds the sum).
   */
  paletteMatrices(out?: Float32Array): Float32Array {
    const h = this.reader.header, s = this.skin;
    const palette = s?.palette ?? new BigInt64Array(0), n = palette.length / 12;
    const m = out && out.length >= 16 * n ? out : new Float32Array(16 * n);
    const linear = h.step / 32768;
    for (let e = 0; e < n; e++) {
      const p = 12 * e, q = 16 * e;
      for (let a = 0; a < 3; a++) {
        for (let c = 0; c < 3; c++) m[q + 4 * c + a] = Number(palette[p + 4 * a + c]) * linear;
        m[q + 12 + a] = h.bboxMin[a] + (Number(palette[p + 4 * a + 3]) * h.step) / 4;
        m[q + 4 * a + 3] = 0;
      }
      m[q + 15] = 1;
    }
    return m;
  }

  /**
   * Every node's offset in the stream's coordinates, step * o (holdsOffsets), plus bbox_min for
   * a node without influence (it skins to 0); what a GPU adds to the skinned bind position.
   */
  offsets(out?: Float32Array): Float32Array {
    const h = this.reader.header, cur = this.current, count = this.skin?.nodes.count;
    const o = out && out.length >= cur.length ? out : new Float32Array(cur.length);
    for (let g = 0; 3 * g < cur.length; g++) {
      const free = count !== undefined && count[g] === 0;
      for (let a = 0; a < 3; a++) o[3 * g + a] = cur[3 * g + a] * h.step + (free ? h.bboxMin[a] : 0);
    }
    return o;
  }

  /** The exact path (proto/container.md, "Positions, band j"): `current` holds positions. */
  private async decodeExact(f: number, fromKey: boolean): Promise<void> {
    const h = this.reader.header, r = this.replay;
    const intra = fromKey || this.reader.isKeyframe(f);
    const cur = this.current, prev = this.previous;
    const top = h.levelSizes.length - 1;
    for (let j = top; j >= this.minLevel; j--) {
      const what = `frame ${f} band ${j} positions`;
      const { shift, res } = readPositions(await this.reader.chunkAt(ChunkKind.Positions, f, j), what, h.levelSizes[j]);
      if (this.holdsOffsets) {
        if (this.skin!.uses(j)) { this.offsetBand(j, intra, shift, res); continue; }
        this.poseFor(j, intra);
      }
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
    // The triangles: a Charts chunk with neighbour charts and band 0's derived entries are read
    // from them, and a band's faces in frame 0 are walked up from them.
    const triangles = async (): Promise<Uint32Array> =>
      this.triangles ?? readTriangles(await c.chunk(c.find(ChunkKind.Triangles, 0, 0)), "triangles chunk", h.triangleCount, h.vertexCount, c.version);
    const chartsRaw = await c.chunk(c.find(ChunkKind.Charts, 0, 0));
    const charts = readCharts(chartsRaw, a, h.triangleCount, chartsNeedTriangles(chartsRaw) ? await triangles() : null);
    const materials = readMaterials(await c.chunk(c.find(ChunkKind.Materials, 0, 0)), a);
    const tables: (Table | null)[] = h.levelSizes.map(() => null);
    // Without channels there is nothing to look up: no Attributes chunks in files since
    // 2026-11-26, and older files' value-less tables are not read.
    const lowest = channels(a) === 0 ? h.levelSizes.length : this.minLevel;
    for (let j = h.levelSizes.length - 1; j >= lowest; j--) {
      const raw = await c.chunk(c.find(ChunkKind.Attributes, 0, j)), what = `band ${j} attributes`;
      let above = null;
      if (needsAbove(raw)) {
        // Bands go top down: the band above is read; frame 0's parents from its Key chunk.
        const parent = readKey(await c.chunk(c.find(ChunkKind.Key, 0, j)), `frame 0 band ${j} keyframe`, h.levelSizes, j, c.version);
        const table = tables[j + 1];
        above = table ? { parent, table } : null;
      }
      if (j > 0 && needsFaces(raw)) {
        // Values across band j's faces in frame 0: the triangles walked up frame 0's parents
        // of levels 0..j (their Key chunks), as a derived Faces chunk does.
        const parents: Uint32Array[] = [];
        for (let i = 0; i < j; i++) parents.push(readKey(await c.chunk(c.find(ChunkKind.Key, 0, i)), `frame 0 band ${i} keyframe`, h.levelSizes, i, c.version));
        const faces = bandFaces(await triangles(), charts.triangleChart, parents, what);
        tables[j] = readTable(raw, what, h.levelSizes[j], a, h.triangleCount, above, faces);
        continue;
      }
      if (j > 0) { tables[j] = readTable(raw, what, h.levelSizes[j], a, h.triangleCount, above); continue; }
      const tris = await triangles();
      // Texture coordinates placed by the bind pose: the Bind chunk of band 0, which a level-0
      // client of a skinned file reads anyway.
      let bind: BigInt64Array | null = null;
      if (needsBind(raw)) {
        if (!h.skin) throw new DecodeError(`${what}: bind positions in a file without a skin`);
        if (this.skin) bind = this.skin.nodes.bind; // level 0 first: read already
        else {
          const skins = nodeSkins(h.levelSizes[0]);
          readBinds(await c.chunk(c.find(ChunkKind.Bind, 0, 0)), "band 0 bind", h.levelSizes[0], h.skin.paletteLen, skins, 0);
          bind = skins.bind;
        }
      }
      tables[j] = readBand0Table(raw, what, h.levelSizes[j], a, tris, charts.triangleChart, above, bind);
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
    // With offsets held, the exact positions are s(v, M_f) + o: the same bits as the default path.
    const q = this.holdsOffsets ? this.posed(this.current, true) : this.current;
    // f32 arithmetic, as the Rust decoder: lo + (q as f32) * step.
    for (let i = 0; i < out.length; i++) out[i] = Math.fround(h.bboxMin[i % 3] + Math.fround(q[i] * h.step));
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
