// The size bar of issue 16: the bytes pmcodec's container spends on a glTF asset's texture
// coordinates, colours and material ids (stored once for the sequence, every level), beside
// what Draco (npm `draco3d`, Edgebreaker with its default texture-coordinate prediction) takes
// for the same attributes on the same input mesh at the same quantization, and the textures'
// own bytes.
//
//   (cd tests && npm ci) && cargo build --release -p pmcodec && \
//     node scripts/attribute-sizes.mjs target/release/pmcodec ../shared/data/gltf/Fox.glb \
//       ../shared/data/gltf/RobotExpressive.glb
//
// (A debug build writes the same bytes.) Generated inputs, not tuned to the files in
// ../shared/data: `node scripts/many-materials-glb.mjs /tmp/mm.glb 12 1 uv none` (see its
// header). Where the bytes go, part by part: the example `appearance_parts` of
// pmcodec-container.
//
// Draco's attribute bytes are measured as a difference: the mesh encoded with positions only,
// then with positions and the attributes, same settings; what the second costs more is the
// attributes, their seams (Draco's attribute connectivity) included. Our side is what
// `pmcodec info` prints as "appearance bytes": the charts chunk (which triangle belongs to which
// chart and material, and the smoothing groups) plus every level's attribute table (level 0
// alone is printed too: it is what describes the same input mesh Draco encodes).
// Quantization: texture coordinates 12 bits (pmcodec's DEFAULT_UV_BITS, Draco's
// SetAttributeQuantization over the same bounding box), colours 8 bits, material ids as
// integers. The verdict is the last line ("bar met" / "bar missed"); the exit status is 0 once
// every input was measured (BENCHMARKS.md's row reads the verdict, a non-zero status means the
// measurement itself failed).
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { createRequire } from 'node:module';
import { tmpdir } from 'node:os';
import { basename, join } from 'node:path';

// The npm packages live in tests/ (CI installs them with `npm ci` there).
const require = createRequire(new URL('../tests/package.json', import.meta.url));
const draco3d = require('draco3d');
const { NodeIO } = require('@gltf-transform/core');
const { ALL_EXTENSIONS } = require('@gltf-transform/extensions');

const UV_BITS = 12;
const COLOR_BITS = 8;
const POSITION_BITS = 14;
const BAR = 1.1;

const [pmcodec, ...inputs] = process.argv.slice(2);
if (!pmcodec || inputs.length === 0) {
  console.error('usage: node scripts/attribute-sizes.mjs PMCODEC_BINARY FILE.glb...');
  process.exit(2);
}

const encoderModule = await draco3d.createEncoderModule({});
// Parrot.glb is itself Draco-compressed: gltf-transform needs the decoder to read it.
const decoderModule = await draco3d.createDecoderModule({});

// Every primitive of every mesh, concatenated: per vertex its position, TEXCOORD_0 and COLOR_0
// (when any primitive has them; zeros for one that has not) and its primitive's material.
function gather(doc) {
  const materials = doc.getRoot().listMaterials();
  const prims = doc.getRoot().listMeshes().flatMap((m) => m.listPrimitives()).filter((p) => p.getMode() === 4);
  const hasUv = prims.some((p) => p.getAttribute('TEXCOORD_0'));
  const hasColor = prims.some((p) => p.getAttribute('COLOR_0'));
  const positions = [];
  const uvs = [];
  const colors = [];
  const material = [];
  const indices = [];
  let base = 0;
  for (const p of prims) {
    const pos = p.getAttribute('POSITION');
    const uv = p.getAttribute('TEXCOORD_0');
    const col = p.getAttribute('COLOR_0');
    const n = pos.getCount();
    const m = Math.max(0, materials.indexOf(p.getMaterial()));
    // A fresh array per element: getElement writes into its target without shortening it, so
    // one shared array carried a position's third value into every texture coordinate (Fox's
    // Draco figure was 5,286 B of garbled coordinates where the real ones take 1,141 B) and a
    // VEC4 colour's fourth value into the next position.
    for (let i = 0; i < n; i++) {
      positions.push(...pos.getElement(i, []));
      if (hasUv) uvs.push(...(uv ? uv.getElement(i, []) : [0, 0]));
      if (hasColor) {
        const c = col ? col.getElement(i, []) : [1, 1, 1, 1];
        colors.push(c[0], c[1], c[2], c.length > 3 ? c[3] : 1);
      }
      material.push(m);
    }
    const idx = p.getIndices();
    const count = idx ? idx.getCount() : n;
    for (let i = 0; i < count; i++) indices.push(base + (idx ? idx.getScalar(i) : i));
    base += n;
  }
  const points = positions.length / 3;
  if (!Number.isInteger(points) || (hasUv && uvs.length !== 2 * points) || (hasColor && colors.length !== 4 * points)) {
    throw new Error(`gathered ${positions.length} position, ${uvs.length} texture-coordinate and ${colors.length} colour values: not per vertex`);
  }
  return { positions, uvs, colors, material, indices, materials: materials.length };
}

