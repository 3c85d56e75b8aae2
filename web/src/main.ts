// The pmcodec viewer: streams an asset's container with HTTP range requests (only the bands the
// current triangle budget needs), replays frames in the browser (src/container.ts,
// src/replay.ts), cuts each frame at the budget, and geomorphs cut changes (src/geomorph.ts,
// Houle & Poulin section 5) instead of popping.

import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { Container, Player } from "./container.js";
import { blend, buildCutMesh, CutMesh, morphStarts } from "./geomorph.js";

interface AssetSummary { id: string; frames: number; frame_rate: number; triangles: number; levels: number[]; file: string; bytes: number }
interface AssetInfo extends AssetSummary { triangles_per_level: number[] }

const MORPH_MS = 250;
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
const material = new THREE.MeshStandardMaterial({ color: 0xc8b89a, roughness: 0.7, flatShading: true, side: THREE.DoubleSide });
const geometry = new THREE.BufferGeometry();
scene.add(new THREE.Mesh(geometry, material));

/** Everything about the asset being played. */
interface Session { info: AssetInfo; container: Container; player: Player; busy: boolean }
let session: Session | null = null;
let frame = 0;
let playing = true;
let lastAdvance = performance.now();
let decodeMs = 0;
let framed = false;
// The cut on screen and its geomorph.
let cut: CutMesh | null = null;
let positions: Float32Array = new Float32Array(0);
let starts: Float32Array = new Float32Array(0);
let morphStart = 0;
let morphed: Float32Array = new Float32Array(0);

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

/** Range reads of the container's immutable URL. */
function rangeReader(url: string) {
  return async (offset: number, len: number): Promise<Uint8Array> => {
    if (len === 0) return new Uint8Array(0);
    const r = await fetch(url, { headers: { Range: `bytes=${offset}-${offset + len - 1}` } });
    if (r.status !== 206 && r.status !== 200) throw new Error(`${url}: HTTP ${r.status}`);
    const b = new Uint8Array(await r.arrayBuffer());
    // A server may answer a range with the whole file (200): cut the range out.
    return r.status === 200 ? b.slice(offset, offset + len) : b;
  };
}

/**
 * The coarsest level whose whole mesh has at least `budget` triangles, less 2% (as the Rust
 * client's LEVEL_SLACK: anchored levels come out a few triangles short of round shares).
 */
function levelFor(info: AssetInfo, budget: number): number {
  let level = 0;
  for (let l = 0; l < info.triangles_per_level.length; l++) if (info.triangles_per_level[l] >= budget * 0.98) level = l;
  return level;
}

async function openAsset(summary: AssetSummary): Promise<void> {
  const info = (await (await fetch(`/v1/assets/${summary.id}`)).json()) as AssetInfo;
  const container = await Container.open(rangeReader(info.file), info.bytes);
  const budget = Number(budgetSlider.value);
  session = { info, container, player: new Player(container, levelFor(info, budget)), busy: false };
  frame = 0;
  framed = false;
  cut = null;
  frameSlider.max = String(info.frames - 1);
  budgetSlider.max = String(info.triangles);
  await showFrame(0);
}

/** A frame asked for while another was decoding: shown as soon as that one is done. */
let pendingFrame: number | null = null;

/**
 * Decodes frame f (reading finer bands first if the budget needs them), cuts it, starts a morph.
 * A request that arrives while a decode runs (a budget or frame change during playback, or
 * just after pausing) is kept and served when it ends, not dropped.
 */
async function showFrame(f: number): Promise<void> {
  const s = session;
  if (!s) return;
  if (s.busy) {
    pendingFrame = f;
    return;
  }
  s.busy = true;
  try {
    const budget = Number(budgetSlider.value);
    const need = levelFor(s.info, budget);
    if (need < s.player.minLevel) s.player = new Player(s.container, need); // raising the budget: fetch finer bands
    const t0 = performance.now();
    await s.player.seek(f);
    positions = s.player.positions();
    const r = s.player.replay;
    r.selectTriangles(budget, r.nodeErrors(positions));
    const next = buildCutMesh(r);
    starts = cut ? morphStarts(next, cut.nodes, positions, (g) => r.parentGlobal(g)) : gather(next, positions);
    morphStart = performance.now();
    cut = next;
    morphed = new Float32Array(next.nodes.length * 3);
    geometry.setIndex(new THREE.BufferAttribute(next.indices, 1));
    geometry.setAttribute("position", new THREE.BufferAttribute(morphed, 3));
    colour(next, r);
    decodeMs = performance.now() - t0;
    frame = f;
    frameSlider.value = String(f);
    showError("");
  } catch (e) {
    showError(String(e));
  } finally {
    s.busy = false;
    if (pendingFrame !== null && session === s) {
      const next = pendingFrame;
      pendingFrame = null;
      void showFrame(next);
    }
  }
}

