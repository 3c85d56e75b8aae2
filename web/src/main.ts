// The pmcodec viewer, built on the pmcodec-three package (src/player): the asset list of the
// server it is served by, playback controls, a triangle budget that geomorphs while dragged,
// uploads by drag and drop or file picker (an encode job, followed over its event stream), and
// an address that carries asset, frame and budget so a view can be shared.

import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { PmcPlayer, roomEnvironment, type ColourMode } from "pmcodec-three";

interface AssetSummary { id: string; frames: number; frame_rate: number; triangles: number }

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const canvas = $<HTMLCanvasElement>("view");
const assetSel = $<HTMLSelectElement>("asset");
const playBtn = $<HTMLButtonElement>("play");
const speedSel = $<HTMLSelectElement>("speed");
const frameSlider = $<HTMLInputElement>("frame");
const budgetSlider = $<HTMLInputElement>("budget");
const wireBox = $<HTMLInputElement>("wire");
const colourSel = $<HTMLSelectElement>("colour");
const fileInput = $<HTMLInputElement>("file");
const overlay = $<HTMLDivElement>("overlay");
const errorBox = $<HTMLDivElement>("error");
const jobBox = $<HTMLDivElement>("job");

const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2026);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
const controls = new OrbitControls(camera, canvas);
// An environment light for the streams' own PBR materials (metallic surfaces render black
// without one), used only while they are drawn: flat colours keep the lights they were tuned with.
// Made on first use (prefiltering it blocks the page a moment): streams without materials never
// need it.
let environment: THREE.Texture | null = null;
const hemisphere = new THREE.HemisphereLight(0xffffff, 0x404050, 1.2);
scene.add(hemisphere);
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(3, 5, 4);
scene.add(sun);

let player: PmcPlayer | null = null;

/** The environment light while the player draws a stream's materials. */
function updateEnvironment(): void {
  const p = player;
  const wanted = p !== null && p.info?.appearance != null && p.colourMode === "authored";
  if (wanted && environment === null) environment = roomEnvironment(renderer);
  scene.environment = wanted ? environment : null;
  // The environment is the ambient light then (as on web/compare.html, where streams are
  // checked against three.js's own drawing of their GLB): the hemisphere would add to it.
  hemisphere.visible = scene.environment === null;
}
let assets: AssetSummary[] = [];
/** The last address written, so history gets one entry per change that matters. */
let lastUrl = "";

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

/** Frames the whole animation's bounds (not one frame's: limbs and wings leave those). */
function frameView(p: PmcPlayer): void {
  const box = p.boundingBox;
  if (!box) return;
  const sphere = box.getBoundingSphere(new THREE.Sphere());
  const fit = sphere.radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * 1.05;
  controls.target.copy(sphere.center);
  camera.position.copy(sphere.center).add(new THREE.Vector3(0.6, 0.4, 1).normalize().multiplyScalar(fit));
  camera.near = sphere.radius / 100;
  camera.far = sphere.radius * 100;
  camera.updateProjectionMatrix();
  controls.update();
}

/** The view's state from the address: ?asset=ID&frame=F&budget=N. */
function fromAddress(): { asset: string | null; frame: number | null; budget: number | null } {
  const q = new URLSearchParams(location.search);
  const num = (k: string) => { const v = q.get(k); return v !== null && /^\d+$/.test(v) ? Number(v) : null; };
  return { asset: q.get("asset"), frame: num("frame"), budget: num("budget") };
}

function writeAddress(): void {
  if (!player?.info) return;
  const q = new URLSearchParams({ asset: assetSel.value, budget: String(player.budget) });
  // The frame only when paused: a playing view's frame changes 30 times a second.
  if (!player.playing) q.set("frame", String(Math.max(0, player.frame)));
  const url = `${location.pathname}?${q}`;
  if (url !== lastUrl) { history.replaceState(null, "", url); lastUrl = url; }
}

