// The decoding side of a player (it runs in the worker; nothing here touches the DOM, so Node
// tests drive it too): opens a container through a RangeCache, keeps one Decoder
// (container/decode.ts) at the finest level the triangle budget needs, fetches the chunks that
// level reads ahead of the playhead, in blocks of frames (to the end of a keyframe interval) so
// that a banded file's groups (proto/container.md, "Index": each group's chunks lie frame after
// frame) are a few long runs, fetched in one multi-range request; and turns a decoded frame
// into render-ready buffers: the budget cut's vertices, smooth normals and indices, computed
// once per decoded frame. Of a banded index it reads the groups of the levels it plays only
// (the coarsest at first, finer ones when a budget needs them).

import { ChunkEntry, ChunkKind, Decoder, Reader, attributeEntry, dequantizeUv, readMaterials, texturedMesh } from "../container/index.js";
import { FLAG_BANDS } from "../container/format.js";
import { buildCutMesh, morphAttributeStarts, morphStarts } from "../geomorph.js";
import { FetchRanges, RangeCache } from "./ranges.js";
import type { ColourMode, FramePayload, LooksPayload, MaterialGroup, OpenedInfo, SkinFrame } from "./protocol.js";

/**
 * The first request of a container: its preamble, header and (a small file's) index. Small, as
 * a coarse client of a banded file reads a small share of its index: what lies past it comes
 * in a second request, with only the groups the level needs.
 */
const FIRST_READ = 16 << 10;
/** Most frames one read-ahead block spans, in multiples of the read-ahead (a long keyframe interval). */
const BLOCK_READS = 4;
/**
 * Budgets within 2% of a level's triangle count take that level (as the Rust client's
 * LEVEL_SLACK: anchored levels come out a few triangles short of round shares).
 */
const LEVEL_SLACK = 0.98;
/** Frames a geomorph is carried over while playing (a quarter second at 30 frames per second). */
const MORPH_FRAMES = 8;

export interface SessionOptions {
  /** Memory limit of the byte cache (bytes). */
  cacheBytes?: number;
  /** Frames whose bytes are fetched ahead of the one being decoded. */
  readAhead?: number;
  /** Whole-mesh triangles per level, when a server says so; estimated from node counts if not. */
  trianglesPerLevel?: number[];
  /**
   * Skinned streams: frames carry the cut's skin, the palette and offsets (FramePayload.skin)
   * for a vertex shader to skin, instead of posed positions and normals; the decoder then skins
   * nothing on the CPU (DecoderOptions.skinOffsets). Default false.
   */
  gpuSkin?: boolean;
}

export class Session {
  readonly cache: RangeCache;
  /** The container; of a banded index, the entries of the level played (or all of them). */
  container: Reader;
  /** Whether the reader holds the whole index; whether a decoder reads through it. */
  private wholeIndex: boolean;
  private readerUsed = false;
  private byFrame: ChunkEntry[][] = [];
  private triangles: ChunkEntry | undefined;
  private decoder: Decoder | null = null;
  private coarseDecoder: Decoder | null = null;
  private errorsOf: { decoder: Decoder; frame: number; positions: Float32Array; errors: Float64Array | null; benefits: Float64Array | null } | null = null;
  /** The decoder whose cut is the whole mesh of its level, every node expanded. */
  private fullOn: Decoder | null = null;
  private lastIndices: Uint32Array | null = null;
  private indexVersion = 0;
  /** The cut a geomorph starts from, which morph it is, and the frames it has lasted. */
  private morphFrom: { nodes: Uint32Array; id: number; frames: number } | null = null;
  private morphId = 0;
  private last: { nodes: Uint32Array; budget: number; level: number; frame: number } | null = null;
  private aheadError: unknown = null;
  readonly trianglesPerLevel: number[];
  readonly readAhead: number;
  budget: number;
  colour: ColourMode = "authored";
  readonly gpuSkin: boolean;
  /** What the page holds of the skin (GPU skinning): the cut's nodes, its offsets, their versions. */
  private skinSent: { nodes: Uint32Array; offsets: Float32Array } | null = null;
  private skinVersion = 0;
  private offsetsVersion = 0;
  private nodeOffsets: Float32Array = new Float32Array(0);
  /** GPU skinning: the last cut's appearance (built from bind positions), while the cut stays. */
  private looksOf: { decoder: Decoder; shown: Uint32Array; nodes: Uint32Array; indices: Uint32Array; looks: NonNullable<ReturnType<typeof texturedCut>> } | null = null;