// Bytes of a Draco encoding of the gathered mesh, with or without its attributes.
function dracoBytes(g, withAttributes) {
  const e = encoderModule;
  const builder = new e.MeshBuilder();
  const mesh = new e.Mesh();
  const points = g.positions.length / 3;
  builder.AddFacesToMesh(mesh, g.indices.length / 3, new Uint32Array(g.indices));
  builder.AddFloatAttributeToMesh(mesh, e.POSITION, points, 3, new Float32Array(g.positions));
  if (withAttributes) {
    if (g.uvs.length) builder.AddFloatAttributeToMesh(mesh, e.TEX_COORD, points, 2, new Float32Array(g.uvs));
    if (g.colors.length) builder.AddFloatAttributeToMesh(mesh, e.COLOR, points, 4, new Float32Array(g.colors));
    if (g.materials > 1) builder.AddUInt16Attribute(mesh, e.GENERIC, points, 1, new Uint16Array(g.material));
  }
  const encoder = new e.Encoder();
  encoder.SetEncodingMethod(e.MESH_EDGEBREAKER_ENCODING);
  encoder.SetAttributeQuantization(e.POSITION, POSITION_BITS);
  encoder.SetAttributeQuantization(e.TEX_COORD, UV_BITS);
  encoder.SetAttributeQuantization(e.COLOR, COLOR_BITS);
  // Draco's defaults otherwise (speed 5: Edgebreaker, parallelogram prediction for texture
  // coordinates).
  const out = new e.DracoInt8Array();
  const bytes = encoder.EncodeMeshToDracoBuffer(mesh, out);
  for (const x of [out, encoder, mesh, builder]) e.destroy(x);
  if (!bytes) throw new Error('Draco failed to encode');
  return bytes;
}

function ours(file) {
  const dir = mkdtempSync(join(tmpdir(), 'pmc-attr-'));
  try {
    const pmc = join(dir, 'a.pmc');
    execFileSync(pmcodec, ['encode', '-q', file, '-o', pmc], { stdio: ['ignore', 'ignore', 'inherit'] });
    const info = execFileSync(pmcodec, ['info', pmc], { encoding: 'utf8' });
    const line = info.split('\n').find((l) => l.startsWith('appearance bytes'));
    const m = line && line.match(/charts (\d+), materials (\d+), attributes ([\d + ]+) \(levels top\.\.0\), images (\d+)/);
    if (!m) throw new Error(`no appearance bytes in pmcodec info ${pmc}:\n${info}`);
    const levels = m[3].split('+').map((x) => Number(x.trim()));
    const tri = info.match(/triangles\s+(\d+)/);
    return {
      charts: Number(m[1]),
      materials: Number(m[2]),
      levels,
      level0: levels[levels.length - 1],
      images: Number(m[4]),
      triangles: tri ? Number(tri[1]) : NaN,
    };
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
}

let over = false;
for (const file of inputs) {
  const io = new NodeIO().registerExtensions(ALL_EXTENSIONS).registerDependencies({ 'draco3d.decoder': decoderModule });
  const doc = await io.read(file);
  const g = gather(doc);
  const bare = dracoBytes(g, false);
  const full = dracoBytes(g, true);
  const draco = full - bare;
  const textures = doc.getRoot().listTextures().reduce((a, t) => a + (t.getImage()?.byteLength ?? 0), 0);
  const what = [g.uvs.length && 'texture coordinates', g.colors.length && 'colours', g.materials > 1 && 'material ids'].filter(Boolean).join(', ');
  console.log(`${basename(file)}: ${g.indices.length / 3} triangles, ${g.positions.length / 3} glTF vertices; ${what || 'no attributes'}`);
  console.log(`  draco: ${draco} B of attributes (${full} B with them, ${bare} B positions and connectivity only)`);
  const o = ours(file);
  const total = o.charts + o.levels.reduce((a, b) => a + b, 0);
  console.log(`  pmcodec (${o.triangles} triangles): ${total} B (charts ${o.charts} + attribute tables ${o.levels.join(' + ')}, levels top..0); level 0 table alone ${o.level0} B; materials chunk ${o.materials} B`);
  const ratio = total / draco;
  console.log(`  ratio pmcodec/draco: ${ratio.toFixed(3)} (bar ${BAR}); textures' own bytes ${textures} (pmcodec images ${o.images})`);
  if (!(ratio <= BAR)) over = true;
}
// A missed bar is the script's verdict, said in words as well as in the exit code.
console.log(over ? `bar missed: pmcodec above ${BAR}x Draco on at least one input` : `bar met: pmcodec at most ${BAR}x Draco on every input`);
process.exit(0);
