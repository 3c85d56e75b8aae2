// Playback measurements of the viewer in headless Chromium (a benchmark, not a test; the bars
// of issue 18). Starts `pmcodec serve --assets DIR` with the viewer in web/dist, then:
//   1. frame rate at full resolution on loopback, over 10 s after the first second, with the
//      page thread's work per displayed frame (the player's own timing) and Long Tasks;
//   2. the same with 50 ms of latency on every request (CDP Network.emulateNetworkConditions);
//   3. bytes: over those seconds (several loops), whether any byte of the container was fetched
//      twice, from the server's request log;
//   4. bytes per frame after lowering the budget from full to 10% during playback;
//   5. median time from a seek to the first drawn frame of the new position, 20 random seeks.
//   With GPUSKIN=1,0 (skinned assets), 0 and 1 before the rest: the paused draw rate and the
//   loopback rate with the worker posing every vertex (?gpuskin=0) and with GPU skinning, in one run
//   (SKIN_ONLY=1: only those).
// Usage (from web/, after npm run build):
//   npx tsc -p tsconfig.test.json && node bench/play.mjs ASSETS_DIR [ASSET_ID]
// (PMCODEC_BIN: the server binary; ASSETS_DIR/ASSET_ID.pmc is read to map bytes to frames.)
import { readFileSync } from "node:fs";
import { Reader } from "../build-test/src/container/index.js";
import { launch, ready, root, serve, sleep } from "../test/harness.mjs";

