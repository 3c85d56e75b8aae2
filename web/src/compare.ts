// The appearance bar of issue 16: a stream drawn by pmcodec-three (frame 0, every triangle, its
// own materials) beside its source GLB drawn by three.js's stock GLTFLoader (the first
// animation at time 0: the pose the encoder samples as frame 0), with one camera, the same
// lights and the same environment. web/test/appearance-e2e.mjs compares the two canvases.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { DRACOLoader } from "three/examples/jsm/loaders/DRACOLoader.js";
import { MeshoptSimplifier } from "meshoptimizer";
import { PmcPlayer, roomEnvironment } from "pmcodec-three";

const q = new URLSearchParams(location.search);
const size = Number(q.get("size") ?? "256");
const status = document.getElementById("status") as HTMLDivElement;

function report(fields: Record<string, string | number>): void {
  for (const k of Object.keys(status.dataset)) delete status.dataset[k];
  for (const [k, v] of Object.entries(fields)) status.dataset[k] = String(v);
  status.textContent = Object.entries(status.dataset).map(([k, v]) => `${k} ${v}`).join("\n");
}

// One renderer for every comparison: three.js compiles a material's shaders once per renderer,
// and on a software GPU that compiling is most of the page's time.
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(size, size, false);
const env = roomEnvironment(renderer, 64);

/**
 * One scene per side, lit the same way: the same environment (made once: prefiltering it is
 * the slowest step of the page on a software GPU) and the same sun.
 */
function stage(env: THREE.Texture): THREE.Scene {
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1d2026);
  scene.environment = env;
  const sun = new THREE.DirectionalLight(0xffffff, 1.5);
  sun.position.set(3, 5, 4);
  scene.add(sun);
  return scene;
}

/** Draws what the renderer shows into 2D canvas `id` (the test reads it and saves it). */
function keep(renderer: THREE.WebGLRenderer, id: string): void {
  const c = document.getElementById(id) as HTMLCanvasElement;
  c.width = size;
  c.height = size;
  c.getContext("2d")!.drawImage(renderer.domElement, 0, 0);
}

