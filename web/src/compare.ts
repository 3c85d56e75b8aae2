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
  for (const [k, v] of Object.entries(fields)) status.dataset[k] = String(v);
  status.textContent = Object.entries(status.dataset).map(([k, v]) => `${k} ${v}`).join("\n");
}

/** A renderer on one canvas and a scene lit the same way as the other's. */
function stage(id: string): { renderer: THREE.WebGLRenderer; scene: THREE.Scene } {
  const canvas = document.getElementById(id) as HTMLCanvasElement;
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(size, size, false);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1d2026);
  scene.environment = roomEnvironment(renderer);
  const sun = new THREE.DirectionalLight(0xffffff, 1.5);
  sun.position.set(3, 5, 4);
  scene.add(sun);
  return { renderer, scene };
}

async function main(): Promise<void> {
  const pmc = q.get("pmc"), glb = q.get("glb");
  if (!pmc || !glb) throw new Error("give ?pmc=URL&glb=URL");
  const ours = stage("stream"), theirs = stage("reference");

  // The reference: the GLB as three.js loads it, posed at the first animation's time 0.
  const loader = new GLTFLoader();
  const draco = new DRACOLoader().setDecoderPath(q.get("draco") ?? "/draco/");
  loader.setDRACOLoader(draco);
  const gltf = await loader.loadAsync(glb);
  draco.dispose();
  const root = gltf.scene;
  theirs.scene.add(root);
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

  // The stream: frame 0, every triangle, no geomorph, its own materials.
  const player = PmcPlayer.fromUrl(pmc, { autoplay: false, morphMs: 0 });
  player.frustumCulled = false;
  ours.scene.add(player);
  const info = await player.ready;
  player.seek(0);
  const materials = new Promise<void>((res) => { if (!info.appearance || player.materials) res(); else player.addEventListener("materials", () => res()); });
  player.addEventListener("error", (e) => { console.error(`player: ${e.error.message}`); report({ error: e.error.message }); });
  await materials;
  await new Promise<void>((res) => {
    const tick = (): void => {
      player.update(performance.now());
      if (player.stats.frame === 0 && player.stats.triangles === info.triangles && (!info.appearance || Array.isArray(player.mesh.material))) res();
      else requestAnimationFrame(tick);
    };
    tick();
  });
  ours.renderer.render(ours.scene, camera);
  theirs.renderer.render(theirs.scene, camera);
  let triangles = 0, textured = 0;
  root.traverse((o) => {
    const m = o as THREE.Mesh;
    if (!m.isMesh) return;
    const idx = m.geometry.getIndex();
    triangles += (idx ? idx.count : m.geometry.getAttribute("position").count) / 3;
    for (const mat of Array.isArray(m.material) ? m.material : [m.material]) if ((mat as THREE.MeshStandardMaterial).map) textured++;
  });
  const ourMaterials = Array.isArray(player.mesh.material) ? player.mesh.material : [player.mesh.material];
  report({
    done: 1, triangles: player.stats.triangles, referenceTriangles: triangles, frames: info.frames,
    materials: ourMaterials.length, textured: ourMaterials.filter((m) => (m as THREE.MeshStandardMaterial).map).length,
    referenceTextured: textured, appearance: info.appearance ? 1 : 0, animation: clip?.name ?? "",
  });
}

main().catch((e) => report({ error: String(e?.message ?? e) }));