const dir = process.argv[2];
const asset = process.argv[3] ?? "horse-gallop";
if (!dir) { console.error("usage: node bench/play.mjs ASSETS_DIR [ASSET_ID]"); process.exit(2); }
const bin = process.env.PMCODEC_BIN ?? `${root}/target/release/pmcodec`;
const host = serve(bin, ["--assets", dir, "--viewer", `${root}/web/dist`], { from: 19000, capture: true });
const { server, base } = host;
// VIEWPORT=WxH (default 960x640): a small one shows the rate when software rasterization is cheap.
const [VW, VH] = (process.env.VIEWPORT ?? "960x640").split("x").map(Number);
let browser;
try {
  await ready(base, 100_000);
  const info = await (await fetch(`${base}/v1/assets/${asset}`)).json();
  browser = await launch();
  const stat = (page) => page.$eval("#overlay", (e) => ({ frame: Number(e.dataset.frame), shown: Number(e.dataset.shown), mainMs: Number(e.dataset.mainMs), bytes: Number(e.dataset.bytes), requests: Number(e.dataset.requests), stalls: Number(e.dataset.stalls), renderMs: Number(e.dataset.renderMs), draws: Number(e.dataset.draws), workerMs: Number(e.dataset.workerMs) }));
  async function openPage(query, latency) {
    const context = await browser.newContext({ viewport: { width: VW, height: VH } });
    const page = await context.newPage();
    await page.addInitScript(() => {
      window.__long = 0;
      new PerformanceObserver((l) => { for (const e of l.getEntries()) window.__long += e.duration; }).observe({ type: "longtask", buffered: true });
    });
    if (latency) {
      const cdp = await context.newCDPSession(page);
      await cdp.send("Network.enable");
      await cdp.send("Network.emulateNetworkConditions", { offline: false, latency, downloadThroughput: -1, uploadThroughput: -1 });
    }
    await page.goto(`${base}/?${query}`);
    await page.waitForFunction(() => Number(document.getElementById("overlay")?.dataset.shown ?? 0) > 0, null, { timeout: 120_000 });
    return { page, context };
  }
  async function rate(latency, extra = "") {
    const logStart = host.log.length;
    const { page, context } = await openPage(`asset=${asset}&budget=${info.triangles}${extra}`, latency);
    await sleep(1000);
    const a = await stat(page), la = await page.evaluate(() => window.__long);
    await sleep(10_000);
    const b = await stat(page), lb = await page.evaluate(() => window.__long);
    // Bytes are counted over three whole loops at least.
    if (!latency) await page.waitForFunction((n) => Number(document.getElementById("overlay")?.dataset.shown) >= n, 3 * info.frames + 1, { timeout: 300_000 });
    const loops = (await stat(page)).shown / info.frames;
    await context.close();
    const shown = b.shown - a.shown;
    return { fps: shown / 10, mainMsPerFrame: (b.mainMs - a.mainMs) / shown, workerMsPerFrame: (b.workerMs - a.workerMs) / shown, renderMs: (b.renderMs - a.renderMs) / (b.draws - a.draws), drawRate: (b.draws - a.draws) / 10, longTaskMsPerS: (lb - la) / 10, stalls: b.stalls - a.stalls, loops, bytes: b.bytes, requests: b.requests, logStart };
  }
  // Byte ranges the server answered for the container since `from` in its log.
  function ranges(from) {
    const out = [];
    for (const line of host.log.slice(from).split("\n")) {
      const m = /\/v\/[0-9a-f]+\/file range=bytes=(\d+)-(\d+) status=206/.exec(line);
      if (m) out.push([Number(m[1]), Math.min(Number(m[2]) + 1, info.bytes)]);
    }
    return out;
  }
  function twice(rs) {
    const seen = new Uint8Array(info.bytes);
    let again = 0, total = 0;
    for (const [s, e] of rs) for (let i = s; i < e; i++) { total++; if (seen[i]++) again++; }
    return { again, total };
  }

  // Which frame each fetched byte belongs to, from the container's index.
  const file = new Uint8Array(readFileSync(`${dir}/${asset}.pmc`));
  const container = await Reader.open(async (o, n) => file.subarray(o, o + n), file.length);
  function perFrame(rs) {
    const out = new Float64Array(info.frames);
    for (const e of container.index) {
      const a = container.dataStart + e.offset, b = a + e.storedLen;
      for (const [s, t] of rs) { const o = Math.min(b, t) - Math.max(a, s); if (o > 0) out[e.frame] += o; }
    }
    return out;
  }

  // Before and after GPU skinning, in the same run (the machine's load changes between runs).
  for (const mode of (process.env.GPUSKIN ?? "").split(",").filter((m) => m === "0" || m === "1")) {
    const q = `&gpuskin=${mode}`;
    const { page, context } = await openPage(`asset=${asset}&budget=${info.triangles}&frame=0${q}`, 0);
    await sleep(1000);
    const n = await page.evaluate(() => new Promise((res) => { let n = 0; const t0 = performance.now(); const tick = () => { n++; if (performance.now() - t0 < 5000) requestAnimationFrame(tick); else res(n); }; requestAnimationFrame(tick); }));
    await context.close();
    const r = await rate(0, q);
    console.log(`gpuskin=${mode}: paused draw rate ${(n / 5).toFixed(1)} frames/s; playing ${r.fps.toFixed(1)} frames/s (asset ${info.frame_rate}), ${r.stalls} stalls, page thread ${r.mainMsPerFrame.toFixed(2)} ms and worker ${r.workerMsPerFrame.toFixed(2)} ms per displayed frame, three.js's render call ${r.renderMs.toFixed(1)} ms per draw (${r.drawRate.toFixed(1)} draws/s), long tasks ${r.longTaskMsPerS.toFixed(0)} ms/s`);
  }

  if (process.env.SKIN_ONLY) { await browser.close(); server.kill("SIGTERM"); process.exit(0); }
  // The page's draw rate while paused, for scale (software rendering: the renderer's ceiling).
  {
    const { page, context } = await openPage(`asset=${asset}&budget=${info.triangles}&frame=0`, 0);
    await sleep(1000);
    const n = await page.evaluate(() => new Promise((res) => { let n = 0; const t0 = performance.now(); const tick = () => { n++; if (performance.now() - t0 < 5000) requestAnimationFrame(tick); else res(n); }; requestAnimationFrame(tick); }));
    await context.close();
    console.log(`paused draw rate: ${(n / 5).toFixed(1)} frames/s`);
  }

  const loop = await rate(0);
  await sleep(300);
  const rs = ranges(loop.logStart), tw = twice(rs);
  console.log(`loopback: ${loop.fps.toFixed(1)} frames/s at full resolution (${info.triangles} triangles), ${loop.stalls} stalls, page thread ${loop.mainMsPerFrame.toFixed(2)} ms per displayed frame in the player, worker ${loop.workerMsPerFrame.toFixed(2)} ms (three.js's render call: ${loop.renderMs.toFixed(1)} ms per draw, ${loop.drawRate.toFixed(1)} draws/s), long tasks ${loop.longTaskMsPerS.toFixed(0)} ms/s`);
  console.log(`bytes: ${loop.loops.toFixed(1)} loops, ${rs.length} range requests, ${tw.total} bytes of ${info.bytes}, bytes fetched more than once: ${tw.again}`);
  const slow = await rate(50);
  console.log(`50 ms latency: ${slow.fps.toFixed(1)} frames/s, ${slow.stalls} stalls, page thread ${slow.mainMsPerFrame.toFixed(2)} ms per displayed frame`);

  // Budget: full, then 10% during the first frames; container bytes per frame fetched for the
  // frames from one keyframe interval after the drop on (one interval's worth), against the same
  // frames at full resolution (the first run's fetches), both from the server's log mapped to
  // frames through the container's index.
  const full = perFrame(rs);
  const from = host.log.length;
  const { page: bp, context: bc } = await openPage(`asset=${asset}&budget=${info.triangles}`, 0);
  // The frame on screen when the budget drops, read in the same task that drops it.
  const dropAt = await bp.$eval("#budget", (e, v) => { e.value = String(v); e.dispatchEvent(new Event("input")); return Number(document.getElementById("overlay").dataset.frame); }, Math.round(info.triangles / 10));
  await bp.waitForFunction(() => Number(document.getElementById("overlay")?.dataset.frame) >= 47, null, { timeout: 60_000 });
  await sleep(500);
  await bc.close();
  const low = perFrame(ranges(from));
  // One keyframe interval after the drop (bytes read ahead before it may reach past the next
  // keyframe), the next keyframe interval's frames.
  const k = info.keyframe_interval, next = dropAt + k;
  let sumFull = 0, sumLow = 0;
  for (let f = next; f < Math.min(info.frames, next + k); f++) { sumFull += full[f]; sumLow += low[f]; }
  if (process.env.VERBOSE) console.log(`per frame, full: ${Array.from(full).join(" ")}\nper frame, lowered: ${Array.from(low).join(" ")}`);
  console.log(`budget: lowered to 10% at frame ${dropAt}; frames ${next}-${Math.min(info.frames, next + k) - 1}: ${(sumLow / k).toFixed(0)} B/frame against ${(sumFull / k).toFixed(0)} at full resolution (${((100 * sumLow) / sumFull).toFixed(1)}%)`);

  // Seeks: paused at frame 0, 20 random targets through the frame slider.
  const { page, context } = await openPage(`asset=${asset}&budget=${info.triangles}&frame=0`, 0);
  const times = [], fulls = [];
  let seed = 12345;
  for (let i = 0; i < 20; i++) {
    seed = (seed * 1103515245 + 12345) % 2147483648;
    let f = seed % info.frames;
    if (f === (await stat(page)).frame) f = (f + 1) % info.frames;
    const [first, whole] = await page.evaluate(([f, full]) => new Promise((res) => {
      const slider = document.getElementById("frame"), o = document.getElementById("overlay");
      const t0 = performance.now();
      let shown = -1;
      slider.value = String(f);
      slider.dispatchEvent(new Event("input"));
      // The rAF callback that shows a frame also renders it: first the coarse cut, then the budget's.
      const poll = () => {
        const now = performance.now();
        if (Number(o.dataset.frame) === f && shown < 0) shown = now - t0;
        if (Number(o.dataset.frame) === f && Number(o.dataset.triangles) >= full * 0.98) res([shown, now - t0]);
        else requestAnimationFrame(poll);
      };
      requestAnimationFrame(poll);
    }), [f, info.triangles]);
    times.push(first);
    fulls.push(whole);
  }
  await context.close();
  times.sort((a, b) => a - b);
  fulls.sort((a, b) => a - b);
  console.log(`seek: median ${times[10].toFixed(0)} ms to the first drawn frame (min ${times[0].toFixed(0)}, max ${times[19].toFixed(0)}), ${fulls[10].toFixed(0)} ms to the full-resolution cut, 20 random seeks`);
} finally {
  await browser?.close();
  server.kill("SIGTERM");
}
