// The pmcodec viewer. This first version plays an asset through the server's LOD-on-demand
// endpoint (one request per frame at the current triangle budget, `format=bin`); the streaming
// decoder with geomorphs (src/replay.ts, src/geomorph.ts) replaces it as it lands.

import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";

interface AssetSummary { id: string; frames: number; frame_rate: number; triangles: number; levels: number[] }

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const canvas = $<HTMLCanvasElement>("view");
const assetSel = $<HTMLSelectElement>("asset");
const playBtn = $<HTMLButtonElement>("play");
const speedSel = $<HTMLSelectElement>("speed");
const frameSlider = $<HTMLInputElement>("frame");
const budgetSlider = $<HTMLInputElement>("budget");
const wireBox = $<HTMLInputElement>("wire");
const colourSel = $<HTMLSelectElement>("colour");
const overlay = $<HTMLDivElement>("overlay");
const errorBox = $<HTMLDivElement>("error");

const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2026);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
const controls = new OrbitControls(camera, canvas);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(3, 5, 4);
scene.add(sun);
const material = new THREE.MeshStandardMaterial({ color: 0xc8b89a, roughness: 0.7, flatShading: true, side: THREE.DoubleSide, vertexColors: false });
const geometry = new THREE.BufferGeometry();
const mesh = new THREE.Mesh(geometry, material);
scene.add(mesh);

let asset: AssetSummary | null = null;
let frame = 0;
let playing = true;
let bytesDownloaded = 0;
let lastDecodeMs = 0;
let shownTriangles = 0;
let inFlight = false;
let framed = false;
let lastAdvance = performance.now();

function resize(): void {
  const w = window.innerWidth, h = window.innerHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener("resize", resize);
resize();

function showError(msg: string): void {
  errorBox.textContent = msg;
  errorBox.style.display = msg ? "block" : "none";
}

async function loadAssets(): Promise<void> {
  const r = await fetch("/v1/assets");
  if (!r.ok) throw new Error(`listing assets: HTTP ${r.status}`);
  const list = (await r.json()).assets as AssetSummary[];
  assetSel.replaceChildren(...list.map((a) => new Option(`${a.id} (${a.frames} frames)`, a.id)));
  const pick = (id: string) => {
    asset = list.find((a) => a.id === id) ?? null;
    if (!asset) return;
    frame = 0;
    framed = false;
    frameSlider.max = String(asset.frames - 1);
    budgetSlider.max = String(asset.triangles);
    budgetSlider.value = String(Math.min(Number(budgetSlider.value), asset.triangles));
  };
  assetSel.onchange = () => pick(assetSel.value);
  if (list.length) pick(list[0].id);
}

/** Fetches one frame at the current budget and installs it. */
async function fetchFrame(f: number): Promise<void> {
  if (!asset || inFlight) return;
  inFlight = true;
  try {
    const t0 = performance.now();
    const r = await fetch(`/v1/assets/${asset.id}/mesh?frame=${f}&triangles=${budgetSlider.value}&format=bin`);
    if (!r.ok) throw new Error(`frame ${f}: ${(await r.json()).detail ?? r.status}`);
    const buf = await r.arrayBuffer();
    bytesDownloaded += buf.byteLength;
    const head = new DataView(buf);
    if (head.getUint32(0, true) !== 0x4d434d50) throw new Error("not a PMCM mesh");
    const v = head.getUint32(8, true), t = head.getUint32(12, true);
    const positions = new Float32Array(buf, 16, v * 3);
    const indices = new Uint32Array(buf, 16 + v * 12, t * 3);
    geometry.setAttribute("position", new THREE.BufferAttribute(positions.slice(), 3));
    geometry.setIndex(new THREE.BufferAttribute(indices.slice(), 1));
    geometry.computeVertexNormals();
    geometry.computeBoundingSphere();
    if (colourSel.value !== "plain") colour(v);
    else geometry.deleteAttribute("color");
    material.vertexColors = colourSel.value !== "plain";
    material.needsUpdate = true;
    shownTriangles = t;
    lastDecodeMs = performance.now() - t0;
    frame = f;
    frameSlider.value = String(f);
    if (!framed && geometry.boundingSphere) {
      const s = geometry.boundingSphere;
      controls.target.copy(s.center);
      camera.position.copy(s.center).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(s.radius * 3));
      camera.near = s.radius / 100;
      camera.far = s.radius * 100;
      camera.updateProjectionMatrix();
      framed = true;
    }
    showError("");
  } catch (e) {
    showError(String(e));
  } finally {
    inFlight = false;
  }
}

/** Colours by a per-vertex proxy: distance from the area-weighted mean (level), or normal variation (error). */
function colour(v: number): void {
  const c = new Float32Array(v * 3);
  const n = geometry.getAttribute("normal") as THREE.BufferAttribute;
  for (let i = 0; i < v; i++) {
    const k = colourSel.value === "level" ? (i * 0.618) % 1 : Math.abs(n.getY(i));
    const col = new THREE.Color().setHSL(0.66 * (1 - k), 0.7, 0.55);
    c.set([col.r, col.g, col.b], 3 * i);
  }
  geometry.setAttribute("color", new THREE.BufferAttribute(c, 3));
}

playBtn.onclick = () => {
  playing = !playing;
  playBtn.textContent = playing ? "pause" : "play";
};
frameSlider.oninput = () => { void fetchFrame(Number(frameSlider.value)); };
budgetSlider.onchange = () => { void fetchFrame(frame); };
wireBox.onchange = () => { material.wireframe = wireBox.checked; };
colourSel.onchange = () => { void fetchFrame(frame); };

function loop(now: number): void {
  if (asset && playing && !inFlight) {
    const period = 1000 / (asset.frame_rate * Number(speedSel.value));
    if (now - lastAdvance >= period) {
      lastAdvance = now;
      void fetchFrame((frame + 1) % asset.frames);
    }
  }
  controls.update();
  renderer.render(scene, camera);
  overlay.textContent =
    `frame ${frame}${asset ? " / " + (asset.frames - 1) : ""}\n` +
    `triangles ${shownTriangles} (budget ${budgetSlider.value})\n` +
    `downloaded ${(bytesDownloaded / 1024).toFixed(1)} KB\n` +
    `fetch+decode ${lastDecodeMs.toFixed(1)} ms`;
  overlay.dataset.frame = String(frame);
  overlay.dataset.triangles = String(shownTriangles);
  requestAnimationFrame(loop);
}

loadAssets().then(() => fetchFrame(0)).catch((e) => showError(String(e)));
requestAnimationFrame(loop);
