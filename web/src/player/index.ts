// pmcodec-three: streams pmcodec containers (.pmc) into a three.js scene. The player is an
// Object3D holding one mesh; fetching (HTTP range requests only), decoding and cutting run in a
// Web Worker, which hands over render-ready buffers by transfer, so the page's thread only
// copies them into the mesh's GPU buffers.

import * as THREE from "three";
import { buildMaterials, buildTextures, decodeImages } from "./appearance.js";
import type { ColourMode, FramePayload, FromWorker, LooksPayload, MaterialGroup, OpenedInfo, SkinFrame, Source, ToWorker } from "./protocol.js";
import { OFFSET, PaletteSkeleton, START_BIND, START_OFFSET, paletteMesh, patchMaterial } from "./skinning.js";

export type { ColourMode, MaterialGroup, OpenedInfo as PmcInfo, Source as PmcSource } from "./protocol.js";
export { DEFAULT_CACHE_BYTES } from "./ranges.js";
export { ALPHA_BLEND, ALPHA_MASK, ALPHA_OPAQUE, buildMaterials, buildTextures, decodeImages, roomEnvironment } from "./appearance.js";
export type { BuildOptions, EncodedImage, Material, Materials, TextureRef } from "./appearance.js";

/** The container format version this package reads (and the oldest it still reads: 3). */
export const FORMAT_VERSION = 7;

export interface PmcPlayerOptions {
  /** Triangles to draw (default: all); the player fetches only the bands this needs. */
  budget?: number;
  /** Start playing when loaded (default true). */
  autoplay?: boolean;
  /** Loop (default true); otherwise playback stops on the last frame. */
  loop?: boolean;
  /** Playback speed (default 1). */
  speed?: number;
  /**
   * The mesh's material when it does not draw the stream's own materials (colour modes other
   * than "authored", or a stream without appearance); default: a MeshStandardMaterial.
   * Vertex normals are always set.
   */
  material?: THREE.Material;
  /** How the mesh is coloured (default "authored": the stream's materials and textures). */
  colourMode?: ColourMode;
  /** Memory limit of the worker's byte cache (default 64 MiB). */
  cacheBytes?: number;
  /** Frames whose bytes are fetched ahead of the one being decoded (default 8). */
  readAhead?: number;
  /** Extra request headers (e.g. Authorization for a server with a read token). */
  headers?: Record<string, string>;
  /** Length of the geomorph when the budget changes (ms, default 250; 0: none). */
  morphMs?: number;
  /** Where the worker script is, when a bundler does not resolve `new URL("./worker.js", import.meta.url)`. */
  workerUrl?: string | URL;
  /**
   * Skinned streams: skin on the GPU (default true). The mesh is then a THREE.SkinnedMesh whose
   * skeleton's matrices are the stream's palette, the worker decodes residuals and swaps only,
   * and frames carry the palette and the offsets that changed; normals are the bind pose's,
   * skinned with the positions. False: the worker poses every vertex, as for other streams.
   */
  gpuSkin?: boolean;
}

export interface PmcFrameEvent { frame: number; triangles: number; level: number; budget: number }
export interface PmcProgressEvent { bytes: number; requests: number; cached: number; total: number }

export interface PmcPlayerEventMap extends THREE.Object3DEventMap {
  load: { info: OpenedInfo };
  /** The stream's materials are built (their images decoded): "authored" frames draw with them. */
  materials: { materials: THREE.Material[] };
  frame: PmcFrameEvent;
  progress: PmcProgressEvent;
  error: { error: Error };
}

/** What the player did: the last frame's worker timings and the page thread's share. */
export interface PmcStats {
  frame: number; triangles: number; level: number; decodeMs: number; cutMs: number;
  /** The budget the frame shown was cut at, and the level that budget asks for (the frame's
   * `level` above it: a coarse stand-in while the budget's decoder catches up). */
  budget: number; budgetLevel: number;
  fetched: number; requests: number; cached: number;
  /** Frames put on screen, and the page thread's milliseconds spent on them in total. */
  shown: number; mainMs: number;
  /** Times playback waited for a frame the worker had not delivered yet. */
  stalls: number;
  /** The worker's milliseconds (decode, fetch waits included, and cut) for the frames shown, in total. */
  workerMs: number;
}