function open(id: string, at: { frame?: number | null; budget?: number | null } = {}): void {
  player?.dispose();
  showError("");
  const a = assets.find((x) => x.id === id);
  const budget = at.budget ?? Math.min(a?.triangles ?? 2000, Number(budgetSlider.value) || 2000);
  // ?gpuskin=0: skinned streams posed by the worker, as before GPU skinning (for comparisons).
  const gpuSkin = new URLSearchParams(location.search).get("gpuskin") !== "0";
  const p = PmcPlayer.fromServer(location.origin, id, { budget, autoplay: at.frame === null || at.frame === undefined, gpuSkin });
  player = p;
  p.colourMode = colourSel.value as ColourMode;
  p.wireframe = wireBox.checked;
  if (at.frame !== null && at.frame !== undefined) p.seek(at.frame);
  scene.add(p);
  p.addEventListener("load", ({ info }) => {
    if (player !== p) return;
    frameSlider.max = String(info.frames - 1);
    budgetSlider.max = String(info.triangles);
    budgetSlider.value = String(Math.min(p.budget, info.triangles));
    playBtn.textContent = p.playing ? "pause" : "play";
    frameView(p);
    updateEnvironment();
    writeAddress();
  });
  p.addEventListener("frame", ({ frame }) => {
    if (player !== p) return;
    if (document.activeElement !== frameSlider) frameSlider.value = String(frame);
  });
  p.addEventListener("error", ({ error }) => { if (player === p) showError(`${id}: ${error.message}`); });
}

async function loadAssets(select?: string): Promise<void> {
  const r = await fetch("/v1/assets");
  if (!r.ok) throw new Error(`listing assets: HTTP ${r.status}`);
  assets = (await r.json()).assets as AssetSummary[];
  const keep = select ?? assetSel.value;
  assetSel.replaceChildren(...assets.map((a) => new Option(`${a.id} (${a.frames} frames)`, a.id)));
  if (keep && assets.some((a) => a.id === keep)) assetSel.value = keep;
}

assetSel.onchange = () => { open(assetSel.value); };
$<HTMLButtonElement>("refresh").onclick = () => { loadAssets().catch((e) => showError(String(e))); };
// Assets added elsewhere (another tab, curl) show up when the page comes back into view.
window.addEventListener("focus", () => { loadAssets().catch((e) => showError(String(e))); });
$<HTMLButtonElement>("reset").onclick = () => { if (player) frameView(player); };
playBtn.onclick = () => {
  if (!player) return;
  if (player.playing) player.pause(); else player.play();
  playBtn.textContent = player.playing ? "pause" : "play";
  writeAddress();
};
speedSel.onchange = () => { if (player) player.speed = Number(speedSel.value); };
// While dragging: the worker cuts again (and the mesh geomorphs) on every step, not on release.
frameSlider.oninput = () => { player?.seek(Number(frameSlider.value)); };
frameSlider.onchange = () => { frameSlider.blur(); writeAddress(); };
budgetSlider.oninput = () => { if (player) player.budget = Number(budgetSlider.value); };
budgetSlider.onchange = () => { writeAddress(); };
wireBox.onchange = () => { if (player) player.wireframe = wireBox.checked; };
colourSel.onchange = () => { if (player) player.colourMode = colourSel.value as ColourMode; updateEnvironment(); };

// ---- uploads -----------------------------------------------------------------------------------

/** The write token, asked for once per tab. */
function writeToken(): string | null {
  let t = sessionStorage.getItem("pmcodec-write-token");
  if (!t) {
    t = window.prompt("Write token of this server (PMCODEC_WRITE_TOKEN):");
    if (t) sessionStorage.setItem("pmcodec-write-token", t);
  }
  return t;
}

/** An asset id from a file name: letters, digits, '-' and '_', as the server accepts. */
function idFrom(name: string): string {
  const base = name.replace(/\.[^.]*$/, "").toLowerCase().replace(/[^a-z0-9_-]+/g, "-").replace(/^-+|-+$/g, "");
  return (base || "upload").slice(0, 64);
}

function showJob(text: string): void {
  jobBox.textContent = text;
  jobBox.style.display = text ? "block" : "none";
}

async function upload(file: File): Promise<void> {
  const lower = file.name.toLowerCase();
  if (!lower.endsWith(".glb") && !lower.endsWith(".zip")) throw new Error(`${file.name}: not a .glb or a .zip of OBJ frames`);
  const token = writeToken();
  if (!token) throw new Error("uploading needs the server's write token");
  const id = idFrom(file.name);
  showJob(`uploading ${file.name} as ${id}...`);
  const r = await fetch(`/v1/assets?id=${encodeURIComponent(id)}`, {
    method: "POST",
    headers: { Authorization: `Bearer ${token}`, "Content-Type": lower.endsWith(".glb") ? "model/gltf-binary" : "application/zip" },
    body: file,
  });
  const body = await r.json().catch(() => ({}));
  if (r.status === 401 || r.status === 403) sessionStorage.removeItem("pmcodec-write-token");
  if (r.status !== 202) throw new Error(`upload of ${file.name}: HTTP ${r.status} ${body.detail ?? body.title ?? ""}`);
  await followJob(String(body.events_url), id);
}

