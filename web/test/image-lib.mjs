// What the image tests of issue 16 share (test/appearance-e2e.mjs, test/simplified-ssim.mjs):
// SSIM of two renders and a static host with range requests for the built pages and the
// streams.
import { createServer } from "node:http";
import { existsSync, readFileSync, statSync } from "node:fs";
import { extname, join, normalize } from "node:path";

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

export function host(mounts) {
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