/** Compares stream `pmc` with its GLB `glb`; resolves with what #status shows. */
async function compare(pmc: string, glb: string): Promise<Record<string, string | number>> {
  const tStage = performance.now();
  const ours = stage(env), theirs = stage(env);

  // The reference: the GLB as three.js loads it, posed at the first animation's time 0.
  const loader = new GLTFLoader();
  const draco = new DRACOLoader().setDecoderPath(q.get("draco") ?? "/draco/");
  loader.setDRACOLoader(draco);
  const t0 = performance.now();
  const gltf = await loader.loadAsync(glb);
  const tGlb = performance.now();
  draco.dispose();
  const root = gltf.scene;
  theirs.add(root);
  const mixer = new THREE.AnimationMixer(root);
  const clip = gltf.animations[0];
  if (clip) mixer.clipAction(clip).play();
  mixer.setTime(0);
  root.updateMatrixWorld(true);
  // Skinned bounds are the bind pose's: never cull.
  root.traverse((o) => { o.frustumCulled = false; });

  // The camera frames the reference's posed vertices (skinning and morphs applied), cropped
  // to what it draws.
  const camera = frameCamera(root, theirs);

  // The stream: frame 0, every triangle, no geomorph, its own materials.
  const player = PmcPlayer.fromUrl(pmc, { autoplay: false, morphMs: 0 });
  let failure: Error | null = null;
  player.addEventListener("error", (e) => { failure = e.error; console.error(`player: ${e.error.message}`); });
  player.frustumCulled = false;
  ours.add(player);
  try {
    const info = await player.ready;
    player.seek(0);
    await new Promise<void>((res, rej) => {
      const tick = (): void => {
        if (failure) { rej(failure); return; }
        player.update(performance.now());
        const drawn = player.stats.frame === 0 && player.stats.triangles === info.triangles;
        if (drawn && (!info.appearance || Array.isArray(player.mesh.material))) res();
        else requestAnimationFrame(tick);
      };
      tick();
    });
    const tFrame = performance.now();
    renderer.render(ours, camera);
    keep(renderer, "stream");
    renderer.render(theirs, camera);
    keep(renderer, "reference");
    const tRender = performance.now();
    // The toggle back to flat colour by level, and back again: the material and the colour
    // attribute change, and so does the picture.
    const authored = pixels(renderer, ours, camera);
    player.colourMode = "level";
    await until(player, () => !Array.isArray(player.mesh.material) && player.geometry.getAttribute("color")?.itemSize === 3 && !player.geometry.getAttribute("uv"));
    const level = pixels(renderer, ours, camera);
    keep(renderer, "level");
    player.colourMode = "authored";
    await until(player, () => !info.appearance || (Array.isArray(player.mesh.material) && player.geometry.getAttribute("color")?.itemSize !== 3));
    const again = pixels(renderer, ours, camera);
    let changed = 0, back = 0;
    for (let i = 0; i < authored.length; i += 4) {
      if (Math.abs(authored[i] - level[i]) + Math.abs(authored[i + 1] - level[i + 1]) + Math.abs(authored[i + 2] - level[i + 2]) > 30) changed++;
      if (Math.abs(authored[i] - again[i]) + Math.abs(authored[i + 1] - again[i + 1]) + Math.abs(authored[i + 2] - again[i + 2]) > 3) back++;
    }
    let triangles = 0, textured = 0;
    root.traverse((o) => {
      const m = o as THREE.Mesh;
      if (!m.isMesh) return;
      const idx = m.geometry.getIndex();
      triangles += (idx ? idx.count : m.geometry.getAttribute("position").count) / 3;
      for (const mat of Array.isArray(m.material) ? m.material : [m.material]) if ((mat as THREE.MeshStandardMaterial).map) textured++;
    });
    const ourMaterials = Array.isArray(player.mesh.material) ? player.mesh.material : [player.mesh.material];
    return {
      done: 1, triangles: player.stats.triangles, referenceTriangles: triangles, frames: info.frames,
      materials: ourMaterials.length, textured: ourMaterials.filter((m) => (m as THREE.MeshStandardMaterial).map).length,
      referenceTextured: textured, appearance: info.appearance ? 1 : 0, animation: clip?.name ?? "",
      toggleChanged: changed, toggleBack: back,
      // Whether the stream was drawn skinned on the GPU (a skinned stream, PmcPlayerOptions.gpuSkin).
      gpuSkinned: (player.mesh as THREE.SkinnedMesh).isSkinnedMesh ? 1 : 0,
      ms: [t0 - tStage, tGlb - t0, tFrame - tGlb, tRender - tFrame].map((x) => x.toFixed(0)).join(" "),
    };
  } finally {
    player.dispose();
    root.traverse((o) => {
      const m = o as THREE.Mesh;
      if (!m.isMesh) return;
      m.geometry.dispose();
      for (const mat of Array.isArray(m.material) ? m.material : [m.material]) mat.dispose();
    });
  }
}

/** What the renderer draws of `scene`, as RGBA bytes. */
function pixels(renderer: THREE.WebGLRenderer, scene: THREE.Scene, camera: THREE.Camera): Uint8Array {
  renderer.render(scene, camera);
  const gl = renderer.getContext(), out = new Uint8Array(size * size * 4);
  gl.readPixels(0, 0, size, size, gl.RGBA, gl.UNSIGNED_BYTE, out);
  return out;
}

/** Updates the player every animation frame until `done` holds (10 s at most). */
function until(player: PmcPlayer, done: () => boolean): Promise<void> {
  const end = performance.now() + 10_000;
  return new Promise((res, rej) => {
    const tick = (): void => {
      player.update(performance.now());
      if (done()) res();
      else if (performance.now() > end) rej(new Error("the colour mode did not change"));
      else requestAnimationFrame(tick);
    };
    tick();
  });
}