export class PmcPlayer extends THREE.Object3D<PmcPlayerEventMap> {
  /** The mesh drawn: a THREE.SkinnedMesh once a skinned stream opens with gpuSkin. */
  mesh: THREE.Mesh;
  readonly geometry = new THREE.BufferGeometry();
  /** Resolves when the container is open (its header and index read). */
  readonly ready: Promise<OpenedInfo>;
  info: OpenedInfo | null = null;
  readonly stats: PmcStats = { frame: -1, triangles: 0, level: -1, budget: 0, budgetLevel: -1, decodeMs: 0, cutMs: 0, fetched: 0, requests: 0, cached: 0, shown: 0, mainMs: 0, stalls: 0, workerMs: 0 };
  loop: boolean;
  speed: number;
  morphMs: number;

  private worker: Worker;
  private queue = new Map<number, FramePayload>();
  private seq = 0;
  private current = -1;
  private target = 0;
  private isPlaying: boolean;
  private due = 0;
  private triangleBudget: number;
  private mode: ColourMode;
  private morph: { from: Float32Array; to: Float32Array; uv: [Float32Array, Float32Array][]; start: number; id: number } | null = null;
  /** The material drawn without the stream's own (options.material or the default), and whether it is ours. */
  private readonly flat: THREE.Material;
  private readonly ownsFlat: boolean;
  /** The stream's materials, once its looks arrived and its images decoded. */
  private authored: THREE.Material[] | null = null;
  /** The material groups of the frame shown (an "authored" frame), or null. */
  private groups: MaterialGroup[] | null = null;
  private wire = false;
  private morphClock = { id: -1, start: 0 };
  private disposed = false;
  private indexes = new Map<number, Uint32Array>();
  private uploadedIndex = -1;
  /** GPU skinning: the skeleton, the cut's skins and offsets by version, what is uploaded, the geomorph. */
  private skeleton: PaletteSkeleton | null = null;
  private skins = new Map<number, SkinFrame>();
  private offsetVersions = new Map<number, Float32Array>();
  private uploadedSkin = -1;
  private uploadedOffsets = -1;
  private readonly morphBlend = { value: 1 };
  private skinMorph: { start: number } | null = null;

  constructor(source: Source, options: PmcPlayerOptions = {}) {
    super();
    this.loop = options.loop ?? true;
    this.speed = options.speed ?? 1;
    this.morphMs = options.morphMs ?? 250;
    this.isPlaying = options.autoplay ?? true;
    this.triangleBudget = options.budget ?? Infinity;
    this.flat = options.material ?? new THREE.MeshStandardMaterial({ color: 0xc8b89a, roughness: 0.7, side: THREE.DoubleSide });
    this.ownsFlat = !options.material;
    this.mode = options.colourMode ?? "authored";
    this.mesh = new THREE.Mesh(this.geometry, this.flat);
    this.add(this.mesh);
    this.worker = options.workerUrl
      ? new Worker(options.workerUrl, { type: "module" })
      : new Worker(new URL("./worker.js", import.meta.url), { type: "module" });
    let opened!: (i: OpenedInfo) => void, failed!: (e: Error) => void;
    this.ready = new Promise((res, rej) => { opened = res; failed = rej; });
    // Nobody may await `ready`: the error event carries it too.
    this.ready.catch(() => {});
    this.worker.onmessage = (ev: MessageEvent<FromWorker>) => {
      const t0 = performance.now();
      const m = ev.data;
      if (m.type === "opened") {
        this.setUp(m.info);
        opened(m.info);
        this.dispatchEvent({ type: "load", info: m.info });
      } else if (m.type === "looks") {
        this.takeLooks(m);
      } else if (m.type === "error") {
        const error = new Error(m.message);
        if (!this.info) failed(error);
        this.dispatchEvent({ type: "error", error });
      } else {
        // Index buffers are sent only when they change: keep each (even a dropped frame's) until
        // a frame that uses it is shown.
        if (m.indices) {
          this.indexes.set(m.indexVersion, m.indices);
          for (const v of this.indexes.keys()) if (this.indexes.size > 16) this.indexes.delete(v);
        }
        if (m.skin) this.keepSkin(m.skin);
        if (m.seq === this.seq) this.queue.set(m.frame, m);
      }
      this.stats.mainMs += performance.now() - t0;
    };
    this.worker.onerror = (ev) => {
      const error = new Error(`pmcodec worker: ${ev.message || "failed to start"}`);
      if (!this.info) failed(error);
      this.dispatchEvent({ type: "error", error });
    };
    this.send({ type: "open", source, cacheBytes: options.cacheBytes, readAhead: options.readAhead, headers: options.headers, gpuSkin: options.gpuSkin ?? true });
    this.send({ type: "colour", mode: this.mode });
    this.applyMaterial();
    if (Number.isFinite(this.triangleBudget)) this.send({ type: "budget", triangles: this.triangleBudget });
  }

