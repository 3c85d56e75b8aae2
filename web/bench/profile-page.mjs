// Where a viewer's time goes while it plays an asset at full resolution (a benchmark, not a
// test): frames advanced and container range requests over 10 s, animation frames per second
// playing and paused, Long Tasks, and how long a 1 KB range fetch issued from the page waits.
// Works against any build of the viewer that shows #overlay with data-frame (this one, and the
// viewer before issue 18). Against a running server (e.g. pmcodec serve --assets DIR):
//   node bench/profile-page.mjs http://127.0.0.1:8080 horse-gallop
import { launch } from "../test/harness.mjs";

const [base, asset = "horse-gallop"] = process.argv.slice(2);
if (!base) { console.error("usage: node bench/profile-page.mjs BASE_URL [ASSET_ID]"); process.exit(2); }
const info = await (await fetch(`${base}/v1/assets/${asset}`)).json();
const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 960, height: 640 } });
  let requests = 0;
  page.on("request", (r) => { if (r.url().includes("/v/")) requests++; });
  await page.goto(`${base}/?asset=${asset}&budget=${info.triangles}`);
  await page.waitForFunction(() => Number(document.getElementById("overlay")?.dataset.triangles ?? 0) > 0, null, { timeout: 120_000 });
  // The viewer before issue 18 takes the budget from its slider only (on change).
  await page.$eval("#budget", (e, n) => { e.max = String(n); e.value = String(n); e.dispatchEvent(new Event("change")); e.dispatchEvent(new Event("input")); }, info.triangles);
  await page.waitForTimeout(3000);
  const frame = () => page.$eval("#overlay", (e) => Number(e.dataset.frame));
  const f0 = await frame(), r0 = requests, t0 = Date.now();
  const playing = await page.evaluate(async (url) => {
    let n = 0, long = 0;
    const start = performance.now();
    new PerformanceObserver((l) => { for (const e of l.getEntries()) long += e.duration; }).observe({ type: "longtask" });
    const waits = [];
    const fetches = (async () => {
      for (let i = 0; i < 10; i++) { const s = performance.now(); await (await fetch(url, { headers: { Range: "bytes=0-1023" } })).arrayBuffer(); waits.push(performance.now() - s); }
    })();
    await new Promise((res) => { const tick = () => { n++; if (performance.now() - start < 10_000) requestAnimationFrame(tick); else res(); }; requestAnimationFrame(tick); });
    await fetches;
    waits.sort((a, b) => a - b);
    return { rafPerS: n / 10, longTaskMsPerS: long / 10, fetchMedianMs: waits[5] };
  }, new URL(info.file, base).href);
  const seconds = (Date.now() - t0) / 1000, advanced = ((await frame()) - f0 + info.frames) % info.frames;
  await page.click("#play");
  await page.waitForTimeout(2000);
  const paused = await page.evaluate(async () => { let n = 0; const s = performance.now(); await new Promise((res) => { const tick = () => { n++; if (performance.now() - s < 5000) requestAnimationFrame(tick); else res(); }; requestAnimationFrame(tick); }); return n / 5; });
  console.log(`playing ${info.triangles} triangles: ${advanced} frames advanced (mod ${info.frames}) in ${seconds.toFixed(1)} s, ${requests - r0} container requests`);
  console.log(`page: ${playing.rafPerS.toFixed(1)} animation frames/s playing, ${paused.toFixed(1)} paused; long tasks ${playing.longTaskMsPerS.toFixed(0)} ms per second; a 1 KB range fetch from the page: median ${playing.fetchMedianMs.toFixed(0)} ms`);
  console.log(`overlay: ${(await page.textContent("#overlay")).replace(/\n/g, " | ")}`);
} finally {
  await browser.close();
}
