// The appearance bar of issue 16: a stream drawn by pmcodec-three (frame 0, every triangle, its
// own materials) beside its source GLB drawn by three.js's stock GLTFLoader (the first
// animation at time 0: the pose the encoder samples as frame 0), with one camera, the same
// lights and the same environment. web/test/appearance-e2e.mjs compares the two canvases.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { DRACOLoader } from "three/examples/jsm/loaders/DRACOLoader.js";
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

  // The camera frames the reference's posed vertices (skinning and morphs applied).
  const box = new THREE.Box3().setFromObject(root, true);
  const sphere = box.getBoundingSphere(new THREE.Sphere());
  const camera = new THREE.PerspectiveCamera(40, 1, sphere.radius / 100, sphere.radius * 100);
  const fit = sphere.radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
  camera.position.copy(sphere.center).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(fit));
  camera.lookAt(sphere.center);
  camera.updateMatrixWorld();
  // Zoomed (a view offset: the same camera, cropped) onto the square around what the reference
  // draws, so the model rather than the background makes most of the images compared.
  const first = pixels(renderer, theirs, camera);
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
