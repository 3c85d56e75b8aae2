// Node throughput of the TypeScript decoder (a benchmark, not a test), at full resolution over
// every frame of a .pmc, `loops` times (default 3):
//   - decode: the Decoder (src/container/decode.ts) alone (what the Rust bench decode_horse_48_frames measures);
//   - worker path: what the player's worker does per frame (src/player/session.ts): decode, cut
//     at the full triangle count, gather the cut's vertices, normals.
// Prints frames per second and the container bytes per second that makes (bytes of the file's
// chunks read per frame, over the time per frame).
//   npx tsc -p tsconfig.test.json && node bench/decode.mjs /path/to/horse-gallop.pmc [loops]
import { readFileSync } from "node:fs";
import { Decoder, Reader } from "../build-test/src/container/index.js";
import { Session } from "../build-test/src/player/session.js";

const path = process.argv[2];
if (!path) { console.error("usage: node bench/decode.mjs FILE.pmc [loops]"); process.exit(2); }
const loops = Number(process.argv[3] ?? 3);
const file = new Uint8Array(readFileSync(path));
const c = await Reader.open(async (o, n) => file.subarray(o, o + n), file.length);
const h = c.header;
console.log(`${path}: ${h.vertexCount} vertices, ${h.triangleCount} triangles, ${h.frameCount} frames, ${file.length} bytes`);

// Decode only. The first loop warms the JIT and is not counted.
{
  const player = new Decoder(c, 0);
  for (let f = 0; f < h.frameCount; f++) await player.seek(f);
  const read0 = c.bytesRead, t0 = performance.now();
  for (let l = 0; l < loops; l++) for (let f = 0; f < h.frameCount; f++) await player.seek(f);
  const s = (performance.now() - t0) / 1000, frames = loops * h.frameCount;
  console.log(`decode: ${(frames / s).toFixed(1)} frames/s (${((1000 * s) / frames).toFixed(2)} ms/frame), ${((c.bytesRead - read0) / s / 1e6).toFixed(2)} MB/s of container`);
}

// The worker's path.
{
  const session = await Session.open(async (a, b) => ({ bytes: file.slice(a, Math.min(b, file.length)), total: file.length }), { readAhead: 0 });
  for (let f = 0; f < h.frameCount; f++) await session.frame(f);
  const t0 = performance.now();
  let decode = 0, cut = 0;
  for (let l = 0; l < loops; l++) for (let f = 0; f < h.frameCount; f++) { const p = await session.frame(f); decode += p.decodeMs; cut += p.cutMs; }
  const s = (performance.now() - t0) / 1000, frames = loops * h.frameCount;
  console.log(`worker path: ${(frames / s).toFixed(1)} frames/s (${((1000 * s) / frames).toFixed(2)} ms/frame: decode ${(decode / frames).toFixed(2)}, cut+normals ${(cut / frames).toFixed(2)})`);
}
