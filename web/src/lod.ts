// Plays one level of a `pmcodec lod` chain (proto/lod.md: scene k is level k) with three.js's
// stock GLTFLoader, skinning and morphing: what an engine or viewer that knows nothing of
// pmcodec does with the file. Results go to #status's dataset for the test harness
// (web/test/lod-e2e.mjs): loaded, scenes, triangles, skinned, morphed and textured meshes, animations,
// and how far sampled vertices move between two animation times (0 would mean it does not play).
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";

const status = document.getElementById("status") as HTMLDivElement;
const canvas = document.getElementById("view") as HTMLCanvasElement;

function report(fields: Record<string, string | number>): void {
  for (const [k, v] of Object.entries(fields)) status.dataset[k] = String(v);
  status.textContent = Object.entries(status.dataset).map(([k, v]) => `${k} ${v}`).join("\n");
}

/** World positions of up to `n` vertices of every skinned or morphed mesh, skinning and morphs applied. */
function samplePositions(meshes: THREE.Mesh[], n: number): THREE.Vector3[] {
  const out: THREE.Vector3[] = [];
  for (const m of meshes) {
    const count = m.geometry.getAttribute("position").count;
    const step = Math.max(1, Math.floor(count / n));
    for (let i = 0; i < count; i += step) out.push(m.getVertexPosition(i, new THREE.Vector3()).applyMatrix4(m.matrixWorld));
  }
  return out;
}

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const src = params.get("src");
  if (!src) throw new Error("no ?src= given");
  const level = Number(params.get("scene") ?? "0");
  const gltf = await new GLTFLoader().loadAsync(src);
  const scene = gltf.scenes[level];
  if (!scene) throw new Error(`scene ${level}: the file has ${gltf.scenes.length}`);
  // Levels share one skeleton (proto/lod.md): three.js gives each scene its own clone of shared
  // roots, while every level's skins stay bound to the original bones. So play in the group
  // that holds those bones, with every level's mesh nodes in it and only this level's shown:
  // every animation track then finds its node (no "No target node found" warnings).
  const levelOf = (o: THREE.Object3D): number | undefined => {
    const m = /^lod(\d+)_mesh\d+$/.exec(o.name);
    return m ? Number(m[1]) : undefined;
  };
  let host: THREE.Object3D = scene;
  scene.traverse((o) => {
    const s = o as THREE.SkinnedMesh;
    if (host === scene && s.isSkinnedMesh && s.skeleton.bones.length > 0) {
      let top: THREE.Object3D = s.skeleton.bones[0];
      while (top.parent) top = top.parent;
      host = top;
    }
  });
  for (const other of gltf.scenes) {
    for (const child of [...other.children]) {
      const k = levelOf(child);
      if (k === undefined) continue;
      if (child.parent !== host) host.add(child);
      child.visible = k === level;
    }
  }
  const meshes: THREE.Mesh[] = [];
  let triangles = 0;
  let textured = 0;
  host.traverse((o) => {
    if ((o as THREE.Mesh).isMesh && o.visible && (o.parent === null || o.parent.visible)) {
      const m = o as THREE.Mesh;
      meshes.push(m);
      const index = m.geometry.getIndex();
      triangles += (index ? index.count : m.geometry.getAttribute("position").count) / 3;
      const mat = m.material as THREE.MeshStandardMaterial;
      if (mat.map) textured++;
    }
  });
  const skinned = meshes.filter((m) => (m as THREE.SkinnedMesh).isSkinnedMesh).length;
  const morphed = meshes.filter((m) => (m.morphTargetInfluences?.length ?? 0) > 0).length;

  const view = new THREE.Scene();
  view.background = new THREE.Color(0x1d2026);
  view.add(new THREE.HemisphereLight(0xffffff, 0x303040, 2.5));
  view.add(host);
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setSize(innerWidth, innerHeight, false);
  const camera = new THREE.PerspectiveCamera(40, innerWidth / innerHeight, 0.01, 1e6);
  host.updateMatrixWorld(true);
  const box = new THREE.Box3();
  for (const m of meshes) box.expandByObject(m, true);
  const centre = box.getCenter(new THREE.Vector3());
  const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-6);
  camera.position.copy(centre).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(radius * 2.6));
  camera.near = radius / 100;
  camera.far = radius * 100;
  camera.updateProjectionMatrix();
  camera.lookAt(centre);

  // Play the first animation; sample the skinned and morphed vertices at two times.
  const mixer = new THREE.AnimationMixer(host);
  const clip = gltf.animations[0];
  if (clip) mixer.clipAction(clip).play();
  const at = (t: number): THREE.Vector3[] => {
    mixer.setTime(t);
    host.updateMatrixWorld(true);
    return samplePositions(meshes, 200);
  };
  const duration = clip?.duration ?? 0;
  const a = at(0);
  const b = at(duration * 0.37);
  let moved = 0;
  for (let i = 0; i < a.length; i++) moved = Math.max(moved, a[i].distanceTo(b[i]));
  renderer.render(view, camera);
  report({
    loaded: 1, scenes: gltf.scenes.length, scene: level, meshes: meshes.length, triangles, skinned, morphed, textured,
    animations: gltf.animations.length, moved: moved / radius,
  });
  // Keep playing, as a viewer would.
  const clock = new THREE.Clock();
  renderer.setAnimationLoop(() => {
    mixer.update(clock.getDelta());
    renderer.render(view, camera);
  });
}

main().catch((e) => report({ error: String(e?.message ?? e) }));
