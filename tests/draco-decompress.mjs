// Writes a copy of a GLB with KHR_draco_mesh_compression decoded into plain accessors, for
// inputs our Rust reader does not decode (the Parrot). Usage:
//   node draco-decompress.mjs IN.glb OUT.glb
import { NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import draco3d from 'draco3dgltf';

const [input, output] = process.argv.slice(2);
if (!input || !output) {
  console.error('usage: node draco-decompress.mjs IN.glb OUT.glb');
  process.exit(2);
}
const io = new NodeIO()
  .registerExtensions(ALL_EXTENSIONS)
  .registerDependencies({ 'draco3d.decoder': await draco3d.createDecoderModule() });
const doc = await io.read(input);
for (const ext of doc.getRoot().listExtensionsUsed()) {
  if (ext.extensionName === 'KHR_draco_mesh_compression') ext.dispose();
}
await io.write(output, doc);
console.log(`${input} -> ${output} (Draco decoded)`);
