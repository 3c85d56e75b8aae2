// Writes a Draco-compressed copy of a GLB for the Rust reader's tests, with a COLOR_0 added to
// every primitive (derived from its positions) so that every attribute KHR_draco_mesh_compression
// maps is covered: POSITION, NORMAL, TEXCOORD_0, COLOR_0, JOINTS_0, WEIGHTS_0. Edgebreaker
// connectivity (the method exporters use for meshes without morph targets), glTF Transform's
// default quantisation (positions 14 bits, normals 10, UVs 12, colours 8, other floats 12).
//   (cd tests && npm ci) && node tests/draco-fixture.mjs IN.glb OUT.glb
// crates/pmcodec-mesh/tests/compressed/make-fixtures.sh runs it on the untextured Fox.
import { NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS, KHRDracoMeshCompression } from '@gltf-transform/extensions';
import draco3d from 'draco3dgltf';

const [input, output] = process.argv.slice(2);
if (!input || !output) {
  console.error('usage: node draco-fixture.mjs IN.glb OUT.glb');
  process.exit(2);
}
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS).registerDependencies({
  'draco3d.decoder': await draco3d.createDecoderModule(),
  'draco3d.encoder': await draco3d.createEncoderModule(),
});
const doc = await io.read(input);
// The first half second of the first animation is enough to pose the skin; the rest would
// only make the file larger (the keys are not compressed).
for (const animation of doc.getRoot().listAnimations().slice(1)) {
  animation.listChannels().forEach((c) => c.dispose());
  animation.listSamplers().forEach((s) => s.dispose());
  animation.dispose();
}
const cut = new Set();
for (const sampler of doc.getRoot().listAnimations()[0]?.listSamplers() ?? []) {
  const [input, output] = [sampler.getInput(), sampler.getOutput()];
  const keep = input.getArray().filter((t) => t <= 0.5).length;
  const width = output.getElementSize() * (sampler.getInterpolation() === 'CUBICSPLINE' ? 3 : 1);
  if (!cut.has(output)) output.setArray(output.getArray().slice(0, keep * width));
  cut.add(output);
  if (!cut.has(input)) input.setArray(input.getArray().slice(0, keep));
  cut.add(input);
}
// Accessors only the disposed animations used.
for (const accessor of doc.getRoot().listAccessors()) {
  if (accessor.listParents().every((p) => p.propertyType === 'Root')) accessor.dispose();
}
const buffer = doc.getRoot().listBuffers()[0];
for (const mesh of doc.getRoot().listMeshes()) {
  for (const prim of mesh.listPrimitives()) {
    const position = prim.getAttribute('POSITION');
    const [lo, hi] = [position.getMin([]), position.getMax([])];
    const colors = new Float32Array(position.getCount() * 4);
    const p = [];
    for (let i = 0; i < position.getCount(); i++) {
      position.getElement(i, p);
      for (let c = 0; c < 3; c++) colors[4 * i + c] = (p[c] - lo[c]) / Math.max(hi[c] - lo[c], 1e-9);
      colors[4 * i + 3] = 1;
    }
    prim.setAttribute('COLOR_0', doc.createAccessor().setType('VEC4').setArray(colors).setBuffer(buffer));
  }
}
doc
  .createExtension(KHRDracoMeshCompression)
  .setRequired(true)
  .setEncoderOptions({ method: KHRDracoMeshCompression.EncoderMethod.EDGEBREAKER, encodeSpeed: 5, decodeSpeed: 5 });
await io.write(output, doc);
console.log(`${input} -> ${output} (Draco, edgebreaker, COLOR_0 added)`);
