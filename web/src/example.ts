// The package's example: what an app needs to stream a pmcodec asset into its own three.js
// scene, using only the package's public API. Opens ?asset=ID from the server that serves this
// page (the first asset when none is named), or ?url=... a .pmc on any range-capable host.

import * as THREE from "three";
import { PmcPlayer } from "pmcodec-three";

const canvas = document.getElementById("view") as HTMLCanvasElement;
const status = document.getElementById("status") as HTMLDivElement;
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
renderer.setSize(innerWidth, innerHeight, false);
const scene = new THREE.Scene();
scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 2));
const camera = new THREE.PerspectiveCamera(40, innerWidth / innerHeight, 0.01, 100);

const q = new URLSearchParams(location.search);
let asset = q.get("asset");
if (!q.get("url") && !asset) asset = (await (await fetch("/v1/assets")).json()).assets[0]?.id;
const player = q.get("url") ? PmcPlayer.fromUrl(q.get("url")!, { budget: 5000 }) : PmcPlayer.fromServer(location.origin, asset ?? "", { budget: 5000 });
scene.add(player);
player.addEventListener("load", () => {
  const s = player.boundingBox!.getBoundingSphere(new THREE.Sphere());
  camera.position.copy(s.center).add(new THREE.Vector3(0, 0, s.radius * 3.2));
  camera.lookAt(s.center);
});
player.addEventListener("frame", (e) => { status.textContent = `frame ${e.frame}, ${e.triangles} triangles`; status.dataset.frame = String(e.frame); });
player.addEventListener("error", (e) => { status.textContent = e.error.message; });

renderer.setAnimationLoop((now) => {
  player.update(now);
  renderer.render(scene, camera);
});