// ---- image error under simplification (issue 16) ------------------------------------------
// A stream cut to a share of its triangles beside what a user gets today without pmcodec:
// meshoptimizer's simplifyWithAttributes (Kapoulkine, meshoptimizer 1.1) applied once to the
// GLB's bind pose, each primitive to the same share, then skinned and morphed by three.js as
// authored; both against the full GLB at the same time of the same animation.

/** Loads `glb` with three.js's GLTFLoader (and its DRACOLoader). */
async function loadGlb(glb: string): Promise<{ scene: THREE.Group; animations: THREE.AnimationClip[] }> {
  const loader = new GLTFLoader();
  const draco = new DRACOLoader().setDecoderPath(q.get("draco") ?? "/draco/");
  loader.setDRACOLoader(draco);
  try {
    const gltf = await loader.loadAsync(glb);
    gltf.scene.traverse((o) => { o.frustumCulled = false; });
    return gltf;
  } finally {
    draco.dispose();
  }
}

/**
 * Every mesh of `root` simplified to `share` of its triangles in its bind pose by
 * simplifyWithAttributes, weighing normals 0.5 and texture coordinates and colours 1 (the
 * attributes a textured, lit mesh shows) and with no error limit, so the share decides; each
 * material group on its own. Returns the triangles before and after.
 */
function simplifyMeshes(root: THREE.Object3D, share: number): [number, number] {
  let before = 0, after = 0;
  root.traverse((o) => {
    const mesh = o as THREE.Mesh;
    if (!mesh.isMesh) return;
    const g = mesh.geometry;
    const pos = g.getAttribute("position");
    const n = pos.count;
    const positions = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) { positions[3 * i] = pos.getX(i); positions[3 * i + 1] = pos.getY(i); positions[3 * i + 2] = pos.getZ(i); }
    const parts: [THREE.BufferAttribute | THREE.InterleavedBufferAttribute, number, number][] = [];
    for (const [name, weight] of [["normal", 0.5], ["uv", 1], ["color", 1]] as const) {
      const a = g.getAttribute(name);
      if (a) parts.push([a, Math.min(a.itemSize, name === "color" ? 3 : a.itemSize), weight]);
    }
    const stride = Math.max(1, parts.reduce((s, [, w]) => s + w, 0));
    const attributes = new Float32Array(stride * n);
    const weights: number[] = [];
    let off = 0;
    for (const [a, width, weight] of parts) {
      for (let i = 0; i < n; i++) for (let k = 0; k < width; k++) attributes[stride * i + off + k] = a.getComponent(i, k);
      for (let k = 0; k < width; k++) weights.push(weight);
      off += width;
    }
    if (weights.length === 0) weights.push(0);
    const index = g.getIndex();
    const all = index ? Uint32Array.from(index.array as ArrayLike<number>) : Uint32Array.from({ length: n }, (_, i) => i);
    const groups = g.groups.length ? g.groups.map((x) => ({ ...x })) : [{ start: 0, count: all.length, materialIndex: 0 }];
    const out: number[] = [];
    const kept: { start: number; count: number; materialIndex?: number }[] = [];
    for (const gr of groups) {
      const src = all.subarray(gr.start, Math.min(all.length, gr.start + gr.count));
      const target = Math.max(3, Math.floor((src.length / 3) * share) * 3);
      let [simple] = MeshoptSimplifier.simplifyWithAttributes(src, positions, 3, attributes, stride, weights, null, target, 1);
      // Where attribute seams lock most vertices (faceted meshes split every vertex by its
      // face's normal), the default keeps seams whole and stops far above the target: then
      // seams may collapse too, as meshoptimizer's Permissive mode allows.
      if (simple.length > 1.2 * target) {
        [simple] = MeshoptSimplifier.simplifyWithAttributes(src, positions, 3, attributes, stride, weights, null, target, 1, ["Permissive"]);
      }
      kept.push({ start: out.length, count: simple.length, materialIndex: gr.materialIndex });
      for (const v of simple) out.push(v);
      before += src.length / 3;
      after += simple.length / 3;
    }
    g.setIndex(out);
    g.clearGroups();
    if (g.groups.length === 0 && kept.length > 1) for (const k of kept) g.addGroup(k.start, k.count, k.materialIndex);
  });
  return [before, after];
}