  /** Opens asset `asset` of a pmcodec server (`server`: its base URL, e.g. "https://host/"). */
  static fromServer(server: string, asset: string, options?: PmcPlayerOptions): PmcPlayer {
    return new PmcPlayer({ server, asset }, options);
  }

  /** Opens a .pmc file on any host that answers range requests (a static server, a CDN). */
  static fromUrl(url: string, options?: PmcPlayerOptions): PmcPlayer {
    return new PmcPlayer({ url }, options);
  }

  private send(m: ToWorker): void { if (!this.disposed) this.worker.postMessage(m); }

  private setUp(info: OpenedInfo): void {
    this.info = info;
    const g = this.geometry;
    // Buffers for the finest cut, reused for every frame: three.js redraws a wireframe only when
    // the index attribute's version rises, which a fresh attribute per frame never does.
    // With appearance a cut node is a vertex per chart and smoothing group it touches: at most
    // one per triangle corner.
    const capacity = info.appearance ? 3 * info.triangles : info.vertices;
    const pos = new THREE.BufferAttribute(new Float32Array(3 * capacity), 3).setUsage(THREE.DynamicDrawUsage);
    const nrm = new THREE.BufferAttribute(new Float32Array(3 * capacity), 3).setUsage(THREE.DynamicDrawUsage);
    const idx = new THREE.BufferAttribute(new Uint32Array(3 * info.triangles), 1).setUsage(THREE.DynamicDrawUsage);
    g.setAttribute("position", pos);
    g.setAttribute("normal", nrm);
    g.setIndex(idx);
    g.setDrawRange(0, 0);
    // Bounds of the whole animation (the container's quantization box), so culling and framing
    // hold in every frame.
    const box = new THREE.Box3(new THREE.Vector3().fromArray(info.bboxMin), new THREE.Vector3().fromArray(info.bboxMax));
    g.boundingBox = box;
    g.boundingSphere = box.getBoundingSphere(new THREE.Sphere());
    if (info.gpuSkinJoints > 0) {
      // Three.js skins with skinIndex and skinWeight; the patched shader adds offsets and morphs.
      g.setAttribute("skinIndex", new THREE.BufferAttribute(new Uint16Array(4 * capacity), 4).setUsage(THREE.DynamicDrawUsage));
      g.setAttribute("skinWeight", new THREE.BufferAttribute(new Float32Array(4 * capacity), 4).setUsage(THREE.DynamicDrawUsage));
      for (const name of [OFFSET, START_BIND, START_OFFSET]) g.setAttribute(name, new THREE.BufferAttribute(new Float32Array(3 * capacity), 3).setUsage(THREE.DynamicDrawUsage));
      this.skeleton = new PaletteSkeleton(info.gpuSkinJoints);
      const mesh = paletteMesh(g, this.mesh.material, this.skeleton);
      this.remove(this.mesh);
      this.mesh = mesh;
      this.add(mesh);
      this.applyMaterial();
    }
    if (!Number.isFinite(this.triangleBudget)) this.triangleBudget = info.triangles;
    this.target = Math.min(this.target, info.frames - 1);
    this.seq++;
    this.send({ type: "seek", frame: this.target, seq: this.seq, coarse: true });
    this.send({ type: "playhead", frame: this.target, playing: this.isPlaying });
  }