  private constructor(container: Reader, cache: RangeCache, opts: SessionOptions) {
    this.cache = cache;
    this.container = container;
    this.wholeIndex = (container.flags & FLAG_BANDS) === 0 || container.version < 7;
    const h = container.header;
    this.trianglesPerLevel = opts.trianglesPerLevel?.length === h.levelSizes.length
      ? opts.trianglesPerLevel
      : h.levelSizes.map((n) => Math.round((h.triangleCount * n) / h.vertexCount));
    this.readAhead = Math.max(0, opts.readAhead ?? 8);
    this.gpuSkin = (opts.gpuSkin ?? false) && h.skin !== null;
    this.budget = h.triangleCount;
    this.holdIndex();
  }

  /** The container's index entries by frame (and its Triangles chunk), as the reader holds them. */
  private holdIndex(): void {
    const c = this.container, h = c.header;
    this.byFrame = Array.from({ length: h.frameCount }, () => []);
    this.triangles = undefined;
    for (const e of c.index) {
      if (e.kind === ChunkKind.Triangles) this.triangles = e;
      else if (e.frame < h.frameCount) this.byFrame[e.frame].push(e);
    }
  }

  /**
   * The reader, holding the index entries a level-`level` decoder reads. Of a banded index, a
   * reader opened for a level holds that level's groups only (not the faces of coarser bands,
   * proto/container.md "Index"): a reader no decoder uses yet is opened again for `level`; one
   * in use, for the whole index, which serves every level (a budget that moves once reads the
   * rest of the index once). The bytes held are not fetched again.
   */
  private async readerFor(level: number): Promise<Reader> {
    const c = this.container;
    if (this.wholeIndex || c.level === level) return c;
    const part = !this.readerUsed;
    this.container = await Reader.open((o, n) => this.cache.read(o, n), c.fileLen, part ? level : undefined);
    this.wholeIndex = !part;
    this.readerUsed = false;
    this.holdIndex();
    return this.container;
  }

  /** A decoder of `level` over the reader for it. */
  private async decoderFor(level: number): Promise<Decoder> {
    const c = await this.readerFor(level);
    this.readerUsed = true;
    return new Decoder(c, level, { skinOffsets: this.gpuSkin });
  }

  /** Opens a container: one range request for its start, which tells the file's length too. */
  static async open(fetchRanges: FetchRanges, opts: SessionOptions = {}): Promise<Session> {
    const cache = new RangeCache(fetchRanges, opts.cacheBytes);
    await cache.ensure([[0, FIRST_READ]]).catch((e) => { throw new Error(`reading the container's start: ${e instanceof Error ? e.message : e}`); });
    const total = cache.total;
    if (!(total > 0)) throw new Error("the server did not say how long the container is (no Content-Range)");
    // The first span may be shorter than FIRST_READ: the whole file. Of a banded index, the
    // coarsest level's groups (frames read finer ones when their budget needs them).
    const container = await Reader.open((o, n) => cache.read(o, n), total, Number.MAX_SAFE_INTEGER);
    return new Session(container, cache, opts);
  }

  info(): OpenedInfo {
    const h = this.container.header;
    return {
      frames: h.frameCount, frameRate: h.frameRate, vertices: h.vertexCount, triangles: h.triangleCount,
      levels: h.levelSizes.slice(), trianglesPerLevel: this.trianglesPerLevel.slice(), keyframeInterval: h.keyframeInterval,
      bboxMin: h.bboxMin.slice(), bboxMax: h.bboxMax.slice(), bytes: this.container.fileLen, version: this.container.version,
      appearance: h.appearance !== null, gpuSkinJoints: this.gpuSkin ? h.skin!.paletteLen : 0,
    };
  }

  /** Whether frames carry the stream's appearance: "authored" mode on a stream that has one. */
  get textured(): boolean { return this.colour === "authored" && this.container.header.appearance !== null; }

