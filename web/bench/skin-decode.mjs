// The worker's CPU time per frame on a skinned stream, posing every vertex (the exact decoder)
// against GPU skinning (the decoder's skinned offsets; the session builds a cut's appearance
// once per cut), in Node, without a browser: what web/bench/play.mjs's worker figure holds
// without fetch waits and page load. Each mode plays the stream twice (the first loop warms up)
// and alternates with the other, ROUNDS times.
// Usage (from web/): npx tsc -p tsconfig.test.json && node bench/skin-decode.mjs FILE.pmc [authored|plain]
import { readFileSync } from "node:fs";
import { Session } from "../build-test/src/player/session.js";

const file = process.argv[2];
if (!file) { console.error("usage: node bench/skin-decode.mjs FILE.pmc [authored|plain]"); process.exit(2); }
const bytes = new Uint8Array(readFileSync(file));
const fetchRange = async (s, e) => ({ bytes: bytes.slice(s, Math.min(e, bytes.length)), total: bytes.length });
const rounds = Number(process.env.ROUNDS ?? 3), times = { false: [], true: [] };
for (let i = 0; i < rounds; i++) {
  for (const gpuSkin of [false, true]) {
    const s = await Session.open(fetchRange, { gpuSkin });
    s.colour = process.argv[3] ?? "authored";
    const n = s.container.header.frameCount;
    for (let f = 0; f < n; f++) await s.frame(f);
    let decode = 0, cut = 0;
    for (let f = 0; f < n; f++) { const p = await s.frame(f); decode += p.decodeMs; cut += p.cutMs; }
    times[gpuSkin].push({ decode: decode / n, cut: cut / n });
  }
}
for (const gpuSkin of [false, true]) {
  const t = times[gpuSkin].sort((a, b) => a.decode + a.cut - b.decode - b.cut)[Math.floor(rounds / 2)];
  console.log(`${gpuSkin ? "GPU skinning" : "posed by the worker"}: median of ${rounds}: ${(t.decode + t.cut).toFixed(2)} ms per frame (decode ${t.decode.toFixed(2)}, cut ${t.cut.toFixed(2)})`);
}
