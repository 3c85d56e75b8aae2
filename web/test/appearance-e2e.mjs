// The appearance bar of issue 16: every GLB in ../shared/data/gltf (Fox, RobotExpressive, Horse,
// the Draco-compressed Parrot) encoded with the CLI, its stream's frame 0 drawn at full
// resolution by pmcodec-three (web/compare.html) beside the GLB drawn by three.js's own
// GLTFLoader (with its DRACOLoader) in the first animation's pose at time 0, one camera, the
// same lights and environment. The two images' SSIM must be at least 0.97. Both images of each
// model are saved under web/test-artifacts/appearance/ (the path is printed). The page also
// switches the colour mode to "level" and back: the picture changes, then comes back exactly.
// Usage: node test/appearance-e2e.mjs [Model ...]   (default: every .glb in ../shared/data/gltf)
// Needs: web/dist (npm run build), the pmcodec binary (PMCODEC_BIN, default target/debug/pmcodec),
// Debian's chromium at /usr/bin/chromium.
import { chromium } from "playwright-core";
import { execFileSync } from "node:child_process";
import { createServer } from "node:http";
import { existsSync, mkdirSync, mkdtempSync, readdirSync, readFileSync, rmSync, statSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { extname, join, normalize } from "node:path";
import assert from "node:assert/strict";

const root = new URL("../..", import.meta.url).pathname;
const bin = process.env.PMCODEC_BIN ?? `${root}/target/debug/pmcodec`;
const models = join(root, "../shared/data/gltf");
const SIZE = 256;
const BAR = 0.97;

// ---- SSIM ----------------------------------------------------------------------------------
// Z. Wang, A. C. Bovik, H. R. Sheikh and E. P. Simoncelli, "Image Quality Assessment: From Error
// Visibility to Structural Similarity", IEEE Transactions on Image Processing, 2004: local means,
// variances and covariance under an 11x11 circular-symmetric Gaussian window (sigma 1.5), on
// luminance (Rec. 601 weights of 8-bit sRGB), C1 = (0.01 L)^2, C2 = (0.03 L)^2, L = 255; the
// mean of the SSIM map over every window that fits in the image.

/** 8-bit luminance of RGBA pixels. */
export function luminance(rgba, w, h) {
  const y = new Float64Array(w * h);
  for (let i = 0; i < w * h; i++) y[i] = 0.299 * rgba[4 * i] + 0.587 * rgba[4 * i + 1] + 0.114 * rgba[4 * i + 2];
  return y;
}

/** Separable Gaussian filter, "valid" windows only: an (w-10) x (h-10) image. */
function gauss(img, w, h) {
  const r = 5, k = [];
  let s = 0;
  for (let i = -r; i <= r; i++) { const v = Math.exp(-(i * i) / (2 * 1.5 * 1.5)); k.push(v); s += v; }
  for (let i = 0; i < k.length; i++) k[i] /= s;
  const ow = w - 2 * r, oh = h - 2 * r, tmp = new Float64Array(ow * h), out = new Float64Array(ow * oh);
  for (let y = 0; y < h; y++) for (let x = 0; x < ow; x++) { let a = 0; for (let i = 0; i <= 2 * r; i++) a += k[i] * img[y * w + x + i]; tmp[y * ow + x] = a; }
  for (let y = 0; y < oh; y++) for (let x = 0; x < ow; x++) { let a = 0; for (let i = 0; i <= 2 * r; i++) a += k[i] * tmp[(y + i) * ow + x]; out[y * ow + x] = a; }
  return out;
}

/** Mean SSIM of two luminance images, and the mean over the windows `mask` marks (if given). */
export function ssim(a, b, w, h, mask = null) {
  const C1 = (0.01 * 255) ** 2, C2 = (0.03 * 255) ** 2;
  const sq = (x) => x.map((v) => v * v), mul = (x, y) => x.map((v, i) => v * y[i]);
  const ma = gauss(a, w, h), mb = gauss(b, w, h), saa = gauss(sq(a), w, h), sbb = gauss(sq(b), w, h), sab = gauss(mul(a, b), w, h);
  const mw = mask ? gauss(mask, w, h) : null;
  let sum = 0, n = 0, msum = 0, mn = 0;
  for (let i = 0; i < ma.length; i++) {
    const va = saa[i] - ma[i] * ma[i], vb = sbb[i] - mb[i] * mb[i], cov = sab[i] - ma[i] * mb[i];
    const v = ((2 * ma[i] * mb[i] + C1) * (2 * cov + C2)) / ((ma[i] * ma[i] + mb[i] * mb[i] + C1) * (va + vb + C2));
    sum += v; n++;
    if (mw && mw[i] > 0) { msum += v; mn++; }
  }
  return { ssim: sum / n, masked: mn > 0 ? msum / mn : 1, windows: mn };
}

// ---- a static host with range requests -------------------------------------------------------
const TYPES = { ".html": "text/html", ".js": "text/javascript", ".css": "text/css", ".wasm": "application/wasm", ".glb": "model/gltf-binary", ".pmc": "application/octet-stream", ".svg": "image/svg+xml", ".json": "application/json" };

function host(mounts) {
  return createServer((req, res) => {
    const path = decodeURIComponent(new URL(req.url, "http://x").pathname);
    const mount = Object.keys(mounts).sort((a, b) => b.length - a.length).find((m) => path.startsWith(m));
    const file = mount !== undefined ? normalize(join(mounts[mount], path.slice(mount.length))) : null;
    if (!file || !file.startsWith(mounts[mount]) || !existsSync(file) || !statSync(file).isFile()) { res.writeHead(404); res.end(); return; }
    const body = readFileSync(file);
    const headers = { "Content-Type": TYPES[extname(file)] ?? "application/octet-stream", "Accept-Ranges": "bytes" };
    const m = /^bytes=(\d+)-(\d*)$/.exec(req.headers.range ?? "");
    if (m) {
      const s = Number(m[1]), e = Math.min(m[2] ? Number(m[2]) + 1 : body.length, body.length);
      if (s >= body.length) { res.writeHead(416, { "Content-Range": `bytes */${body.length}` }); res.end(); return; }
      res.writeHead(206, { ...headers, "Content-Range": `bytes ${s}-${e - 1}/${body.length}`, "Content-Length": e - s });
      res.end(body.subarray(s, e));
    } else {
      res.writeHead(200, { ...headers, "Content-Length": body.length });
      res.end(body);
    }
  });
}

// ---- the test -------------------------------------------------------------------------------
const names = process.argv.slice(2).length ? process.argv.slice(2) : readdirSync(models).filter((f) => f.endsWith(".glb")).map((f) => f.replace(/\.glb$/, "")).sort();
for (const want of ["Fox", "RobotExpressive", "Horse", "Parrot"]) {
  if (process.argv.length <= 2) assert.ok(names.includes(want), `${models}/${want}.glb is missing: this test reads the shared models beside the repository`);
}
const work = mkdtempSync(join(tmpdir(), "pmc-appearance-"));
const artifacts = join(root, "web/test-artifacts/appearance");
mkdirSync(artifacts, { recursive: true });
for (const name of names) execFileSync(bin, ["encode", "-q", join(models, `${name}.glb`), "-o", join(work, `${name}.pmc`)]);
const server = host({ "/": join(root, "web/dist") + "/", "/draco/": join(root, "web/node_modules/three/examples/jsm/libs/draco") + "/", "/models/": models + "/", "/streams/": work + "/" });
await new Promise((r) => server.listen(0, "127.0.0.1", r));
const base = `http://127.0.0.1:${server.address().port}`;
let browser;
const results = [];
try {
  browser = await chromium.launch({
    executablePath: "/usr/bin/chromium",
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync"],
  });
  // One page for every model: three.js compiles the materials' shaders once per renderer.
  const page = await browser.newPage({ viewport: { width: 2 * SIZE + 40, height: SIZE + 120 } });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  page.on("console", (m) => { if (process.env.PMCODEC_E2E_CONSOLE) console.log(`  [console] ${m.text()}`); });
  await page.goto(`${base}/compare.html?size=${SIZE}`, { waitUntil: "commit" });
  await page.waitForFunction(() => document.getElementById("status")?.dataset.ready === "1", null, { timeout: 120_000 });
  for (const name of names) {
    try {
      const t0 = Date.now();
      errors.length = 0;
      const status = await page.evaluate(([pmc, glb]) => window.pmcodecCompare(pmc, glb), [`/streams/${name}.pmc`, `/models/${name}.glb`]);
      assert.ok(!status.error, `${name}: ${status.error}`);
      assert.deepEqual(errors, [], `${name}: errors on the page`);
      // Both canvases' pixels (top row first, as the PNGs) and PNGs of them.
      const shots = await page.evaluate(() => ["stream", "reference", "level"].map((id) => {
        const c = document.getElementById(id), w = c.width, h = c.height;
        const px = c.getContext("2d").getImageData(0, 0, w, h).data;
        let s = "";
        for (let i = 0; i < px.length; i += 0x8000) s += String.fromCharCode(...px.subarray(i, i + 0x8000));
        return { w, h, rgba: btoa(s), png: c.toDataURL("image/png") };
      }));
      const [a, b, c] = shots.map((s) => ({ ...s, rgba: Buffer.from(s.rgba, "base64") }));
      for (const [s, kind] of [[a, "stream"], [b, "three"], [c, "stream-level"]]) writeFileSync(join(artifacts, `${name}-${kind}.png`), Buffer.from(s.png.split(",")[1], "base64"));
      assert.equal(a.w, SIZE);
      const ya = luminance(a.rgba, a.w, a.h), yb = luminance(b.rgba, b.w, b.h);
      // The model's pixels: either image differs from the background there.
      const bg = [0x1d, 0x20, 0x26], mask = new Float64Array(a.w * a.h);
      let covered = 0;
      for (let i = 0; i < mask.length; i++) {
        const off = (px) => Math.abs(px[4 * i] - bg[0]) + Math.abs(px[4 * i + 1] - bg[1]) + Math.abs(px[4 * i + 2] - bg[2]) > 6;
        if (off(a.rgba) || off(b.rgba)) { mask[i] = 1; covered++; }
      }
      const s = ssim(ya, yb, a.w, a.h, mask);
      // A control: the same stream coloured by level (no materials) against the reference.
      const control = ssim(luminance(c.rgba, c.w, c.h), yb, a.w, a.h, mask);
      const line = `${name}: SSIM ${s.ssim.toFixed(4)} (over the model's windows ${s.masked.toFixed(4)}; model covers ${(100 * covered / mask.length).toFixed(1)}% of ${a.w}x${a.h}; coloured by level instead: ${control.ssim.toFixed(4)}, ${control.masked.toFixed(4)}), ${status.triangles} triangles (GLB ${status.referenceTriangles}), ${status.materials} materials, ${status.textured} textured (GLB ${status.referenceTextured}), animation "${status.animation}"; ${Date.now() - t0} ms (page: ${status.ms} ms to set up, load the GLB, show the frame, render)`;
      assert.ok(covered > mask.length * 0.05, `${name}: the model covers only ${covered} pixels`);
      assert.ok(Number(status.appearance) === 1, `${name}: the stream carries no appearance`);
      assert.equal(Number(status.textured) > 0, Number(status.referenceTextured) > 0, `${name}: textured in one image only`);
      // The colour toggle: flat colour by level changes the picture; back to authored restores it.
      assert.ok(Number(status.toggleChanged) > covered * 0.2, `${name}: colour by level changed only ${status.toggleChanged} of ${covered} pixels`);
      assert.equal(Number(status.toggleBack), 0, `${name}: back to authored, ${status.toggleBack} pixels differ`);
      assert.ok(s.ssim >= BAR, `${line}: below the bar ${BAR}`);
      // And the bar tells a drawing with the stream's materials from one without.
      assert.ok(control.ssim < BAR, `${line}: coloured by level, the stream passes the bar too`);
      results.push([name, null]);
      console.log(`ok - ${line}`);
    } catch (e) {
      results.push([name, e]);
      console.log(`not ok - ${name}\n  ${String(e?.stack ?? e).split("\n").slice(0, 4).join("\n  ")}`);
    }
  }
} finally {
  await browser?.close();
  server.close();
  rmSync(work, { recursive: true, force: true });
}
console.log(`appearance-e2e: images in ${artifacts}`);
const failed = results.filter(([, e]) => e);
console.log(`appearance-e2e: ${results.length - failed.length} passed, ${failed.length} failed`);
if (failed.length || results.length === 0) process.exit(1);
