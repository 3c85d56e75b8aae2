// GPU skinning in the viewer (issue 17), beyond frame 0 (appearance-e2e draws frame 0 against
// GLTFLoader): each shared skinned GLB is encoded, served with the viewer, and drawn
// (1) paused at a frame far from a keyframe, (2) where playback was paused after a few seconds
// (the per-frame palette and offset changes applied on the page one after another), and
// (3) after the budget dropped to a third and rose back during playback (new cuts, their skins,
// geomorphs), each time with GPU skinning (?gpuskin=1) and with the worker posing every vertex
// (?gpuskin=0) at the same frame: the two pictures must agree (SSIM >= 0.96 over the model; they
// differ in normals: the GPU skins the bind pose's, as GLTFLoader's drawing does, the worker
// recomputes them from posed positions). A control: the drawing against the worker's two frames
// later must fall below the bar, so the bar tells a pose from its neighbour.
// Usage: node test/skin-e2e.mjs [Model ...]   (default: Fox RobotExpressive)
// Needs: web/dist (npm run build), the pmcodec binary (PMCODEC_BIN, default target/debug/pmcodec),
// Debian's chromium at /usr/bin/chromium.
import { execFileSync } from "node:child_process";
import { mkdtempSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import assert from "node:assert/strict";
import { launch, ready, root, serve, sleep } from "./harness.mjs";
import { luminance, ssim } from "./image-lib.mjs";

const bin = process.env.PMCODEC_BIN ?? `${root}/target/debug/pmcodec`;
const names = process.argv.slice(2).length ? process.argv.slice(2) : ["Fox", "RobotExpressive"];
// Fox's faceted shading differs most between the two normals (0.977-0.985 by frame, and the
// frame playback pauses at varies from run to run); a neighbouring pose scores 0.53 (Fox) and
// 0.88 (RobotExpressive), so 0.96 still tells a pose from its neighbour.
const BAR = 0.96;
const work = mkdtempSync(join(tmpdir(), "pmc-skin-e2e-"));
for (const n of names) execFileSync(bin, ["encode", "-q", join(root, "../shared/data/gltf", `${n}.glb`), "-o", join(work, `${n.toLowerCase()}.pmc`), "--keyframe-interval", "8"]);
const { server, base } = serve(bin, ["--assets", work, "--viewer", `${root}/web/dist`], { from: 17000 });
const results = [];
let browser;
try {
  await ready(base, 100_000);
  browser = await launch();
  const W = 320, H = 320;
  async function open(query) {
    const context = await browser.newContext({ viewport: { width: W, height: H } });
    const page = await context.newPage();
    const errors = [];
    page.on("pageerror", (e) => errors.push(String(e)));
    await page.goto(`${base}/?${query}`);
    await page.waitForFunction(() => Number(document.getElementById("overlay")?.dataset.shown ?? 0) > 0, null, { timeout: 120_000 });
    return { page, context, errors };
  }
  /** Waits until frame f is on screen at the full triangle count with no geomorph running, then reads the canvas. */
  async function shot(page, f, triangles) {
    await page.waitForFunction(([f, t]) => {
      const o = document.getElementById("overlay").dataset, p = window.pmcodecViewer.player;
      return Number(o.frame) === f && Number(o.triangles) === t && !p.morph && !p.skinMorph;
    }, [f, triangles], { timeout: 120_000 });
    // Two animation frames: the frame shown is rendered.
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
    return page.evaluate(() => {
      const c = document.getElementById("view"), gl = window.pmcodecViewer.renderer.getContext();
      const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight, px = new Uint8Array(w * h * 4);
      gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
      let s = "";
      for (let i = 0; i < px.length; i += 0x8000) s += String.fromCharCode(...px.subarray(i, i + 0x8000));
      return { w, h, rgba: btoa(s), skinned: window.pmcodecViewer.player.mesh.isSkinnedMesh === true, c: c.width };
    });
  }
  function compare(a, b) {
    const ra = Buffer.from(a.rgba, "base64"), rb = Buffer.from(b.rgba, "base64");
    const bg = [0x1d, 0x20, 0x26], mask = new Float64Array(a.w * a.h);
    let covered = 0;
    for (let i = 0; i < mask.length; i++) {
      const off = (px) => Math.abs(px[4 * i] - bg[0]) + Math.abs(px[4 * i + 1] - bg[1]) + Math.abs(px[4 * i + 2] - bg[2]) > 6;
      if (off(ra) || off(rb)) { mask[i] = 1; covered++; }
    }
    return { ...ssim(luminance(ra, a.w, a.h), luminance(rb, b.w, b.h), a.w, a.h, mask), covered: covered / mask.length };
  }
  for (const name of names) {
    const asset = name.toLowerCase();
    try {
      const info = await (await fetch(`${base}/v1/assets/${asset}`)).json();
      const full = info.triangles, lines = [];
      /** The same frame drawn by the worker's positions. */
      async function reference(f) {
        const { page, context, errors } = await open(`asset=${asset}&budget=${full}&frame=${f}&gpuskin=0`);
        const s = await shot(page, f, full);
        await context.close();
        assert.deepEqual(errors, [], "errors on the reference page");
        assert.equal(s.skinned, false);
        return s;
      }
      async function check(what, page, errors, f, control = false) {
        const s = await shot(page, f, full);
        assert.deepEqual(errors, [], `${what}: errors on the page`);
        assert.equal(s.skinned, true, `${what}: not skinned on the GPU`);
        const c = compare(s, await reference(f));
        lines.push(`${what} (frame ${f}): SSIM ${c.ssim.toFixed(4)} (model ${c.masked.toFixed(4)}, covers ${(100 * c.covered).toFixed(1)}%)`);
        assert.ok(c.covered > 0.03, `${what}: the model covers ${c.covered}`);
        assert.ok(c.masked >= BAR, `${what} (frame ${f}): SSIM over the model ${c.masked} below ${BAR}`);
        if (control) {
          const g = (f + 2) % info.frames, k = compare(s, await reference(g));
          lines.push(`against frame ${g}: ${k.masked.toFixed(4)}`);
          assert.ok(k.masked < BAR, `${what}: against frame ${g} too, SSIM ${k.masked}`);
        }
      }
      // (1) Paused at a frame between keyframes.
      const f1 = Math.min(info.frames - 1, 8 * Math.floor(info.frames / 16) + 5);
      {
        const { page, context, errors } = await open(`asset=${asset}&budget=${full}&frame=${f1}&gpuskin=1`);
        await check("paused", page, errors, f1, true);
        await context.close();
      }
      // (2) Played, then paused; (3) the budget dropped and raised while playing, then paused.
      for (const kind of ["played", "budget"]) {
        const { page, context, errors } = await open(`asset=${asset}&budget=${full}&gpuskin=1`);
        await page.waitForFunction((n) => Number(document.getElementById("overlay").dataset.shown) >= n, 40, { timeout: 120_000 });
        if (kind === "budget") {
          const set = (v) => page.$eval("#budget", (e, v) => { e.value = String(v); e.dispatchEvent(new Event("input")); }, v);
          await set(Math.round(full / 3));
          const shown = Number(await page.$eval("#overlay", (e) => e.dataset.shown));
          await page.waitForFunction((n) => Number(document.getElementById("overlay").dataset.shown) >= n, shown + 20, { timeout: 120_000 });
          await set(full);
          await page.waitForFunction((n) => Number(document.getElementById("overlay").dataset.shown) >= n, shown + 40, { timeout: 120_000 });
        }
        await page.click("#play");
        const f = Number(await page.$eval("#overlay", (e) => e.dataset.frame));
        await check(kind, page, errors, f);
        await context.close();
      }
      results.push([name, null]);
      console.log(`ok - ${name}: ${lines.join("; ")}`);
    } catch (e) {
      results.push([name, e]);
      console.log(`not ok - ${name}\n  ${String(e?.stack ?? e).split("\n").slice(0, 4).join("\n  ")}`);
    }
  }
} finally {
  await browser?.close();
  server.kill("SIGTERM");
  rmSync(work, { recursive: true, force: true });
}
const failed = results.filter(([, e]) => e);
console.log(`skin-e2e: ${results.length - failed.length} passed, ${failed.length} failed`);
if (failed.length || results.length === 0) process.exit(1);