  /**
   * The stream's materials and its images' encoded bytes (null without appearance): what the
   * page needs once to build its materials (pmcodec-three's appearance module).
   */
  async looks(): Promise<LooksPayload | null> {
    const c = this.container, a = c.header.appearance;
    if (!a) return null;
    const materials = readMaterials(await c.chunk(c.find(ChunkKind.Materials, 0, 0)), a);
    const images = [];
    for (const [i, d] of materials.images.entries()) {
      // A copy: the cache's bytes stay in the cache when the copy is transferred to the page.
      const bytes = (await c.chunk(c.find(ChunkKind.Image, 0, i))).slice();
      if (bytes.length !== d.byteLength) throw new Error(`image ${i}: ${bytes.length} bytes where the materials chunk says ${d.byteLength}`);
      images.push({ name: d.name, mimeType: d.mimeType, bytes });
    }
    return { type: "looks", materials, images, vertexColors: a.colors, normals: a.normals };
  }

  /** The coarsest level whose whole mesh has the budget's triangles. */
  levelFor(budget: number): number {
    let level = 0;
    for (let l = 0; l < this.trianglesPerLevel.length; l++) if (this.trianglesPerLevel[l] >= budget * LEVEL_SLACK) level = l;
    return level;
  }

  /** The level of the decoder now (what is being fetched), or -1 before the first frame. */
  get level(): number { return this.decoder?.minLevel ?? -1; }

  /**
   * What to fetch ahead of frame f (decoded at `level`; from the next keyframe on at `want`, the
   * level the budget wants, a loop restarting at keyframe 0): nothing while the next
   * `readAhead` frames are held or on their way; else a block from the first that is not to
   * the end of the keyframe interval holding frame f + readAhead (at most BLOCK_READS times the
   * read-ahead), so that each group of a banded file is one run of many frames and a block
   * is one request, about once a keyframe interval.
   */
  private ahead(f: number, level: number, want: number): [number, number][] {
    const c = this.container, n = c.header.frameCount, horizon = Math.min(this.readAhead, n - 1);
    const out: [number, number][] = [];
    let passedKey = false, first = 0;
    for (let i = 1; i <= horizon; i++) {
      const g = (f + i) % n;
      if (c.isKeyframe(g)) passedKey = true;
      const at = out.length;
      this.spans(g, passedKey ? want : level, out);
      if (first === 0 && out.slice(at).some(([a, b]) => !this.cache.has(a, b))) first = i;
    }
    if (first === 0) return [];
    const last = Math.min(n - 1, first + BLOCK_READS * horizon - 1);
    for (let i = horizon + 1; i <= last; i++) {
      const g = (f + i) % n;
      if (c.isKeyframe(g)) break;
      this.spans(g, passedKey ? want : level, out);
    }
    return out;
  }

  /** Byte ranges of what a level-L decoder reads of frame f. */
  private spans(f: number, level: number, out: [number, number][]): void {
    const base = this.container.dataStart;
    for (const e of this.byFrame[f]) if (this.container.reads(e, level)) out.push([base + e.offset, base + e.offset + e.storedLen]);
  }

  /**
   * Decodes frame f and cuts it at the budget. Raising the budget past the decoder's level
   * starts a finer decoder at once (from the keyframe before f); lowering it waits for a
   * keyframe, so coarser playback stops fetching finer bands from the next keyframe on.
   */
  async frame(f: number): Promise<FramePayload> {
    const t0 = performance.now();
    const h = this.container.header;
    if (!(f >= 0 && f < h.frameCount)) throw new Error(`frame ${f} is beyond the ${h.frameCount} frames`);
    if (this.aheadError) { const e = this.aheadError; this.aheadError = null; throw e; }
    const want = this.levelFor(this.budget);
    let d = this.decoder;
    const key = this.container.keyframeBefore(f);
    const continues = d !== null && d.frame >= key && d.frame <= f;
    if (!d || want < d.minLevel || (want > d.minLevel && (!continues || f === key))) d = this.decoder = await this.decoderFor(want);
    // (The reader serves `want` too, for the read-ahead past the next keyframe.)
    const c = await this.readerFor(want);
    const from = d.frame >= key && d.frame <= f ? d.frame + 1 : key;
    const need: [number, number][] = [];
    // Above level 0, an interval that derives its faces reads the triangles too.
    if ((d.minLevel === 0 || c.derives(key, d.minLevel)) && this.triangles) need.push([c.dataStart + this.triangles.offset, c.dataStart + this.triangles.offset + this.triangles.storedLen]);
    for (let g = from; g <= f; g++) this.spans(g, d.minLevel, need);
    // Asked for in the same tick: the frame's ranges and the block ahead share requests.
    const ready = this.cache.ensure(need);
    this.cache.ensure(this.ahead(f, d.minLevel, want)).catch((e) => { this.aheadError = e; });
    await ready;
    await d.seek(f);
    if (this.textured) await d.loadAppearance();
    const tDecode = performance.now();
    return this.cut(d, f, performance.now() - t0, tDecode);
  }

