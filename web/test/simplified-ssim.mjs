// The image-error bar of issue 16: at 25% and 10% of the triangles, each shared GLB's stream
// (`pmcodec encode --animation A`, one stream per animation) against the full GLB, beside the
// GLB simplified once in its bind pose by meshoptimizer's simplifyWithAttributes to the same
// share and animated as authored (what a user gets today without pmcodec); SSIM (test/
// image-lib.mjs) over the windows on the model's pixels, at FRAMES frames of every animation (web/compare.html,
// `pmcodecSimplified`). The bar: our mean SSIM above meshoptimizer's at both shares on every
// model. Prints a table per model and share; exits 1 when the bar is missed.
// Usage: node test/simplified-ssim.mjs [Model ...]   env: FRAMES (per animation, default 4),
//   ANIMATIONS (at most this many per model, default all), PMCODEC_BIN, SIZE (default 256).
// Needs: web/dist (npm run build), the pmcodec binary, Debian's chromium at /usr/bin/chromium.
// Images of the first frame of each animation: web/test-artifacts/simplified/.
import { execFileSync } from "node:child_process";
import { mkdirSync, mkdtempSync, readdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { launch, root } from "./harness.mjs";
import { host, luminance, ssim } from "./image-lib.mjs";

const bin = process.env.PMCODEC_BIN ?? `${root}/target/debug/pmcodec`;
const models = join(root, "../shared/data/gltf");
const SIZE = Number(process.env.SIZE ?? 256);
const FRAMES = Number(process.env.FRAMES ?? 4);
const MAX_ANIMATIONS = Number(process.env.ANIMATIONS ?? Infinity);
const SHARES = [0.25, 0.1];

/** The animations of a GLB, from its JSON chunk. */
function animations(path) {
  const b = readFileSync(path);
  const len = b.readUInt32LE(12);
  const json = JSON.parse(b.subarray(20, 20 + len).toString("utf8"));
  return (json.animations ?? []).map((a, i) => a.name ?? `#${i}`);
}

/** A minimal PNG (RGBA, no filter, stored zlib blocks) of `rgba` rows, for the artifacts. */
function png(rgba, w, h) {
  const crcTable = Array.from({ length: 256 }, (_, n) => { let c = n; for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1; return c >>> 0; });
  const crc = (buf) => { let c = 0xffffffff; for (const x of buf) c = crcTable[(c ^ x) & 0xff] ^ (c >>> 8); return (c ^ 0xffffffff) >>> 0; };
  const chunk = (type, data) => { const out = Buffer.alloc(12 + data.length); out.writeUInt32BE(data.length, 0); out.write(type, 4, "latin1"); data.copy(out, 8); out.writeUInt32BE(crc(out.subarray(4, 8 + data.length)), 8 + data.length); return out; };
  const raw = Buffer.alloc(h * (4 * w + 1));
  for (let y = 0; y < h; y++) rgba.copy(raw, y * (4 * w + 1) + 1, y * 4 * w, (y + 1) * 4 * w);
  const blocks = [];
  for (let i = 0; i < raw.length; i += 65535) {
    const part = raw.subarray(i, Math.min(raw.length, i + 65535)), head = Buffer.alloc(5);
    head[0] = i + 65535 >= raw.length ? 1 : 0; head.writeUInt16LE(part.length, 1); head.writeUInt16LE(~part.length & 0xffff, 3);
    blocks.push(head, part);
  }
  let a = 1, b = 0;
  for (const x of raw) { a = (a + x) % 65521; b = (b + a) % 65521; }
  const adler = Buffer.alloc(4); adler.writeUInt32BE(((b << 16) | a) >>> 0);
  const ihdr = Buffer.alloc(13); ihdr.writeUInt32BE(w, 0); ihdr.writeUInt32BE(h, 4); ihdr[8] = 8; ihdr[9] = 6;
  return Buffer.concat([Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]), chunk("IHDR", ihdr), chunk("IDAT", Buffer.concat([Buffer.from([0x78, 0x01]), ...blocks, adler])), chunk("IEND", Buffer.alloc(0))]);
}

/** SSIM of `a` against the reference `r` over the pixels either image draws the model on. */
function score(a, r) {
  const bg = [0x1d, 0x20, 0x26], mask = new Float64Array(SIZE * SIZE);
  for (let i = 0; i < mask.length; i++) {
    const off = (px) => Math.abs(px[4 * i] - bg[0]) + Math.abs(px[4 * i + 1] - bg[1]) + Math.abs(px[4 * i + 2] - bg[2]) > 6;
    if (off(a) || off(r)) mask[i] = 1;
  }
  // Over the windows on the model (the background, the same in both, would pull every score
  // towards 1).
  return ssim(luminance(a, SIZE, SIZE), luminance(r, SIZE, SIZE), SIZE, SIZE, mask).masked;
}

