// Node throughput of the TypeScript decoder (a benchmark, not a test): decodes every frame of a
// .pmc at full resolution, twice over, and cuts each at the full triangle count, as the player's
// worker does. Prints frames per second and the container bytes per second that makes.
//   npx tsc -p tsconfig.test.json && node bench/decode.mjs /path/to/horse-gallop.pmc
import { readFileSync } from "node:fs";
import { Container, Player } from "../build-test/src/container.js";

const path = process.argv[2];
if (!path) { console.error("usage: node bench/decode.mjs FILE.pmc"); process.exit(2); }
const file = readFileSync(path);
let reads = 0;
const c = await Container.open(async (o, n) => { reads++; return file.subarray(o, o + n); }, file.length);
const h = c.header;
const loops = Number(process.argv[3] ?? 3);
let t0 = performance.now(), frames = 0, cutMs = 0;
const player = new Player(c, 0);
reads = 0;
for (let l = 0; l < loops; l++) {
  for (let f = 0; f < h.frameCount; f++) {
    await player.seek(f);
    const t1 = performance.now();
    const pos = player.positions();
    player.replay.selectTriangles(h.triangleCount, player.replay.nodeErrors(pos));
    cutMs += performance.now() - t1;
    frames++;
  }
}
const ms = performance.now() - t0;
const perLoop = c.bytesRead / loops;
console.log(`${path}: ${h.vertexCount} vertices, ${h.frameCount} frames, ${file.length} bytes`);
console.log(`decode+cut: ${(frames / (ms / 1000)).toFixed(1)} frames/s (${(ms / frames).toFixed(2)} ms/frame, of which positions+cut ${(cutMs / frames).toFixed(2)} ms)`);
console.log(`chunk reads per frame: ${(reads / frames).toFixed(1)}; container bytes decoded: ${((c.bytesRead / (ms / 1000)) / 1e6).toFixed(2)} MB/s`);