  /** The whole animation's bounds, in the player's space (null before load). */
  get boundingBox(): THREE.Box3 | null { return this.geometry.boundingBox; }
  get frame(): number { return this.current; }
  get frameCount(): number { return this.info?.frames ?? 0; }
  get playing(): boolean { return this.isPlaying; }

  play(): void {
    if (this.isPlaying) return;
    this.isPlaying = true;
    this.due = 0;
    this.send({ type: "playhead", frame: Math.max(0, this.current), playing: true });
  }

  pause(): void {
    if (!this.isPlaying) return;
    this.isPlaying = false;
    // Frames decoded ahead are dropped: the worker keeps its decoder at the frame shown.
    this.jump(Math.max(0, this.current), false);
  }

  /**
   * Shows frame f as soon as the worker has it (decoded from the keyframe before it; what is
   * already fetched is not fetched again), then plays on from there if playing.
   */
  seek(f: number): void { this.jump(f, true); }

  private jump(f: number, coarse: boolean): void {
    const n = this.frameCount;
    this.target = n ? Math.min(Math.max(0, Math.floor(f)), n - 1) : Math.max(0, Math.floor(f));
    this.seq++;
    this.queue.clear();
    this.due = 0;
    this.send({ type: "seek", frame: this.target, seq: this.seq, coarse });
    this.send({ type: "playhead", frame: this.target, playing: this.isPlaying });
  }

  /** Triangles drawn; lowering it stops the fetching of finer bands from the next keyframe. */
  get budget(): number { return this.triangleBudget; }
  set budget(triangles: number) {
    const t = Math.max(1, Math.floor(triangles));
    if (t === this.triangleBudget) return;
    this.triangleBudget = t;
    this.send({ type: "budget", triangles: t });
  }

  /**
   * The stream's materials and textures ("authored"; a stream without appearance draws as
   * "plain"), one flat material ("plain"), or vertex colours by the hierarchy level of each
   * vertex's node ("level") or by its split priority ("error").
   */
  get colourMode(): ColourMode { return this.mode; }
  set colourMode(mode: ColourMode) {
    if (mode === this.mode) return;
    this.mode = mode;
    this.applyMaterial();
    this.send({ type: "colour", mode });
  }

  /** The stream's materials (after the `materials` event), or null. */
  get materials(): THREE.Material[] | null { return this.authored; }

  /** Draws every material as a wireframe. */
  get wireframe(): boolean { return this.wire; }
  set wireframe(on: boolean) {
    this.wire = on;
    for (const m of [this.flat, ...(this.authored ?? [])]) if ("wireframe" in m) (m as THREE.MeshStandardMaterial).wireframe = on;
  }

  /** Builds the stream's materials from the worker's looks (images decoded on the page). */
  private takeLooks(m: LooksPayload): void {
    decodeImages(m.images).then((bitmaps) => {
      if (this.disposed) { for (const b of bitmaps) b?.close(); return; }
      const textures = buildTextures(m.materials, bitmaps);
      this.authored = buildMaterials(m.materials, textures, { vertexColors: m.vertexColors, flatShading: !m.normals });
      // The clones in the materials hold the images; the shared textures are not used.
      for (const t of textures) t?.dispose();
      this.wireframe = this.wire;
      this.applyMaterial();
      this.dispatchEvent({ type: "materials", materials: this.authored });
    }, (e) => this.dispatchEvent({ type: "error", error: e instanceof Error ? e : new Error(String(e)) }));
  }

  /**
   * The stream's materials, one per group, when the frame shown carries them ("authored" on a
   * stream with appearance, its materials built); else the flat material, with vertex colours
   * in "level" and "error" modes.
   */
  private applyMaterial(): void {
    const g = this.geometry;
    g.clearGroups();
    if (this.mode === "authored" && this.authored && this.groups) {
      for (const x of this.groups) g.addGroup(x.start, x.count, Math.min(x.material, this.authored.length - 1));
      if (this.skeleton) for (const m of this.authored) patchMaterial(m, this.morphBlend);
      this.mesh.material = this.authored;
      return;
    }
    if (this.skeleton) patchMaterial(this.flat, this.morphBlend);
    this.mesh.material = this.flat;
    const f = this.flat as THREE.Material & { vertexColors?: boolean };
    const colours = this.mode === "level" || this.mode === "error";
    if (f.vertexColors !== colours) { f.vertexColors = colours; f.needsUpdate = true; }
  }

