// A generated many-material input for the size bar of issue 16 (scripts/attribute-sizes.mjs):
// a torus of W x H quads cut into irregular patches, each patch one of M materials (a
// primitive per material, as glTF has it), with texture coordinates per material in its own
// cell of an atlas (so every material boundary is a UV seam as well) and, optionally, vertex
// colours. Deterministic from the seed, so the figures reproduce; not one of the files in
// ../shared/data, so the coding is not tuned to those.
//
//   node scripts/many-materials-glb.mjs OUT.glb [materials=12] [seed=1] [uv|none] [colors|none]
import { createRequire } from 'node:module';

const require = createRequire(new URL('../tests/package.json', import.meta.url));
const { Document, NodeIO } = require('@gltf-transform/core');

const [out, mArg, seedArg, uvArg, colArg] = process.argv.slice(2);
if (!out) {
  console.error('usage: node scripts/many-materials-glb.mjs OUT.glb [materials] [seed] [uv|none] [colors|none]');
  process.exit(2);
}
const M = Number(mArg ?? 12);
let seed = Number(seedArg ?? 1) >>> 0 || 1;
const withUv = (uvArg ?? 'uv') !== 'none';
const withColors = (colArg ?? 'none') === 'colors';
const rnd = () => {
  // xorshift32
  seed ^= seed << 13; seed >>>= 0;
  seed ^= seed >>> 17;
  seed ^= seed << 5; seed >>>= 0;
  return seed / 4294967296;
};

const W = 64, H = 32, R = 1, r = 0.35;
// Patches: Voronoi cells of 3M random sites on the (u, v) torus, each cell a random material.
const sites = Array.from({ length: 3 * M }, () => [rnd() * W, rnd() * H, Math.floor(rnd() * M)]);
const wrapD = (a, b, n) => { const d = Math.abs(a - b) % n; return Math.min(d, n - d); };
const quadMaterial = (x, y) => {
  let best = 0, bd = Infinity;
  for (const [sx, sy, m] of sites) {
    const d = wrapD(x + 0.5, sx, W) ** 2 + wrapD(y + 0.5, sy, H) ** 2;
    if (d < bd) { bd = d; best = m; }
  }
  return best;
};
const point = (x, y) => {
  const a = (2 * Math.PI * (x % W)) / W, b = (2 * Math.PI * (y % H)) / H;
  return [(R + r * Math.cos(b)) * Math.cos(a), r * Math.sin(b), (R + r * Math.cos(b)) * Math.sin(a)];
};
const cells = Math.ceil(Math.sqrt(M));

const doc = new Document();
const buffer = doc.createBuffer();
const mesh = doc.createMesh('patches');
for (let m = 0; m < M; m++) {
  const pos = [], uv = [], col = [], idx = [];
  const index = new Map();
  const vert = (x, y) => {
    const k = `${x},${y}`;
    let i = index.get(k);
    if (i === undefined) {
      i = pos.length / 3;
      index.set(k, i);
      pos.push(...point(x, y));
      // Material m's atlas cell, the torus unrolled inside it.
      uv.push(((m % cells) + (0.05 + 0.9 * x / W)) / cells, (Math.floor(m / cells) + (0.05 + 0.9 * y / H)) / cells);
      col.push(0.5 + 0.5 * Math.cos(x / 5 + m), 0.5 + 0.5 * Math.sin(y / 3), (m + 1) / (M + 1), 1);
    }
    return i;
  };
  for (let y = 0; y < H; y++) for (let x = 0; x < W; x++) {
    if (quadMaterial(x, y) !== m) continue;
    const a = vert(x, y), b = vert(x + 1, y), c = vert(x + 1, y + 1), d = vert(x, y + 1);
    idx.push(a, d, c, a, c, b);
  }
  if (idx.length === 0) continue;
  const acc = (type, arr, ctor) => doc.createAccessor().setType(type).setArray(new ctor(arr)).setBuffer(buffer);
  const mat = doc.createMaterial(`m${m}`).setBaseColorFactor([rnd(), rnd(), rnd(), 1]);
  const prim = doc.createPrimitive().setMaterial(mat).setIndices(acc('SCALAR', idx, Uint32Array))
    .setAttribute('POSITION', acc('VEC3', pos, Float32Array));
  if (withUv) prim.setAttribute('TEXCOORD_0', acc('VEC2', uv, Float32Array));
  if (withColors) prim.setAttribute('COLOR_0', acc('VEC4', col, Float32Array));
  mesh.addPrimitive(prim);
}
const node = doc.createNode('torus').setMesh(mesh);
doc.createScene().addChild(node);
await new NodeIO().write(out, doc);