function gather(mesh: CutMesh, pos: Float32Array): Float32Array {
  const out = new Float32Array(mesh.nodes.length * 3);
  mesh.nodes.forEach((g, i) => out.set(pos.subarray(3 * g, 3 * g + 3), 3 * i));
  return out;
}

/** Colour modes: the hierarchy level of each vertex's node, or its split priority (error bound). */
function colour(mesh: CutMesh, r: Player["replay"]): void {
  material.vertexColors = colourSel.value !== "plain";
  material.needsUpdate = true;
  if (colourSel.value === "plain") { geometry.deleteAttribute("color"); return; }
  const c = new Float32Array(mesh.nodes.length * 3);
  const errors = colourSel.value === "error" ? r.nodeErrors(positions) : null;
  let maxErr = 1e-12;
  if (errors) mesh.nodes.forEach((g) => { maxErr = Math.max(maxErr, errors[g]); });
  mesh.nodes.forEach((g, i) => {
    const k = errors ? errors[g] / maxErr : r.levelOf(g) / Math.max(1, r.top);
    const col = new THREE.Color().setHSL(0.66 * (1 - k), 0.75, 0.55);
    c.set([col.r, col.g, col.b], 3 * i);
  });
  geometry.setAttribute("color", new THREE.BufferAttribute(c, 3));
}

async function loadAssets(): Promise<void> {
  const r = await fetch("/v1/assets");
  if (!r.ok) throw new Error(`listing assets: HTTP ${r.status}`);
  const list = (await r.json()).assets as AssetSummary[];
  assetSel.replaceChildren(...list.map((a) => new Option(`${a.id} (${a.frames} frames)`, a.id)));
  assetSel.onchange = () => {
    const a = list.find((x) => x.id === assetSel.value);
    if (a) openAsset(a).catch((e) => showError(String(e)));
  };
  if (list.length) await openAsset(list[0]);
}

playBtn.onclick = () => { playing = !playing; playBtn.textContent = playing ? "pause" : "play"; };
frameSlider.oninput = () => { void showFrame(Number(frameSlider.value)); };
budgetSlider.onchange = () => { void showFrame(frame); };
wireBox.onchange = () => { material.wireframe = wireBox.checked; };
colourSel.onchange = () => { if (cut && session) colour(cut, session.player.replay); };

function loop(now: number): void {
  const s = session;
  if (s && playing && !s.busy) {
    const period = 1000 / (s.info.frame_rate * Number(speedSel.value));
    if (now - lastAdvance >= period) {
      lastAdvance = now;
      void showFrame((frame + 1) % s.info.frames);
    }
  }
  if (cut && morphed.length) {
    blend(cut, starts, positions, (now - morphStart) / MORPH_MS, morphed);
    (geometry.getAttribute("position") as THREE.BufferAttribute).needsUpdate = true;
    geometry.computeVertexNormals();
    if (!framed) {
      geometry.computeBoundingSphere();
      const b = geometry.boundingSphere;
      if (b) {
        controls.target.copy(b.center);
        camera.position.copy(b.center).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(b.radius * 3));
        camera.near = b.radius / 100;
        camera.far = b.radius * 100;
        camera.updateProjectionMatrix();
        framed = true;
      }
    }
  }
  controls.update();
  renderer.render(scene, camera);
  const tris = cut ? cut.indices.length / 3 : 0;
  overlay.textContent =
    `frame ${frame}${s ? " / " + (s.info.frames - 1) : ""}\n` +
    `triangles ${tris} (budget ${budgetSlider.value}, levels >= ${s?.player.minLevel ?? "-"})\n` +
    `downloaded ${((s?.container.bytesRead ?? 0) / 1024).toFixed(1)} KB\n` +
    `decode ${decodeMs.toFixed(1)} ms`;
  overlay.dataset.frame = String(frame);
  overlay.dataset.triangles = String(tris);
  overlay.dataset.level = String(s?.player.minLevel ?? "");
  overlay.dataset.bytes = String(s?.container.bytesRead ?? 0);
  requestAnimationFrame(loop);
}

loadAssets().catch((e) => showError(String(e)));
requestAnimationFrame(loop);