  /**
   * Advances playback to `now` (ms, as performance.now) and puts the frame due on the mesh.
   * Call it once per animation frame, before rendering. True when the mesh changed.
   */
  update(now = performance.now()): boolean {
    if (!this.info || this.disposed) return false;
    const t0 = performance.now();
    let changed = false;
    const n = this.info.frames;
    // The frame asked for by a seek (or a new cut of the frame shown, after a budget change).
    const again = this.queue.get(this.current < 0 ? this.target : this.current);
    if (again && (this.current < 0 || again.frame === this.current)) {
      this.queue.delete(again.frame);
      this.show(again, now);
      changed = true;
      if (this.due === 0) this.due = now + this.period();
    } else if (this.current < 0 || this.current !== this.target) {
      const p = this.queue.get(this.target);
      if (p) { this.queue.delete(p.frame); this.show(p, now); changed = true; this.due = now + this.period(); }
    }
    if (this.isPlaying && this.current >= 0 && now >= this.due) {
      const nextFrame = (this.current + 1) % n;
      const p = this.queue.get(nextFrame);
      if (this.current === n - 1 && !this.loop) {
        this.pause();
      } else if (p) {
        this.queue.delete(nextFrame);
        this.show(p, now);
        changed = true;
        // Keep the frame rate's pace; after a stall longer than a frame, restart it from now.
        this.due = this.due > 0 && now - this.due < this.period() ? this.due + this.period() : now + this.period();
      } else {
        this.stats.stalls++;
      }
    }
    if (this.skinMorph) {
      const a = this.morphMs > 0 ? Math.min(1, (now - this.skinMorph.start) / this.morphMs) : 1;
      this.morphBlend.value = a * a * (3 - 2 * a);
      if (a >= 1) this.skinMorph = null;
      changed = true;
    }
    if (this.morph) {
      const a = this.morphMs > 0 ? Math.min(1, (now - this.morph.start) / this.morphMs) : 1;
      if (this.morph.to.length > 0) blendInto(this.morph.from, this.morph.to, a, this.geometry.getAttribute("position") as THREE.BufferAttribute);
      this.morph.uv.forEach(([from, to], k) => blendInto(from, to, a, this.geometry.getAttribute(k === 0 ? "uv" : "uv1") as THREE.BufferAttribute));
      if (a >= 1) this.morph = null;
      changed = true;
    }
    const dt = performance.now() - t0;
    this.stats.mainMs += dt;
    return changed;
  }

  private period(): number { return 1000 / ((this.info?.frameRate || 30) * (this.speed > 0 ? this.speed : 1)); }