  /**
   * After a jump, the frame from a coarse decoder (two levels below the top, or the budget's
   * level if coarser), which reads and decodes a small share of the bytes: something to show
   * while the budget's decoder goes back to the keyframe and steps forward. Null when the
   * budget's decoder gets there by stepping on, or is that coarse already.
   */
  async coarse(f: number): Promise<FramePayload | null> {
    const t0 = performance.now();
    const c = this.container, h = c.header;
    const want = this.levelFor(this.budget), level = Math.max(want, h.levelSizes.length - 3);
    const d = this.decoder, key = c.keyframeBefore(f);
    if (level <= want || (d && d.frame >= key && d.frame <= f && d.minLevel <= want)) return null;
    let cd = this.coarseDecoder;
    if (!cd || cd.minLevel !== level) cd = this.coarseDecoder = await this.decoderFor(level);
    const from = cd.frame >= key && cd.frame <= f ? cd.frame + 1 : key;
    const need: [number, number][] = [];
    for (let g = from; g <= f; g++) this.spans(g, level, need);
    await this.cache.ensure(need);
    await cd.seek(f);
    if (this.textured) await cd.loadAppearance();
    return this.cut(cd, f, performance.now() - t0, performance.now());
  }

  /** Cuts the decoder's frame at the budget again (a budget change while paused). */
  recut(): FramePayload | null {
    const d = this.decoder;
    if (!d || d.frame < 0 || this.levelFor(this.budget) < d.minLevel || (this.textured && !d.looks)) return null;
    const t = performance.now();
    return this.cut(d, d.frame, 0, t);
  }