const names = process.argv.slice(2).length ? process.argv.slice(2) : readdirSync(models).filter((f) => f.endsWith(".glb")).map((f) => f.replace(/\.glb$/, "")).sort();
const work = mkdtempSync(join(tmpdir(), "pmc-simplified-"));
const artifacts = join(root, "web/test-artifacts/simplified");
mkdirSync(artifacts, { recursive: true });
const server = host({ "/": join(root, "web/dist") + "/", "/draco/": join(root, "web/node_modules/three/examples/jsm/libs/draco") + "/", "/models/": models + "/", "/streams/": work + "/" });
await new Promise((r) => server.listen(0, "127.0.0.1", r));
const base = `http://127.0.0.1:${server.address().port}`;
const rows = [];
let browser;
try {
  browser = await launch();
  const page = await browser.newPage({ viewport: { width: 2 * SIZE + 40, height: SIZE + 120 } });
  page.on("pageerror", (e) => console.log(`  [page error] ${e}`));
  await page.goto(`${base}/compare.html?size=${SIZE}`, { waitUntil: "commit" });
  await page.waitForFunction(() => document.getElementById("status")?.dataset.ready === "1", null, { timeout: 120_000 });
  for (const name of names) {
    const glb = join(models, `${name}.glb`);
    const anims = animations(glb).slice(0, MAX_ANIMATIONS);
    const sums = SHARES.map(() => ({ ours: 0, meshopt: 0, n: 0, tris: 0, mtris: 0 }));
    for (const [a, anim] of anims.entries()) {
      const pmc = `${name}-${a}.pmc`;
      execFileSync(bin, ["encode", "-q", glb, "--animation", String(a), "-o", join(work, pmc)]);
      const t0 = Date.now();
      const r = await page.evaluate(([p, g, a, k, s]) => window.pmcodecSimplified(p, g, a, k, s), [`/streams/${pmc}`, `/models/${name}.glb`, a, FRAMES, SHARES]);
      if (r.error) throw new Error(`${name} animation ${a} (${anim}): ${r.error}`);
      const line = [];
      for (const img of r.images) {
        const [ref, ours, mo] = [img.reference, img.ours, img.meshopt].map((x) => Buffer.from(x, "base64"));
        const k = SHARES.indexOf(img.share);
        const so = score(ours, ref), sm = score(mo, ref);
        Object.assign(sums[k], { ours: sums[k].ours + so, meshopt: sums[k].meshopt + sm, n: sums[k].n + 1, tris: sums[k].tris + img.triangles, mtris: sums[k].mtris + img.meshoptTriangles });
        line.push(`f${img.frame}@${img.share * 100}% ${so.toFixed(3)}/${sm.toFixed(3)}`);
        if (img.frame === r.images[0].frame) {
          for (const [kind, buf] of [["reference", ref], ["ours", ours], ["meshopt", mo]]) writeFileSync(join(artifacts, `${name}-${a}-${img.share * 100}-${kind}.png`), png(buf, SIZE, SIZE));
        }
      }
      console.log(`  ${name} animation ${a} "${anim}" (${r.frames} frames, ${r.totalTriangles} triangles; ${Date.now() - t0} ms): ours/meshopt ${line.join(", ")}`);
    }
    for (const [k, share] of SHARES.entries()) {
      const s = sums[k];
      rows.push({ name, share, ours: s.ours / s.n, meshopt: s.meshopt / s.n, n: s.n, tris: s.tris / s.n, mtris: s.mtris / s.n, animations: anims.length });
    }
  }
} finally {
  await browser?.close();
  server.close();
  rmSync(work, { recursive: true, force: true });
}
console.log("\n| model | share | frames (animations) | our mean SSIM | meshopt mean SSIM | our triangles | meshopt triangles | ours higher |");
console.log("|---|---|---|---|---|---|---|---|");
for (const r of rows) console.log(`| ${r.name} | ${r.share * 100}% | ${r.n} (${r.animations}) | ${r.ours.toFixed(4)} | ${r.meshopt.toFixed(4)} | ${r.tris.toFixed(0)} | ${r.mtris.toFixed(0)} | ${r.ours > r.meshopt ? "yes" : "no"} |`);
console.log(`simplified-ssim: images in ${artifacts}`);
const missed = rows.filter((r) => !(r.ours > r.meshopt));
console.log(`simplified-ssim: ${rows.length - missed.length} of ${rows.length} (model, share) pairs above meshoptimizer`);
if (missed.length || rows.length === 0) process.exit(1);
