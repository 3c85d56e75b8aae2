// pmcodec-three: streams pmcodec containers (.pmc) into a three.js scene. The player is an
// Object3D holding one mesh; fetching (HTTP range requests only), decoding and cutting run in a
// Web Worker, which hands over render-ready buffers by transfer, so the page's thread only
// copies them into the mesh's GPU buffers.

import * as THREE from "three";
import type { ColourMode, FramePayload, FromWorker, OpenedInfo, Source, ToWorker } from "./protocol.js";

export type { ColourMode, OpenedInfo as PmcInfo, Source as PmcSource } from "./protocol.js";
export { DEFAULT_CACHE_BYTES } from "./ranges.js";

/** The container format version this package reads (and the oldest it still reads: 3). */
export const FORMAT_VERSION = 6;

export interface PmcPlayerOptions {
  /** Triangles to draw (default: all); the player fetches only the bands this needs. */
  budget?: number;
  /** Start playing when loaded (default true). */
  autoplay?: boolean;
  /** Loop (default true); otherwise playback stops on the last frame. */
  loop?: boolean;
  /** Playback speed (default 1). */
  speed?: number;
  /** The mesh's material (default: a MeshStandardMaterial). Vertex normals are always set. */
  material?: THREE.Material;
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
}

export interface PmcFrameEvent { frame: number; triangles: number; level: number; budget: number }
export interface PmcProgressEvent { bytes: number; requests: number; cached: number; total: number }

export interface PmcPlayerEventMap extends THREE.Object3DEventMap {
  load: { info: OpenedInfo };
  frame: PmcFrameEvent;
  progress: PmcProgressEvent;
  error: { error: Error };
}

/** What the player did: the last frame's worker timings and the page thread's share. */
export interface PmcStats {
  frame: number; triangles: number; level: number; decodeMs: number; cutMs: number;
  fetched: number; requests: number; cached: number;
  /** Frames put on screen, and the page thread's milliseconds spent on them in total. */
  shown: number; mainMs: number;
  /** Times playback waited for a frame the worker had not delivered yet. */
  stalls: number;
}

export class PmcPlayer extends THREE.Object3D<PmcPlayerEventMap> {
  readonly mesh: THREE.Mesh;
  readonly geometry = new THREE.BufferGeometry();
  /** Resolves when the container is open (its header and index read). */
  readonly ready: Promise<OpenedInfo>;
  info: OpenedInfo | null = null;
  readonly stats: PmcStats = { frame: -1, triangles: 0, level: -1, decodeMs: 0, cutMs: 0, fetched: 0, requests: 0, cached: 0, shown: 0, mainMs: 0, stalls: 0 };
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
  private mode: ColourMode = "plain";
  private morph: { from: Float32Array; to: Float32Array; start: number; id: number } | null = null;
  private morphClock = { id: -1, start: 0 };
  private disposed = false;
  private indexes = new Map<number, Uint32Array>();
  private uploadedIndex = -1;

  constructor(source: Source, options: PmcPlayerOptions = {}) {
    super();
    this.loop = options.loop ?? true;
    this.speed = options.speed ?? 1;
    this.morphMs = options.morphMs ?? 250;
    this.isPlaying = options.autoplay ?? true;
    this.triangleBudget = options.budget ?? Infinity;
    const material = options.material ?? new THREE.MeshStandardMaterial({ color: 0xc8b89a, roughness: 0.7, side: THREE.DoubleSide });
    this.mesh = new THREE.Mesh(this.geometry, material);
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
        if (m.seq === this.seq) this.queue.set(m.frame, m);
      }
      this.stats.mainMs += performance.now() - t0;
    };
    this.worker.onerror = (ev) => {
      const error = new Error(`pmcodec worker: ${ev.message || "failed to start"}`);
      if (!this.info) failed(error);
      this.dispatchEvent({ type: "error", error });
    };
    this.send({ type: "open", source, cacheBytes: options.cacheBytes, readAhead: options.readAhead, headers: options.headers });
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
    const pos = new THREE.BufferAttribute(new Float32Array(3 * info.vertices), 3).setUsage(THREE.DynamicDrawUsage);
    const nrm = new THREE.BufferAttribute(new Float32Array(3 * info.vertices), 3).setUsage(THREE.DynamicDrawUsage);
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

  /** Vertex colours: none, the hierarchy level of each vertex's node, or its split priority. */
  get colourMode(): ColourMode { return this.mode; }
  set colourMode(mode: ColourMode) {
    this.mode = mode;
    const m = this.mesh.material as THREE.Material & { vertexColors?: boolean };
    m.vertexColors = mode !== "plain";
    m.needsUpdate = true;
    this.send({ type: "colour", mode });
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
    if (this.morph) {
      const a = this.morphMs > 0 ? Math.min(1, (now - this.morph.start) / this.morphMs) : 1;
      blendInto(this.morph.from, this.morph.to, a, this.geometry.getAttribute("position") as THREE.BufferAttribute);
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
    if (p.starts && this.morphMs > 0) {
      // The same morph carried on to a new frame keeps its clock (even once it has ended).
      const start = this.morphClock.id === p.morphId ? this.morphClock.start : now;
      this.morphClock = { id: p.morphId, start };
      const a = Math.min(1, (now - start) / this.morphMs);
      this.morph = a < 1 ? { from: p.starts, to: p.positions, start, id: p.morphId } : null;
      blendInto(p.starts, p.positions, a, pos);
    } else {
      this.morph = null;
      upload(pos, p.positions);
    }
    upload(nrm, p.normals);
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
    if (p.colours) {
      let col = g.getAttribute("color") as THREE.BufferAttribute | undefined;
      if (!col || col.array.length < p.colours.length) {
        col = new THREE.BufferAttribute(new Float32Array((pos.array as Float32Array).length), 3).setUsage(THREE.DynamicDrawUsage);
        g.setAttribute("color", col);
      }
      upload(col, p.colours);
    } else if (g.getAttribute("color")) g.deleteAttribute("color");
    g.setDrawRange(0, p.indexCount);
    const progressed = p.fetched !== this.stats.fetched;
    Object.assign(this.stats, { frame: p.frame, triangles: p.triangles, level: p.level, decodeMs: p.decodeMs, cutMs: p.cutMs, fetched: p.fetched, requests: p.requests, cached: p.cached });
    this.stats.shown++;
    this.current = p.frame;
    this.target = p.frame;
    this.send({ type: "playhead", frame: p.frame, playing: this.isPlaying });
    this.dispatchEvent({ type: "frame", frame: p.frame, triangles: p.triangles, level: p.level, budget: p.budget });
    if (progressed && this.info) this.dispatchEvent({ type: "progress", bytes: p.fetched, requests: p.requests, cached: p.cached, total: this.info.bytes });
  }

  /** Stops the worker and frees the GPU buffers (and the material, unless it was given). */
  dispose(): void {
    if (this.disposed) return;
    this.disposed = true;
    this.worker.terminate();
    this.queue.clear();
    this.geometry.dispose();
    (this.mesh.material as THREE.Material).dispose();
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