  private cut(d: Decoder, f: number, decodeMs: number, t0: number): FramePayload {
    const r = d.replay;
    // A budget that holds the level's whole mesh: every node stays expanded from frame to frame
    // (a delta moves nodes, never collapses them), so the cut is the replay's as it stands and
    // needs no split priorities (the two most expensive steps of a frame) unless they are shown.
    const whole = this.fullOn === d && this.budget >= this.trianglesPerLevel[d.minLevel] && r.shown.length <= this.budget && allExpanded(r);
    // GPU skinning: the CPU has no posed positions; the cut's split priorities, normals and
    // geomorph starts come from the bind pose (skinned by the shader with the positions).
    const gpu = d.holdsOffsets ? d.skinAttributes() : null;
    let memo = this.errorsOf;
    if (!memo || memo.decoder !== d || memo.frame !== f) {
      const positions = gpu ? gpu.bind : d.positions();
      memo = this.errorsOf = { decoder: d, frame: f, positions, errors: null, benefits: null };
    }
    // Budgets split by budget priorities; the error colouring shows split priorities (RMS).
    if (!whole && !memo.benefits) memo.benefits = r.splitBenefits(memo.positions);
    if (this.colour === "error" && !memo.errors) memo.errors = r.nodeErrors(memo.positions);
    const all = memo.positions;
    if (!whole) {
      r.selectTriangles(this.budget, memo.benefits!);
      this.fullOn = this.budget >= this.trianglesPerLevel[d.minLevel] && allExpanded(r) ? d : null;
    }
    const cutMesh = buildCutMesh(r);
    // GPU skinning: a cut's appearance is built from bind positions, so the same cut (same
    // nodes, same triangles) has the same vertices, normals and texture coordinates as in the
    // frame before: built once per cut, not once per frame.
    const memoLooks = this.looksOf;
    const same = gpu && memoLooks && memoLooks.decoder === d && equal(memoLooks.shown, r.shown) && equal(memoLooks.nodes, cutMesh.nodes) && equal(memoLooks.indices, cutMesh.indices);
    const looks = !this.textured ? null : same ? memoLooks.looks : texturedCut(d, all);
    this.looksOf = gpu && looks ? { decoder: d, shown: Uint32Array.from(r.shown), nodes: cutMesh.nodes, indices: cutMesh.indices, looks } : null;
    const mesh = looks ? { nodes: looks.mesh.nodes, indices: looks.indices } : cutMesh;
    // The index buffer only when it changed: at full resolution it rarely does.
    let indices: Uint32Array | undefined = mesh.indices;
    if (this.lastIndices && equal(this.lastIndices, mesh.indices)) indices = undefined;
    else { this.lastIndices = mesh.indices.slice(); this.indexVersion++; }
    // A kept appearance (GPU skinning) is used again: its buffers go out as copies.
    if (indices && this.looksOf) indices = indices.slice();
    const n = mesh.nodes.length;
    const positions = new Float32Array(gpu ? 0 : 3 * n);
    for (let i = 0; i < (gpu ? 0 : n); i++) {
      const g = 3 * mesh.nodes[i];
      positions[3 * i] = all[g]; positions[3 * i + 1] = all[g + 1]; positions[3 * i + 2] = all[g + 2];
    }
    // With appearance, the decoder's normals: split at seams and smoothing groups
    // (proto/container.md, "Drawing a cut's appearance"), as the server's GLB answers draw them.
    const normals = gpu ? new Float32Array(0) : looks ? looks.mesh.normals : vertexNormals(positions, mesh.indices);
    // A geomorph when the cut moved for another reason than time (the budget or the level): from
    // the cut before the change, carried on over the next frames while playing (each frame's
    // starts are the old cut's nodes at that frame's positions), so the page blends on one clock.
    let starts: Float32Array | undefined;
    const prev = this.last;
    // The old cut is kept as its distinct nodes (a textured mesh repeats a node once per chart
    // and group).
    if (prev && (prev.budget !== this.budget || prev.level !== d.minLevel)) this.morphFrom = { nodes: prev.nodes, id: ++this.morphId, frames: 0 };
    const from = this.morphFrom;
    let uvStarts: Float32Array | undefined, uv1Starts: Float32Array | undefined;
    if (from && from.frames < MORPH_FRAMES && from.nodes.every((g) => g >= r.offsets[d.minLevel])) {
      if (!gpu) starts = morphStarts(mesh, from.nodes, all, (g) => r.parentGlobal(g));
      if (looks) [uvStarts, uv1Starts] = looks.uvStarts(from.nodes);
      from.frames++;
    } else this.morphFrom = null;
    let colours: Float32Array | undefined;
    // (Copies: the payload's buffers are transferred, and a kept appearance is used again.)
    if (looks) colours = looks.mesh.colors?.slice() ?? undefined;
    else if (this.colour === "level" || this.colour === "error") colours = colourOf(this.colour, mesh.nodes, r, memo.errors ?? new Float64Array(r.nodeCount));
    let skin: SkinFrame | undefined;
    if (gpu) {
      skin = this.skinFrame(d, gpu, mesh, indices !== undefined, looks ? looks.mesh.normals.slice() : null);
      // The geomorph blends bind positions and offsets (the shader skins the blend with the
      // vertex's own influences), from those of the node the vertex starts from, as morphStarts.
      if (this.morphFrom && this.morphFrom.frames > 0 && this.morphFrom.nodes.every((g) => g >= r.offsets[d.minLevel])) {
        skin.startBind = morphStarts(mesh, this.morphFrom.nodes, gpu.bind, (g) => r.parentGlobal(g));
        skin.startOffsets = morphStarts(mesh, this.morphFrom.nodes, this.nodeOffsets, (g) => r.parentGlobal(g));
      }
    }
    this.last = { nodes: cutMesh.nodes, budget: this.budget, level: d.minLevel, frame: f };
    return {
      type: "frame", seq: 0, frame: f, budget: this.budget, level: d.minLevel, budgetLevel: this.levelFor(this.budget), triangles: mesh.indices.length / 3,
      positions, normals, indices, indexVersion: this.indexVersion, indexCount: mesh.indices.length, starts, morphId: this.morphId, colours,
      uvs: looks?.mesh.uv0?.slice() ?? undefined, uv1: looks?.mesh.uv1?.slice() ?? undefined, uvStarts, uv1Starts, groups: looks?.groups, skin,
      decodeMs, cutMs: performance.now() - t0, fetched: this.cache.fetched, requests: this.cache.requests, cached: this.cache.size,
    };
  }