  private show(p: FramePayload, now: number): void {
    const g = this.geometry;
    const pos = g.getAttribute("position") as THREE.BufferAttribute;
    const nrm = g.getAttribute("normal") as THREE.BufferAttribute;
    const idx = g.index as THREE.BufferAttribute;
    if (p.skin) this.showSkin(p, p.skin, now);
    if (p.skin && !(p.uvStarts && this.morphMs > 0)) {
      this.morph = null;
      this.setVertexAttribute("uv", 2, p.uvs);
      this.setVertexAttribute("uv1", 2, p.uv1);
    } else if ((p.starts || (p.skin && p.uvStarts)) && this.morphMs > 0) {
      // The same morph carried on to a new frame keeps its clock (even once it has ended).
      const start = this.morphClock.id === p.morphId ? this.morphClock.start : now;
      this.morphClock = { id: p.morphId, start };
      const a = Math.min(1, (now - start) / this.morphMs);
      const uv: [Float32Array, Float32Array][] = [];
      if (p.uvs && p.uvStarts) uv.push([p.uvStarts, p.uvs]);
      if (p.uvs && p.uvStarts && p.uv1 && p.uv1Starts) uv.push([p.uv1Starts, p.uv1]);
      // GPU skinning morphs positions in the shader (showSkin); only texture coordinates here.
      const from = p.starts ?? new Float32Array(0);
      this.morph = a < 1 ? { from, to: p.positions, uv, start, id: p.morphId } : null;
      if (p.starts) blendInto(p.starts, p.positions, a, pos);
      this.setVertexAttribute("uv", 2, p.uvs);
      this.setVertexAttribute("uv1", 2, p.uv1);
      uv.forEach(([from, to], k) => blendInto(from, to, a, g.getAttribute(k === 0 ? "uv" : "uv1") as THREE.BufferAttribute));
    } else {
      this.morph = null;
      upload(pos, p.positions);
      this.setVertexAttribute("uv", 2, p.uvs);
      this.setVertexAttribute("uv1", 2, p.uv1);
    }
    if (!p.skin) upload(nrm, p.normals);
    if (p.indexVersion !== this.uploadedIndex) {
      const indices = this.indexes.get(p.indexVersion);
      if (indices) {
        upload(idx, indices);
        this.uploadedIndex = p.indexVersion;
      } else {
        this.dispatchEvent({ type: "error", error: new Error(`pmcodec: the triangles of frame ${p.frame} (index version ${p.indexVersion}) never arrived`) });
      }
      for (const v of this.indexes.keys()) if (v < p.indexVersion) this.indexes.delete(v);
    }
    // Authored vertex colours are RGBA (glTF's COLOR_0), the level and error colours RGB.
    this.setVertexAttribute("color", p.uvs || p.groups ? 4 : 3, p.colours);
    g.setDrawRange(0, p.indexCount);
    const groups = p.groups ?? null;
    if (groups !== this.groups) { this.groups = groups; this.applyMaterial(); }
    const progressed = p.fetched !== this.stats.fetched;
    Object.assign(this.stats, { frame: p.frame, triangles: p.triangles, level: p.level, budget: p.budget, budgetLevel: p.budgetLevel, decodeMs: p.decodeMs, cutMs: p.cutMs, fetched: p.fetched, requests: p.requests, cached: p.cached });
    this.stats.shown++;
    this.stats.workerMs += p.decodeMs + p.cutMs;
    this.current = p.frame;
    this.target = p.frame;
    this.send({ type: "playhead", frame: p.frame, playing: this.isPlaying });
    this.dispatchEvent({ type: "frame", frame: p.frame, triangles: p.triangles, level: p.level, budget: p.budget });
    if (progressed && this.info) this.dispatchEvent({ type: "progress", bytes: p.fetched, requests: p.requests, cached: p.cached, total: this.info.bytes });
  }

  /**
   * Keeps a GPU-skinned frame's versioned data as it arrives (in the order the worker made it,
   * which offsets given as changes rely on), whether or not the frame is shown.
   */
  private keepSkin(k: SkinFrame): void {
    if (k.bind) {
      this.skins.set(k.version, k);
      for (const v of this.skins.keys()) if (this.skins.size > 16) this.skins.delete(v);
    }
    let o: Float32Array | null = null;
    if (k.offsets) o = k.offsets;
    else if (k.changed && k.values) {
      const base = this.offsetVersions.get(k.offsetsVersion - 1);
      if (!base) { this.dispatchEvent({ type: "error", error: new Error(`pmcodec: offsets version ${k.offsetsVersion - 1} never arrived`) }); return; }
      o = base.slice();
      const c = k.changed, vals = k.values;
      for (let i = 0; i < c.length; i++) { o[3 * c[i]] = vals[3 * i]; o[3 * c[i] + 1] = vals[3 * i + 1]; o[3 * c[i] + 2] = vals[3 * i + 2]; }
    }
    if (o) {
      this.offsetVersions.set(k.offsetsVersion, o);
      for (const v of this.offsetVersions.keys()) if (this.offsetVersions.size > 16) this.offsetVersions.delete(v);
    }
  }

