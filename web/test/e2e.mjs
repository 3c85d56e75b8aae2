// End-to-end: start `pmcodec serve` (built-in samples + this viewer), open the page in headless
// Chromium, and check that frames play, the canvas shows a mesh, and moving the triangle budget
// changes the triangle count. Saves a screenshot to web/test-artifacts/viewer.png.
// Needs: the release binary (cargo build --release -p pmcodec), web/dist (npm run build),
// Debian's chromium at /usr/bin/chromium.
import { mkdirSync } from "node:fs";
import assert from "node:assert/strict";
import { launch, ready, root, serve } from "./harness.mjs";

const bin = process.env.PMCODEC_BIN ?? `${root}/target/release/pmcodec`;
// The server's request log (one line per request on stderr) collects in `host.log`.
const host = serve(bin, ["--viewer", `${root}/web/dist`], { capture: true });
const { server, base } = host;
let browser;
try {
  // The server encodes its samples at start.
  await ready(base);
  browser = await launch();
  const page = await browser.newPage({ viewport: { width: 960, height: 640 } });
  const fileRequests = [];
  page.on("request", (r) => { if (r.url().includes("/v/")) fileRequests.push(r.headers()["range"] ?? "all"); });
  await page.goto(base + "/");
  const frameOf = () => page.$eval("#overlay", (e) => Number(e.dataset.frame ?? -1));
  const trianglesOf = () => page.$eval("#overlay", (e) => Number(e.dataset.triangles ?? 0));
  await page.waitForFunction(() => Number(document.getElementById("overlay")?.dataset.triangles ?? 0) > 0, null, { timeout: 90_000 });
  const f0 = await frameOf();
  await page.waitForFunction((f) => Number(document.getElementById("overlay")?.dataset.frame ?? -1) !== f, f0, { timeout: 60_000 });
  assert.notEqual(await frameOf(), f0, "the frame counter advances");
  // Non-background pixels on the canvas.
  const lit = await page.$eval("#view", (c) => {
    const gl = c.getContext("webgl2") ?? c.getContext("webgl");
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let n = 0;
    for (let i = 0; i < px.length; i += 4) if (Math.abs(px[i] - 0x1d) + Math.abs(px[i + 1] - 0x20) + Math.abs(px[i + 2] - 0x26) > 30) n++;
    return n;
  });
  assert.ok(lit > 1000, `only ${lit} lit pixels`);
  // Budget slider: fewer triangles shown; then a large budget makes the page fetch finer bands
  // (new range requests to the container's immutable URL, more bytes, a finer level).
  await page.click("#play");
  const before = await trianglesOf();
  await page.$eval("#budget", (e) => { e.value = "200"; e.dispatchEvent(new Event("input")); });
  // Wait for the budget itself, not for any change: a frame that was decoding when playback
  // paused may still land first, and budget cuts differ by a few triangles from frame to frame.
  await page.waitForFunction(() => { const t = Number(document.getElementById("overlay")?.dataset.triangles ?? 0); return t > 0 && t <= 200; }, null, { timeout: 60_000 });
  const after = await trianglesOf();
  assert.ok(after <= 200 && after < before, `budget 200 shows ${after} (was ${before})`);
  const levelBefore = await page.$eval("#overlay", (e) => Number(e.dataset.level));
  const requestsBefore = fileRequests.length;
  const logBefore = host.log.length;
  await page.$eval("#budget", (e) => { e.value = e.max; e.dispatchEvent(new Event("input")); });
  await page.waitForFunction((l) => Number(document.getElementById("overlay")?.dataset.level) < l, levelBefore, { timeout: 60_000 });
  await page.waitForFunction((a) => Number(document.getElementById("overlay")?.dataset.triangles ?? 0) > a, after, { timeout: 60_000 });
  const big = await trianglesOf();
  assert.ok(fileRequests.length > requestsBefore, "raising the budget fetched more of the container");
  assert.ok(fileRequests.every((r) => r.startsWith("bytes=")), "every container read is a range request");
  const newLines = host.log.slice(logBefore).split("\n").filter((l) => l.includes("/v/") && l.includes("range=bytes=") && l.includes("status=206"));
  assert.ok(newLines.length > 0, "the server's request log shows the finer bands being fetched");
  // Let a geomorph finish before the screenshot.
  await page.waitForTimeout(400);
  mkdirSync(`${root}/web/test-artifacts`, { recursive: true });
  await page.screenshot({ path: `${root}/web/test-artifacts/viewer.png` });
  console.log(`e2e: 1 passed, 0 failed (frames advance, ${lit} lit pixels, ${before} -> ${after} -> ${big} triangles, ${fileRequests.length} range requests)`);
} finally {
  await browser?.close();
  server.kill("SIGTERM");
}