  /**
   * A GPU-skinned frame: the cut's per-vertex skin when the cut changed (new vertices or
   * triangles), the palette, and the offsets: all of them when the cut changed, else those that
   * changed since the last frame (all of them when most did, none when none did).
   */
  private skinFrame(d: Decoder, gpu: NonNullable<ReturnType<Decoder["skinAttributes"]>>, mesh: { nodes: Uint32Array; indices: Uint32Array }, newIndices: boolean, textureNormals: Float32Array | null): SkinFrame {
    const nodes = mesh.nodes, n = nodes.length;
    this.nodeOffsets = d.offsets(this.nodeOffsets);
    const all = this.nodeOffsets, o = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) { const g = 3 * nodes[i]; o[3 * i] = all[g]; o[3 * i + 1] = all[g + 1]; o[3 * i + 2] = all[g + 2]; }
    const skin: SkinFrame = { version: this.skinVersion, palette: d.paletteMatrices(), offsetsVersion: this.offsetsVersion };
    const sent = this.skinSent;
    if (!sent || newIndices || !equal(sent.nodes, nodes)) {
      skin.version = ++this.skinVersion;
      const bind = new Float32Array(3 * n), joints = new Uint16Array(4 * n), weights = new Float32Array(4 * n);
      for (let i = 0; i < n; i++) {
        const g = nodes[i];
        bind.set(gpu.bind.subarray(3 * g, 3 * g + 3), 3 * i);
        joints.set(gpu.joints.subarray(4 * g, 4 * g + 4), 4 * i);
        weights.set(gpu.weights.subarray(4 * g, 4 * g + 4), 4 * i);
      }
      Object.assign(skin, { bind, joints, weights, normals: textureNormals ?? vertexNormals(bind, mesh.indices) });
      skin.offsetsVersion = ++this.offsetsVersion;
      skin.offsets = o.slice();
    } else {
      const before = sent.offsets, changed: number[] = [];
      for (let i = 0; i < n; i++) if (o[3 * i] !== before[3 * i] || o[3 * i + 1] !== before[3 * i + 1] || o[3 * i + 2] !== before[3 * i + 2]) changed.push(i);
      if (changed.length > 0) {
        skin.offsetsVersion = ++this.offsetsVersion;
        // An index and three values per changed vertex: past 3/4 of them, the whole array is smaller.
        if (4 * changed.length >= 3 * n) skin.offsets = o.slice();
        else {
          skin.changed = Uint32Array.from(changed);
          skin.values = new Float32Array(3 * changed.length);
          changed.forEach((i, k) => skin.values!.set(o.subarray(3 * i, 3 * i + 3), 3 * k));
        }
      }
    }
    this.skinSent = { nodes: nodes.slice(), offsets: o };
    return skin;
  }
}

/**
 * The replay's shown triangles with the stream's appearance (the decoder's `loadAppearance`
 * done): one vertex per (cut node, chart, smoothing group), triangles sorted by material so
 * each material draws as one group; and, for a geomorph, where each vertex's texture
 * coordinates start (`morphAttributeStarts`: those of the node the vertex's position starts
 * from, in the vertex's own chart).
 */
/** Whether missing attribute entries were reported (once per worker). */
let warned = false;

function texturedCut(d: Decoder, positions: Float32Array): { mesh: ReturnType<typeof texturedMesh>; indices: Uint32Array; groups: MaterialGroup[]; uvStarts: (old: Uint32Array) => [Float32Array | undefined, Float32Array | undefined] } | null {
  const a = d.reader.header.appearance, looks = d.looks;
  if (!a || !looks) return null;
  const r = d.replay, rep = r.cutNodes(), base = r.offsets[r.minLevel];
  const shown = r.shown, cut = new Uint32Array(3 * shown.length);
  for (let i = 0; i < shown.length; i++) for (let c = 0; c < 3; c++) cut[3 * i + c] = rep[base + r.corners[3 * shown[i] + c]];
  // Lenient: containers written so far lack some (node, chart) entries that budget cuts mixing
  // levels reach (the Rust decoder refuses those cuts too); such a vertex takes its
  // neighbours' values rather than the frame failing.
  const mesh = texturedMesh(a, looks.charts, looks.tables, r.offsets, positions, shown, cut, { lenient: true });
  if (mesh.missing > 0 && !warned) {
    warned = true;
    console.warn(`pmcodec: ${mesh.missing} vertices of a cut have no texture coordinates in the file's tables; filled in from their neighbours`);
  }
  // Counting sort of the triangles by material (stable: mesh order within a material).
  const nm = Math.max(1, looks.materials.materials.length), count = new Uint32Array(nm + 1);
  for (const m of mesh.triangleMaterial) count[Math.min(m, nm - 1) + 1]++;
  for (let m = 0; m < nm; m++) count[m + 1] += count[m];
  const groups: MaterialGroup[] = [];
  for (let m = 0; m < nm; m++) if (count[m + 1] > count[m]) groups.push({ start: 3 * count[m], count: 3 * (count[m + 1] - count[m]), material: m });
  const indices = new Uint32Array(mesh.indices.length), at = count.slice(0, nm);
  mesh.triangleMaterial.forEach((m, t) => { indices.set(mesh.indices.subarray(3 * t, 3 * t + 3), 3 * at[Math.min(m, nm - 1)]++); });
  const uvStarts = (old: Uint32Array): [Float32Array | undefined, Float32Array | undefined] => {
    const set = (k: number, own: Float32Array | null): Float32Array | undefined => own ? morphAttributeStarts(mesh.nodes, mesh.charts, old, own, 2, (g) => r.parentGlobal(g), (g, chart, out, o) => {
      const e = attributeEntry(a, looks.tables, r.offsets, g, chart);
      if (!e) return false;
      out[o] = dequantizeUv(a, 0, e[2 * k]); out[o + 1] = dequantizeUv(a, 1, e[2 * k + 1]);
      return true;
    }) : undefined;
    return [set(0, mesh.uv0), set(1, mesh.uv1)];
  };
  return { mesh, indices, groups, uvStarts };
}