/**
 * A camera framing what `root` draws now (skinning and morphs applied), zoomed (a view offset:
 * the same camera, cropped) onto the square around what it draws in `scene`, so the model
 * rather than the background makes most of the images compared.
 */
function frameCamera(root: THREE.Object3D, scene: THREE.Scene): THREE.PerspectiveCamera {
  const box = new THREE.Box3().setFromObject(root, true);
  const sphere = box.getBoundingSphere(new THREE.Sphere());
  const camera = new THREE.PerspectiveCamera(40, 1, sphere.radius / 100, sphere.radius * 100);
  const fit = sphere.radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
  camera.position.copy(sphere.center).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(fit));
  camera.lookAt(sphere.center);
  camera.updateMatrixWorld();
  const first = pixels(renderer, scene, camera);
  let x0 = size, y0 = size, x1 = -1, y1 = -1;
  for (let y = 0; y < size; y++) for (let x = 0; x < size; x++) {
    const o = 4 * (y * size + x);
    if (Math.abs(first[o] - 0x1d) + Math.abs(first[o + 1] - 0x20) + Math.abs(first[o + 2] - 0x26) <= 6) continue;
    // readPixels' rows run bottom up; a view offset's from the top.
    const top = size - 1 - y;
    x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, top); y1 = Math.max(y1, top);
  }
  if (x1 >= 0) {
    const side = Math.min(size, Math.max(x1 - x0, y1 - y0) * 1.1 + 4);
    camera.setViewOffset(size, size, (x0 + x1) / 2 - side / 2, (y0 + y1) / 2 - side / 2, side, side);
    camera.updateProjectionMatrix();
  }
  return camera;
}

/** RGBA rows, top row first, base64 (what the harness decodes). */
function shot(renderer: THREE.WebGLRenderer, scene: THREE.Scene, camera: THREE.Camera): string {
  const px = pixels(renderer, scene, camera), out = new Uint8Array(px.length), row = 4 * size;
  for (let y = 0; y < size; y++) out.set(px.subarray((size - 1 - y) * row, (size - y) * row), y * row);
  let s = "";
  for (let i = 0; i < out.length; i += 0x8000) s += String.fromCharCode(...out.subarray(i, i + 0x8000));
  return btoa(s);
}

/**
 * Stream `pmc` (animation `animation` of `glb`, as `pmcodec encode --animation` samples it) at
 * each of `shares` of its triangles, and the GLB simplified by meshoptimizer to the same shares,
 * beside the full GLB, at `count` frames spread evenly over the stream (the first and the last
 * among them): one image of each per (frame, share).
 */
