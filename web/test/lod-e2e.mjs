// The LOD chains `pmcodec lod` writes, played by three.js's stock GLTFLoader in headless
// Chromium (web/lod.html): every level (scene) of every file given loads, has skinned and/or
// morphed meshes, plays its first animation (sampled vertices move) with no track missing its
// node, draws textured when the file has images, and has fewer triangles than the level
// before. Saves a screenshot per level to web/test-artifacts/.
// Usage: node test/lod-e2e.mjs A-lod.glb [B-lod.glb ...]
// Needs: a pmcodec binary (PMCODEC_BIN, default target/release/pmcodec) to serve web/dist,
// web/dist (npm run build), Debian's chromium at /usr/bin/chromium.
import { mkdirSync, readFileSync } from "node:fs";
import { basename } from "node:path";
import assert from "node:assert/strict";
import { launch, ready, root, serve } from "./harness.mjs";

const files = process.argv.slice(2);
if (files.length === 0) throw new Error("usage: node test/lod-e2e.mjs FILE.glb ...");
const bin = process.env.PMCODEC_BIN ?? `${root}/target/release/pmcodec`;
// An empty asset folder: the page and its bundle are all this test needs from the server.
const assets = `${root}/target/lod-e2e-assets`;
mkdirSync(assets, { recursive: true });
const { server, base } = serve(bin, ["--assets", assets, "--viewer", `${root}/web/dist`, "--quiet"], { from: 19000 });
let browser;
let checked = 0;
try {
  await ready(base, 60_000);
  browser = await launch();
  mkdirSync(`${root}/web/test-artifacts`, { recursive: true });
  for (const file of files) {
    const bytes = readFileSync(file);
    const name = basename(file, ".glb");
    const images = (JSON.parse(bytes.subarray(20, 20 + bytes.readUInt32LE(12)).toString()).images ?? []).length;
    let previous = Infinity;
    for (let level = 0; ; level++) {
      const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
      const errors = [];
      const warnings = [];
      page.on("pageerror", (e) => errors.push(String(e)));
      page.on("console", (m) => { if (m.type() === "warning" || m.type() === "error") warnings.push(m.text()); });
      // The file under test, served to the page at a URL of its own.
      await page.route("**/under-test.glb", (r) => r.fulfill({ body: bytes, contentType: "model/gltf-binary" }));
      await page.goto(`${base}/lod.html?src=/under-test.glb&scene=${level}`);
      await page.waitForFunction(() => { const d = document.getElementById("status")?.dataset; return d && (d.loaded || d.error); }, null, { timeout: 60_000 });
      const d = await page.$eval("#status", (e) => ({ ...e.dataset }));
      if (d.error?.startsWith(`scene ${level}:`) && level > 0) { await page.close(); break; }
      assert.equal(d.error, undefined, `${name} level ${level}: ${d.error}`);
      assert.deepEqual(errors, [], `${name} level ${level}: page errors`);
      const at = `${name} level ${level}`;
      assert.ok(Number(d.meshes) > 0, `${at}: no meshes`);
      assert.ok(Number(d.skinned) + Number(d.morphed) > 0, `${at}: nothing skinned or morphed`);
      assert.ok(Number(d.animations) > 0, `${at}: no animations`);
      // One skeleton and one set of animations: every track finds its node.
      const missing = warnings.filter((w) => w.includes("No target node found"));
      assert.deepEqual(missing, [], `${at}: animation tracks without a node`);
      // A file with textures draws every level textured.
      if (images > 0) assert.ok(Number(d.textured) > 0, `${at}: no textured mesh though the file has ${images} images`);
      assert.ok(Number(d.moved) > 1e-3, `${at}: the animation does not move the mesh (${d.moved})`);
      assert.ok(Number(d.triangles) < previous, `${at}: ${d.triangles} triangles, not fewer than the level before (${previous})`);
      previous = Number(d.triangles);
      await page.waitForTimeout(200);
      const lit = await page.$eval("#view", (c) => {
        const gl = c.getContext("webgl2") ?? c.getContext("webgl");
        const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
        const px = new Uint8Array(w * h * 4);
        gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
        let n = 0;
        for (let i = 0; i < px.length; i += 4) if (Math.abs(px[i] - 0x1d) + Math.abs(px[i + 1] - 0x20) + Math.abs(px[i + 2] - 0x26) > 30) n++;
        return n;
      });
      assert.ok(lit > 500, `${at}: only ${lit} lit pixels`);
      await page.screenshot({ path: `${root}/web/test-artifacts/lod-${name}-${level}.png` });
      console.log(`lod-e2e: ${at}: ${d.triangles} triangles, ${d.skinned} skinned, ${d.morphed} morphed and ${d.textured} textured meshes, ${d.animations} animations, moved ${Number(d.moved).toFixed(3)} radii, ${lit} lit pixels`);
      checked++;
      await page.close();
    }
    assert.ok(previous < Infinity, `${name}: no level played`);
  }
  console.log(`lod-e2e: ${checked} levels of ${files.length} files play in three.js`);
} finally {
  await browser?.close();
  server.kill("SIGTERM");
}