function allExpanded(r: Decoder["replay"]): boolean {
  for (let g = r.offsets[r.minLevel + 1] ?? r.nodeCount; g < r.nodeCount; g++) if (!r.expanded[g]) return false;
  return true;
}

function equal(a: ArrayLike<number>, b: ArrayLike<number>): boolean {
  if (a.length !== b.length) return false;
  for (let i = 0; i < a.length; i++) if (a[i] !== b[i]) return false;
  return true;
}

/** Area-weighted vertex normals: each face's unnormalized cross product added to its corners. */
export function vertexNormals(pos: Float32Array, idx: Uint32Array): Float32Array {
  const nrm = new Float32Array(pos.length);
  for (let t = 0; t < idx.length; t += 3) {
    const a = 3 * idx[t], b = 3 * idx[t + 1], c = 3 * idx[t + 2];
    const e1x = pos[b] - pos[a], e1y = pos[b + 1] - pos[a + 1], e1z = pos[b + 2] - pos[a + 2];
    const e2x = pos[c] - pos[a], e2y = pos[c + 1] - pos[a + 1], e2z = pos[c + 2] - pos[a + 2];
    const nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
    nrm[a] += nx; nrm[a + 1] += ny; nrm[a + 2] += nz;
    nrm[b] += nx; nrm[b + 1] += ny; nrm[b + 2] += nz;
    nrm[c] += nx; nrm[c + 1] += ny; nrm[c + 2] += nz;
  }
  for (let i = 0; i < nrm.length; i += 3) {
    const l = Math.hypot(nrm[i], nrm[i + 1], nrm[i + 2]);
    if (l > 0) { nrm[i] /= l; nrm[i + 1] /= l; nrm[i + 2] /= l; }
  }
  return nrm;
}

/** Per-vertex colours: the hierarchy level of each vertex's node, or its split priority. */
function colourOf(mode: ColourMode, nodes: Uint32Array, r: Decoder["replay"], errors: Float64Array): Float32Array {
  const out = new Float32Array(nodes.length * 3);
  let maxErr = 1e-12;
  if (mode === "error") for (const g of nodes) maxErr = Math.max(maxErr, errors[g]);
  for (let i = 0; i < nodes.length; i++) {
    const g = nodes[i];
    const k = mode === "error" ? errors[g] / maxErr : r.levelOf(g) / Math.max(1, r.top);
    hsl(0.66 * (1 - k), 0.75, 0.55, out, 3 * i);
  }
  return out;
}

/** HSL to linear-free RGB (as three.js's Color.setHSL before colour management). */
function hsl(h: number, s: number, l: number, out: Float32Array, at: number): void {
  const q = l <= 0.5 ? l * (1 + s) : l + s - l * s, p = 2 * l - q;
  const f = (t: number) => {
    if (t < 0) t += 1;
    if (t > 1) t -= 1;
    if (t < 1 / 6) return p + (q - p) * 6 * t;
    if (t < 1 / 2) return q;
    if (t < 2 / 3) return p + (q - p) * 6 * (2 / 3 - t);
    return p;
  };
  out[at] = f(h + 1 / 3); out[at + 1] = f(h); out[at + 2] = f(h - 1 / 3);
}