async function simplified(pmc: string, glb: string, animation: number, count: number, shares: number[]): Promise<Record<string, unknown>> {
  await MeshoptSimplifier.ready;
  const reference = await loadGlb(glb);
  const theirs = stage(env);
  theirs.add(reference.scene);
  const clip = reference.animations[animation];
  // Played once and held at the end: the encoder samples the clip's last instant too, which a
  // repeating action would wrap back to its start.
  const once = (m: THREE.AnimationMixer, c: THREE.AnimationClip | undefined): void => {
    if (c) m.clipAction(c).setLoop(THREE.LoopOnce, 1).play().clampWhenFinished = true;
  };
  const mixer = new THREE.AnimationMixer(reference.scene);
  once(mixer, clip);
  const simple = await Promise.all(shares.map(async (share) => {
    const g = await loadGlb(glb);
    const [before, after] = simplifyMeshes(g.scene, share);
    const scene = stage(env);
    scene.add(g.scene);
    const m = new THREE.AnimationMixer(g.scene);
    once(m, g.animations[animation]);
    return { scene, root: g.scene, mixer: m, before, after };
  }));
  const ours = stage(env);
  const player = PmcPlayer.fromUrl(pmc, { autoplay: false, morphMs: 0 });
  let failure: Error | null = null;
  player.addEventListener("error", (e) => { failure = e.error; });
  player.frustumCulled = false;
  ours.add(player);
  const images: { frame: number; share: number; reference: string; ours: string; meshopt: string; triangles: number; meshoptTriangles: number }[] = [];
  try {
    const info = await player.ready;
    const n = Math.max(1, Math.min(count, info.frames));
    const frames = [...new Set(Array.from({ length: n }, (_, i) => (n === 1 ? 0 : Math.round((i * (info.frames - 1)) / (n - 1)))))];
    for (const frame of frames) {
      const t = frame / info.frameRate;
      mixer.setTime(t);
      reference.scene.updateMatrixWorld(true);
      const camera = frameCamera(reference.scene, theirs);
      const ref = shot(renderer, theirs, camera);
      for (const [k, share] of shares.entries()) {
        player.budget = Math.max(1, Math.floor(share * info.triangles));
        player.seek(frame);
        const end = performance.now() + 20_000;
        await new Promise<void>((res, rej) => {
          const tick = (): void => {
            if (failure) { rej(failure); return; }
            player.update(performance.now());
            // A budget change may show a coarser cut first (a coarse decoder's stand-in): wait
            // for a cut at this budget from a decoder at the level the budget asks for or finer,
            // as the session itself chose it. Its triangle count is not a test: the cut stops
            // where the level's nodes run out, which may be well under the budget (Fox, frame 22
            // at 10%: level 2 has 58 triangles for a 57 budget, so level 3's 50 are drawn).
            const s = player.stats;
            const drawn = s.frame === frame && s.budget === player.budget && s.level >= 0 && s.level <= s.budgetLevel && s.triangles <= player.budget;
            if (drawn && (!info.appearance || Array.isArray(player.mesh.material))) res();
            else if (performance.now() > end) rej(new Error(`frame ${frame} at ${share}: not drawn (${player.stats.frame}, ${player.stats.triangles} triangles)`));
            else requestAnimationFrame(tick);
          };
          tick();
        });
        const s = simple[k];
        s.mixer.setTime(t);
        s.root.updateMatrixWorld(true);
        images.push({ frame, share, reference: ref, ours: shot(renderer, ours, camera), meshopt: shot(renderer, s.scene, camera), triangles: player.stats.triangles, meshoptTriangles: s.after });
      }
    }
    return { done: 1, size, frames: info.frames, totalTriangles: info.triangles, meshoptBefore: simple.map((s) => s.before), images };
  } finally {
    player.dispose();
    for (const root of [reference.scene, ...simple.map((s) => s.root)]) root.traverse((o) => {
      const m = o as THREE.Mesh;
      if (!m.isMesh) return;
      m.geometry.dispose();
      for (const mat of Array.isArray(m.material) ? m.material : [m.material]) mat.dispose();
    });
  }
}
Object.defineProperty(window, "pmcodecSimplified", {
  value: (pmc: string, glb: string, animation: number, count: number, shares: number[]) =>
    simplified(pmc, glb, animation, count, shares).catch((e) => ({ error: String(e?.message ?? e) })),
});

async function run(pmc: string, glb: string): Promise<Record<string, string | number>> {
  report({ running: pmc });
  const r = await compare(pmc, glb).catch((e) => ({ error: String(e?.message ?? e) }));
  report(r);
  return r;
}

// For the test harness: compare one pair after another on this page.
Object.defineProperty(window, "pmcodecCompare", { value: run });
const pmc = q.get("pmc"), glb = q.get("glb");
if (pmc && glb) void run(pmc, glb);
else report({ ready: 1 });