  /** Puts a GPU-skinned frame on the mesh: the cut's skin when it changed, palette, offsets, geomorph. */
  private showSkin(p: FramePayload, k: SkinFrame, now: number): void {
    const g = this.geometry;
    if (k.version !== this.uploadedSkin) {
      const s = this.skins.get(k.version);
      if (!s || !s.bind || !s.joints || !s.weights || !s.normals) {
        this.dispatchEvent({ type: "error", error: new Error(`pmcodec: the skin of frame ${p.frame} (version ${k.version}) never arrived`) });
        return;
      }
      upload(g.getAttribute("position") as THREE.BufferAttribute, s.bind);
      upload(g.getAttribute("normal") as THREE.BufferAttribute, s.normals);
      upload(g.getAttribute("skinIndex") as THREE.BufferAttribute, s.joints);
      upload(g.getAttribute("skinWeight") as THREE.BufferAttribute, s.weights);
      this.uploadedSkin = k.version;
      for (const v of this.skins.keys()) if (v < k.version) this.skins.delete(v);
    }
    this.skeleton?.setPalette(k.palette);
    if (k.offsetsVersion !== this.uploadedOffsets) {
      const o = this.offsetVersions.get(k.offsetsVersion);
      if (o) { upload(g.getAttribute(OFFSET) as THREE.BufferAttribute, o); this.uploadedOffsets = k.offsetsVersion; }
      else this.dispatchEvent({ type: "error", error: new Error(`pmcodec: the offsets of frame ${p.frame} (version ${k.offsetsVersion}) never arrived`) });
      for (const v of this.offsetVersions.keys()) if (v < k.offsetsVersion) this.offsetVersions.delete(v);
    }
    if (k.startBind && k.startOffsets && this.morphMs > 0) {
      // The same morph carried on to a new frame keeps its clock (even once it has ended).
      const start = this.morphClock.id === p.morphId ? this.morphClock.start : now;
      this.morphClock = { id: p.morphId, start };
      const a = Math.min(1, (now - start) / this.morphMs);
      upload(g.getAttribute(START_BIND) as THREE.BufferAttribute, k.startBind);
      upload(g.getAttribute(START_OFFSET) as THREE.BufferAttribute, k.startOffsets);
      this.morphBlend.value = a * a * (3 - 2 * a);
      this.skinMorph = a < 1 ? { start } : null;
    } else {
      this.morphBlend.value = 1;
      this.skinMorph = null;
    }
  }

  /**
   * Puts `values` (`size` floats per vertex) in the geometry's attribute `name`, made (once, as
   * large as the position buffer) when missing or of another size; removes it when absent.
   */
  private setVertexAttribute(name: string, size: number, values: Float32Array | undefined): void {
    const g = this.geometry;
    let attr = g.getAttribute(name) as THREE.BufferAttribute | undefined;
    if (!values) { if (attr) g.deleteAttribute(name); return; }
    const vertices = (g.getAttribute("position") as THREE.BufferAttribute).count;
    if (!attr || attr.itemSize !== size || attr.count < values.length / size) {
      attr = new THREE.BufferAttribute(new Float32Array(size * Math.max(vertices, values.length / size)), size).setUsage(THREE.DynamicDrawUsage);
      g.setAttribute(name, attr);
    }
    upload(attr, values);
  }

  /** Stops the worker and frees the GPU buffers (and the material, unless it was given). */
  dispose(): void {
    if (this.disposed) return;
    this.disposed = true;
    this.worker.terminate();
    this.queue.clear();
    this.geometry.dispose();
    this.skeleton?.dispose();
    if (this.ownsFlat) this.flat.dispose();
    for (const m of this.authored ?? []) {
      const s = m as THREE.MeshStandardMaterial;
      for (const t of [s.map, s.metalnessMap, s.normalMap, s.aoMap, s.emissiveMap]) t?.dispose();
      m.dispose();
    }
    this.removeFromParent();
  }
}

/** Copies `src` into the start of the attribute and marks only that part for upload. */
function upload(attr: THREE.BufferAttribute, src: ArrayLike<number>): void {
  (attr.array as Float32Array | Uint32Array).set(src as ArrayLike<number>);
  attr.clearUpdateRanges();
  attr.addUpdateRange(0, src.length);
  attr.needsUpdate = true;
}

/** Smoothstep blend of two position arrays into the attribute (no velocity jump at either end). */
function blendInto(from: Float32Array, to: Float32Array, alpha: number, attr: THREE.BufferAttribute): void {
  const s = alpha * alpha * (3 - 2 * alpha), out = attr.array as Float32Array;
  for (let i = 0; i < to.length; i++) out[i] = from[i] + (to[i] - from[i]) * s;
  attr.clearUpdateRanges();
  attr.addUpdateRange(0, to.length);
  attr.needsUpdate = true;
}