/** Shows an encode job's progress from its event stream; opens the asset when it succeeds. */
function followJob(eventsUrl: string, id: string): Promise<void> {
  return new Promise((resolve, reject) => {
    const es = new EventSource(eventsUrl);
    const status = (ev: MessageEvent) => {
      const s = JSON.parse(ev.data);
      const frames = s.frames_total ? ` ${s.frames_done}/${s.frames_total} frames` : "";
      showJob(`${id}: ${s.stage} ${Math.round(100 * (s.progress ?? 0))}%${frames}`);
      return s;
    };
    es.addEventListener("queued", (ev) => status(ev as MessageEvent));
    es.addEventListener("running", (ev) => status(ev as MessageEvent));
    es.addEventListener("succeeded", (ev) => {
      status(ev as MessageEvent);
      es.close();
      showJob(`${id}: done`);
      setTimeout(() => showJob(""), 3000);
      loadAssets(id).then(() => { open(id); resolve(); }, reject);
    });
    es.addEventListener("failed", (ev) => {
      es.close();
      const s = JSON.parse((ev as MessageEvent).data);
      showJob("");
      reject(new Error(`${id}: encoding failed: ${s.message ?? "no reason given"}`));
    });
    es.onerror = () => {
      if (es.readyState === EventSource.CLOSED) reject(new Error(`${id}: lost the job's event stream`));
    };
  });
}

fileInput.onchange = () => {
  const f = fileInput.files?.[0];
  fileInput.value = "";
  if (f) upload(f).catch((e) => { showJob(""); showError(String(e instanceof Error ? e.message : e)); });
};
let dragDepth = 0;
window.addEventListener("dragenter", (e) => { e.preventDefault(); dragDepth++; document.body.classList.add("dragging"); });
window.addEventListener("dragleave", () => { if (--dragDepth <= 0) { dragDepth = 0; document.body.classList.remove("dragging"); } });
window.addEventListener("dragover", (e) => { e.preventDefault(); });
window.addEventListener("drop", (e) => {
  e.preventDefault();
  dragDepth = 0;
  document.body.classList.remove("dragging");
  const f = e.dataTransfer?.files?.[0];
  if (f) upload(f).catch((err) => { showJob(""); showError(String(err instanceof Error ? err.message : err)); });
});

// ---- drawing -----------------------------------------------------------------------------------

/** Time in three.js's render calls and animation frames drawn, for the benchmark. */
let renderMs = 0, draws = 0;

function loop(now: number): void {
  const p = player;
  if (p) p.update(now);
  controls.update();
  const r0 = performance.now();
  renderer.render(scene, camera);
  renderMs += performance.now() - r0;
  const s = p?.stats;
  overlay.textContent = s && p?.info
    ? `frame ${Math.max(0, s.frame)} / ${p.info.frames - 1}\n` +
      `triangles ${s.triangles} (budget ${p.budget}, levels >= ${s.level})\n` +
      `downloaded ${(s.fetched / 1024).toFixed(1)} KB in ${s.requests} requests (cache ${(s.cached / 1024).toFixed(0)} KB)\n` +
      `worker: decode ${s.decodeMs.toFixed(1)} ms, cut ${s.cutMs.toFixed(1)} ms`
    : "loading...";
  overlay.dataset.frame = String(s?.frame ?? -1);
  overlay.dataset.triangles = String(s?.triangles ?? 0);
  overlay.dataset.level = String(s?.level ?? "");
  overlay.dataset.bytes = String(s?.fetched ?? 0);
  overlay.dataset.requests = String(s?.requests ?? 0);
  overlay.dataset.asset = p ? assetSel.value : "";
  overlay.dataset.shown = String(s?.shown ?? 0);
  overlay.dataset.mainMs = String(s?.mainMs ?? 0);
  overlay.dataset.stalls = String(s?.stalls ?? 0);
  overlay.dataset.workerMs = String(s?.workerMs ?? 0);
  overlay.dataset.renderMs = String(renderMs);
  overlay.dataset.draws = String(++draws);
  requestAnimationFrame(loop);
}

// For the console and the end-to-end tests: what is on screen.
Object.defineProperty(window, "pmcodecViewer", { value: { get player() { return player; }, camera, controls, renderer, scene } });

const start = fromAddress();
loadAssets(start.asset ?? undefined)
  .then(() => {
    const id = start.asset && assets.some((a) => a.id === start.asset) ? start.asset : assets[0]?.id;
    if (id) { assetSel.value = id; open(id, { frame: start.frame, budget: start.budget }); }
  })
  .catch((e) => showError(String(e)));
requestAnimationFrame(loop);
