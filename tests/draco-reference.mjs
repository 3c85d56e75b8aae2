// Decodes a KHR_draco_mesh_compression GLB with glTF Transform and Google's draco3dgltf decoder
// (an implementation independent of ours) and writes a digest of every Draco primitive's
// decoded accessors, which crates/pmcodec-mesh checks its own Draco decoding against:
//   node tests/draco-reference.mjs ../shared/data/gltf/Parrot.glb \
//     crates/pmcodec-mesh/tests/compressed/parrot-draco-reference.json
// Per accessor (by its index in the file): count, components, per-component sum, min and max,
// and every 7th element in full. Floats are written as JavaScript prints them (shortest
// round-trip form), so the digest is exact.
import { readFileSync, writeFileSync } from 'node:fs';
import { NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import draco3d from 'draco3dgltf';

const [input, output] = process.argv.slice(2);
if (!input || !output) {
  console.error('usage: node draco-reference.mjs IN.glb OUT.json');
  process.exit(2);
}
// Which accessor indices the file gives each Draco primitive's attributes and indices.
const glb = readFileSync(input);
const jsonLength = glb.readUInt32LE(12);
const json = JSON.parse(glb.subarray(20, 20 + jsonLength).toString('utf8'));

const io = new NodeIO()
  .registerExtensions(ALL_EXTENSIONS)
  .registerDependencies({ 'draco3d.decoder': await draco3d.createDecoderModule() });
const doc = await io.read(input);
const STEP = 7;
const digest = (accessor) => {
  const array = accessor.getArray();
  const n = accessor.getElementSize();
  const count = accessor.getCount();
  const sum = new Array(n).fill(0);
  const min = new Array(n).fill(Infinity);
  const max = new Array(n).fill(-Infinity);
  const samples = [];
  for (let i = 0; i < count; i++) {
    const element = Array.from(array.subarray(i * n, i * n + n));
    element.forEach((v, c) => {
      sum[c] += v;
      min[c] = Math.min(min[c], v);
      max[c] = Math.max(max[c], v);
    });
    if (i % STEP === 0) samples.push(element);
  }
  return { count, components: n, sum, min, max, step: STEP, samples };
};
const out = { source: input.split('/').pop(), decoder: 'glTF Transform 4.5.1 + draco3dgltf 1.5.7', accessors: {} };
doc.getRoot().listMeshes().forEach((mesh, m) => {
  mesh.listPrimitives().forEach((prim, p) => {
    const raw = json.meshes[m].primitives[p];
    if (!raw.extensions?.KHR_draco_mesh_compression) return;
    for (const name of Object.keys(raw.extensions.KHR_draco_mesh_compression.attributes)) {
      out.accessors[raw.attributes[name]] = { what: `mesh ${m} primitive ${p} ${name}`, ...digest(prim.getAttribute(name)) };
    }
    out.accessors[raw.indices] = { what: `mesh ${m} primitive ${p} indices`, ...digest(prim.getIndices()) };
  });
});
writeFileSync(output, JSON.stringify(out, null, 0) + '\n');
console.log(`${input} -> ${output}: ${Object.keys(out.accessors).length} accessors`);
