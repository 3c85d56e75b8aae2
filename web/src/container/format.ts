// The byte layout of a .pmc file (proto/container.md), as `pmcodec_container::format`: the
// preamble, the postcard header and index, their checks and limits, and the CRC-32 every
// region carries.

import { DecodeError } from "./error.js";
import { Cursor, Postcard } from "./payload.js";
import { ENTRY, MAX_PALETTE, SkinHeader } from "./skin.js";

export const MAGIC = [0x89, 0x50, 0x4d, 0x43, 0x0d, 0x0a, 0x1a, 0x0a];
export const PREAMBLE_LEN = 32;
/**
 * The format version this decoder reads, and the oldest it still reads (version 6: the index
 * in postcard, every entry whole; version 5: no
 * `appearance` nor `skin` in the header; version 4: no `order` either, faces and corners as
 * plain ids; version 3: no `motion` either).
 */
export const VERSION = 7, OLDEST_READABLE = 3;
/** The largest header or index the preamble may declare. */
export const MAX_TABLE_LEN = 64 << 20;
/** Caps on a header's declared sizes (proto/container.md, "Limits"). */
export const MAX_VERTICES = 1 << 24, MAX_TRIANGLES = 1 << 25, MAX_NODES = 1 << 25, MAX_FRAMES = 1 << 20;

export enum ChunkKind { Triangles = 0, Key = 1, Delta = 2, Positions = 3, Faces = 4, Corners = 5, Charts = 6, Attributes = 7, Materials = 8, Image = 9, Bind = 10, Pose = 11, Palette = 12, Joints = 13 }
/** Most materials and images a file may declare; the largest Materials and Image chunks. */
export const MAX_MATERIALS = 1 << 16, MAX_IMAGES = 1 << 12, MAX_MATERIALS_LEN = 16 << 20, MAX_IMAGE_LEN = 256 << 20;
/** How band 0 is predicted on frames that are not keyframes (proto/container.md, "Positions, band j"). */
export enum Motion { Mean = 0, Affine = 1, KeyframeAffine = 2 }
/** The order band 0 is decoded in (proto/container.md, "Band 0 order"). */
export enum VertexOrder { Input = 0, BreadthFirst = 1 }

/**
 * Whether a client whose finest level is `minLevel` reads chunks of this kind in `band`: every
 * band from its level up, except faces and corners, which only the band of its finest level
 * needs (proto/container.md, "Who reads what").
 */
export function readAt(kind: ChunkKind, band: number, minLevel: number): boolean {
  if (kind === ChunkKind.Triangles) return minLevel === 0;
  if (kind === ChunkKind.Faces || kind === ChunkKind.Corners) return band === minLevel;
  if (kind === ChunkKind.Charts || kind === ChunkKind.Materials || kind === ChunkKind.Image || kind === ChunkKind.Pose) return true;
  return band >= minLevel;
}

export interface Header {
  vertexCount: number; triangleCount: number; frameCount: number; frameRate: number;
  levelSizes: number[]; branching: number; bboxMin: number[]; bboxMax: number[];
  step: number; keyframeInterval: number; generator: string; frameNames: string[];
  /** Band 0's prediction on inter frames. */
  motion: Motion;
  /** Band 0's decoding order. */
  order: VertexOrder;
  /** Texture coordinates, colours and materials (version 6), or null. */
  appearance: AppearanceInfo | null;
  /** The skin, when node positions may be predicted by skinning (version 6). */
  skin: SkinHeader | null;
}

/** The header's `appearance` (proto/container.md, "Header"). */
export interface AppearanceInfo {
  charts: number; groups: number; materials: number; images: number; uvSets: number;
  uvMin: number[]; uvStep: number[]; colors: boolean; normals: boolean;
}

/** Scalar channels per attribute entry: two per texture coordinate set, four for colour. */
export function channels(a: AppearanceInfo): number { return 2 * a.uvSets + (a.colors ? 4 : 0); }

export interface ChunkEntry { kind: ChunkKind; frame: number; band: number; offset: number; storedLen: number; rawLen: number; crc32: number }

/** The fixed 32 bytes at the start of a file: version, table lengths and their checksums. */
/**
 * Preamble flags (proto/container.md, "Preamble"): a chunk whose stored length equals its raw
 * length is stored as is (FLAG_STORED); empty Delta and Corners chunks, and Positions chunks of zero residuals, are left out (FLAG_SPARSE).
 */
export const FLAG_STORED = 1, FLAG_SPARSE = 2;
/** Preamble flag: frame names front-coded (proto/container.md, "Header"; frontDecode). */
export const FLAG_NAMES = 4;
/**
 * Preamble flag: the index is banded (proto/container.md, "Index"; format::FLAG_BANDS): a table
 * of groups (what every client reads, then per band from the top down its topology, geometry and
 * faces), each group's entries and chunks contiguous, so a client fetches only its levels' groups.
 */
export const FLAG_BANDS = 8;

/**
 * Undoes the front coding of frame names (as `format::front_decode`): each name after the first
 * is the previous one's first k bytes (UTF-8; k the code of the entry's first character, 0 to
 * 127, cut back to the name before and to a character boundary) and the rest of the entry; an
 * entry whose first character is no count is a whole name.
 */
export function frontDecode(coded: string[]): string[] {
  const enc = new TextEncoder(), dec = new TextDecoder();
  const out: string[] = [];
  for (let i = 0; i < coded.length; i++) {
    const e = coded[i], c = e.codePointAt(0);
    if (i === 0 || c === undefined || c > 127) { out.push(e); continue; }
    const prev = enc.encode(out[i - 1]);
    let k = Math.min(c, prev.length);
    while (k > 0 && k < prev.length && (prev[k] & 0xc0) === 0x80) k--;
    out.push(dec.decode(prev.subarray(0, k)) + e.slice(1));
  }
  return out;
}

export interface Preamble { version: number; flags: number; headerLen: number; indexLen: number; headerCrc: number; indexCrc: number; tableLen: number }

const CRC_TABLE = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();

export function crc32(b: Uint8Array): number {
  let c = 0xffffffff;
  for (let i = 0; i < b.length; i++) c = CRC_TABLE[(c ^ b[i]) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

/** Reads the preamble (at least PREAMBLE_LEN bytes): magic number, a readable version, lengths. */
export function parsePreamble(pre: Uint8Array): Preamble {
  for (let i = 0; i < 8; i++) if (pre[i] !== MAGIC[i]) throw new DecodeError("not a .pmc file (bad magic number)");
  const dv = new DataView(pre.buffer, pre.byteOffset, pre.byteLength);
  const version = dv.getUint16(8, true);
  if (version < OLDEST_READABLE || version > VERSION) throw new DecodeError(`container version ${version} is not supported (this decoder reads versions ${OLDEST_READABLE} to ${VERSION})`);
  return { version, flags: dv.getUint16(10, true), headerLen: dv.getUint32(12, true), indexLen: dv.getUint32(16, true), headerCrc: dv.getUint32(20, true), indexCrc: dv.getUint32(24, true), tableLen: dv.getUint32(28, true) };
}

/** The header of a file of `version` (older versions lack the fields added since). */
export function parseHeader(hb: Uint8Array, version: number): Header {
  const p = new Postcard(hb, "header");
  const header: Header = {
    vertexCount: p.varint(), triangleCount: p.varint(), frameCount: p.varint(), frameRate: p.f32(),
    levelSizes: p.seq(() => p.varint(), 64), branching: p.varint(),
    bboxMin: [p.f32(), p.f32(), p.f32()], bboxMax: [p.f32(), p.f32(), p.f32()],
    step: p.f32(), keyframeInterval: p.varint(), generator: "", frameNames: [], motion: Motion.Mean, order: VertexOrder.Input,
    appearance: null, skin: null,
  };
  // encoded_with: informative, read and dropped.
  p.str(); p.str(); p.f64(); p.f64(); p.varint(); p.bool(); p.bool(); p.option(() => p.f64()); p.option(() => p.u8());
  header.generator = p.str();
  header.frameNames = p.seq(() => p.str(), 1 << 20);
  header.motion = version >= 4 ? p.varint() : Motion.Mean;
  if (header.motion > (version >= 5 ? Motion.KeyframeAffine : Motion.Affine)) throw new DecodeError(`header: unknown band-0 motion ${header.motion}`);
  header.order = version >= 5 ? p.varint() : VertexOrder.Input;
  if (header.order > VertexOrder.BreadthFirst) throw new DecodeError(`header: unknown band-0 order ${header.order}`);
  if (version >= 6) {
    header.appearance = p.option((): AppearanceInfo => ({
      charts: p.varint(), groups: p.varint(), materials: p.varint(), images: p.varint(), uvSets: p.u8(),
      uvMin: [p.f32(), p.f32()], uvStep: [p.f32(), p.f32()], colors: p.bool(), normals: p.bool(),
    }));
  }
  header.skin = version >= 6 ? p.option(() => ({ paletteLen: p.varint(), bindStep: p.f32() })) : null;
  // Every version's header ends with its last field, except version 5's, whose readers ignored bytes after it.
  if (version !== 5 && p.pos !== hb.length) throw new DecodeError(`header: ${hb.length - p.pos} bytes after its last field`);
  return header;
}

/** The largest chunk kind this decoder knows. */
const LAST_KIND = ChunkKind.Joints;

/**
 * The index of a file of `version` whose header declares `frames` frames. Versions up to 6:
 * postcard, every entry whole. Version 7 (proto/container.md, "Index"): per frame, its entry
 * count, then each entry's tag (kind in bits 0..5, bit 5: the raw length is the stored length
 * and is not written, the band above), stored length, raw length unless the tag says so, and
 * CRC-32 (4 bytes, little-endian); offsets follow from the order.
 */
export function parseIndex(ib: Uint8Array, version: number, frames: number): ChunkEntry[] {
  if (version < 7) {
    const q = new Postcard(ib, "index");
    return q.seq((): ChunkEntry => {
      const kind = q.varint();
      if (kind > LAST_KIND) throw new DecodeError(`index: chunk kind ${kind}`);
      return { kind, frame: q.varint(), band: q.varint(), offset: q.varint(), storedLen: q.varint(), rawLen: q.varint(), crc32: q.varint() };
    }, 1 << 24);
  }
  const c = new Cursor(ib, "index");
  const out: ChunkEntry[] = [];
  let offset = 0;
  for (let frame = 0; frame < frames; frame++) {
    // Each entry takes at least 6 bytes (tag, stored length, CRC): a count beyond what is left is refused.
    const n = c.get();
    if (n * 6 > ib.length - c.pos) throw new DecodeError(`index: ${n} chunks in ${ib.length - c.pos} bytes`);
    for (let i = 0; i < n; i++) {
      const tag = c.get();
      const kind = tag & 31;
      if (kind > LAST_KIND) throw new DecodeError(`index: unknown chunk kind ${kind}`);
      const storedLen = c.get();
      const rawLen = tag & 32 ? storedLen : c.get();
      const crc = c.u32le();
      out.push({ kind, frame, band: Math.floor(tag / 64), offset, storedLen, rawLen, crc32: crc });
      offset += storedLen;
    }
  }
  c.finish();
  return out;
}

/** Groups of a banded index for `levels` levels (format::group_count). */
export function groupCount(levels: number): number { return 1 + 3 * levels; }

/** The group of a chunk (format::group_of): 0 what every client reads, then per band from the top down topology, geometry, faces. */
export function groupOf(kind: ChunkKind, band: number, levels: number): number {
  const top = Math.max(levels - 1, 0), base = 1 + 3 * (top - Math.min(band, top));
  switch (kind) {
    case ChunkKind.Pose: case ChunkKind.Charts: case ChunkKind.Materials: case ChunkKind.Image: return 0;
    case ChunkKind.Triangles: case ChunkKind.Key: case ChunkKind.Delta: return base;
    case ChunkKind.Faces: case ChunkKind.Corners: return base + 2;
    default: return base + 1;
  }
}

/** Group `g`'s name in messages (format::group_name). */
export function groupName(g: number, levels: number): string {
  if (g === 0) return "index group 0 (every client)";
  const top = Math.max(levels - 1, 0);
  return `index group ${g} (band ${top - Math.min(Math.floor((g - 1) / 3), top)} ${["topology", "geometry", "faces"][(g - 1) % 3]})`;
}

/** The groups a client of finest level `level` reads (format::groups_for), ascending. */
export function groupsFor(levels: number, level: number, derived: boolean): number[] {
  const top = Math.max(levels - 1, 0), out = [0];
  for (let b = top; b >= level; b--) {
    const base = 1 + 3 * (top - b);
    out.push(base, base + 1);
    if (b === level) out.push(base + 2);
  }
  if (derived) for (let b = Math.min(level, levels) - 1; b >= 0; b--) out.push(1 + 3 * (top - b));
  return out.sort((a, b) => a - b);
}

/** A banded index's table row: entry bytes, the faces group's derived bit, chunk bytes, CRC-32 of the entry bytes. */
export interface GroupRow { bodyLen: number; derived: boolean; chunksLen: number; crc32: number }

/** A banded index's table (format::parse_table): the group count, then each group's row. */
export function parseTable(tb: Uint8Array, levels: number): GroupRow[] {
  const c = new Cursor(tb, "index table");
  const n = c.get();
  if (n !== groupCount(levels)) throw new DecodeError(`index table: ${n} groups for ${levels} levels (1 + 3 per level)`);
  const rows: GroupRow[] = [];
  for (let i = 0; i < n; i++) {
    const first = c.get(), chunksLen = c.get(), crc = first >= 2 ? c.u32le() : 0;
    rows.push({ bodyLen: Math.floor(first / 2), derived: (first & 1) !== 0, chunksLen, crc32: crc });
  }
  c.finish();
  return rows;
}

/**
 * Group `g`'s entries (format::parse_group): its CRC checked, then entries until its bytes end,
 * each a tag (kind in bits 0..4, bit 4: raw length = stored length, the frame's advance above),
 * the band (group 0 only), the stored length, the raw length unless the tag says so, the CRC-32;
 * its chunks start at `offset` and take the table's `chunksLen` bytes.
 */
export function parseGroup(b: Uint8Array, g: number, row: GroupRow, offset: number, levels: number, frames: number): ChunkEntry[] {
  const what = groupName(g, levels);
  if (crc32(b) !== row.crc32) throw new DecodeError(`${what}: checksum mismatch`);
  const c = new Cursor(b, what), out: ChunkEntry[] = [];
  const top = Math.max(levels - 1, 0), implied = g === 0 ? 0 : top - Math.min(Math.floor((g - 1) / 3), top);
  let frame = 0, at = offset, derived = false;
  while (c.pos < b.length) {
    const tag = c.get(), kind = tag & 15;
    if (kind > LAST_KIND) throw new DecodeError(`${what}: unknown chunk kind ${kind}`);
    frame += Math.floor(tag / 32);
    if (frame >= frames) throw new DecodeError(`${what}: a frame beyond the header's`);
    const band = g === 0 ? c.get() : implied;
    if (groupOf(kind, band, levels) !== g) throw new DecodeError(`${what}: a ${ChunkKind[kind]} chunk, which belongs to another group`);
    const storedLen = c.get(), rawLen = tag & 16 ? storedLen : c.get(), crc = c.u32le();
    out.push({ kind, frame, band, offset: at, storedLen, rawLen, crc32: crc });
    derived ||= kind === ChunkKind.Faces && rawLen === 2;
    at += storedLen;
  }
  if (at - offset !== row.chunksLen) throw new DecodeError(`${what}: chunks of ${at - offset} bytes where the table says ${row.chunksLen}`);
  if (derived !== row.derived) throw new DecodeError(`${what}: the table and its entries disagree on whether its band derives its faces`);
  return out;
}

/** Entries read group after group, in the order readers use (format::frame_order): Triangles, then frame after frame, stable. */
export function frameOrder(entries: ChunkEntry[]): ChunkEntry[] {
  return entries.sort((a, b) => (a.kind === ChunkKind.Triangles ? 0 : 1) - (b.kind === ChunkKind.Triangles ? 0 : 1) || a.frame - b.frame);
}

/**
 * Checks a header and index against each other and the file: consistent counts, shrinking
 * levels, sizes within the limits, every chunk inside the data and of a plausible size, and no
 * bytes after the last chunk. `dataLen`: the bytes after the preamble, header and index.
 */
export function checkTables(h: Header, index: ChunkEntry[], dataLen: number, banded = false): void {
  if (h.levelSizes.length === 0 || h.levelSizes[0] !== h.vertexCount || h.frameCount === 0 || !(h.step > 0)) throw new DecodeError("header: inconsistent counts");
  if (h.levelSizes.some((s, i) => i > 0 && (s === 0 || s > h.levelSizes[i - 1]))) throw new DecodeError(`header: level sizes ${h.levelSizes} do not shrink`);
  // As the Rust reader's check_header: a frame rate, step or box that is not a finite number
  // would reach the player's clock and every dequantized position.
  if (!(Number.isFinite(h.step) && h.step > 0)) throw new DecodeError(`header: quantization step ${h.step}`);
  if (!(Number.isFinite(h.frameRate) && h.frameRate > 0)) throw new DecodeError(`header: frame rate ${h.frameRate}`);
  if (![...h.bboxMin, ...h.bboxMax].every(Number.isFinite)) throw new DecodeError("header: bounding box is not finite");
  // Declared sizes are capped, so what a player allocates from them is bounded (proto/container.md, "Limits").
  const nodes = h.levelSizes.reduce((a, b) => a + b, 0);
  if (h.vertexCount > MAX_VERTICES || h.triangleCount > MAX_TRIANGLES || nodes > MAX_NODES || h.frameCount > MAX_FRAMES) {
    throw new DecodeError(`header: ${h.vertexCount} vertices, ${h.triangleCount} triangles, ${nodes} nodes, ${h.frameCount} frames: beyond the limits`);
  }
  const a = h.appearance;
  if (a && (a.charts === 0 || a.charts > h.triangleCount || a.groups === 0 || a.groups > h.triangleCount || a.materials > MAX_MATERIALS
    || a.images > MAX_IMAGES || a.uvSets > 2 || !a.uvMin.every(Number.isFinite) || !a.uvStep.every((x) => Number.isFinite(x) && x > 0))) {
    throw new DecodeError("header: appearance out of range");
  }
  if (h.skin && !(h.skin.paletteLen >= 1 && h.skin.paletteLen <= MAX_PALETTE && h.skin.bindStep > 0 && Number.isFinite(h.skin.bindStep))) {
    throw new DecodeError(`header: skin palette of ${h.skin.paletteLen} entries, bind quantum ${h.skin.bindStep}`);
  }
  let end = 0, trianglesSeen = false;
  const seen = new Set<string>();
  for (const e of index) {
    if ((e.kind === ChunkKind.Bind || e.kind === ChunkKind.Pose || e.kind === ChunkKind.Palette || e.kind === ChunkKind.Joints) && !h.skin) throw new DecodeError(`${describe(e)}: a skin chunk in a file without a skin`);
    if (e.kind === ChunkKind.Bind && e.frame !== 0) throw new DecodeError(`${describe(e)}: frame ${e.frame}, where bind chunks are frame 0`);
    if (e.kind === ChunkKind.Pose && e.band !== 0) throw new DecodeError(`${describe(e)}: band ${e.band}, where pose chunks are band 0`);
    if (e.offset + e.storedLen > dataLen) throw new DecodeError(`${describe(e)}: the file ends before it does`);
    end = Math.max(end, e.offset + e.storedLen);
    if (e.kind !== ChunkKind.Triangles && e.kind !== ChunkKind.Image && (e.frame >= h.frameCount || e.band >= h.levelSizes.length)) throw new DecodeError(`${describe(e)}: frame or band beyond the header's counts`);
    if (e.kind === ChunkKind.Triangles) {
      if (e.frame !== 0 || e.band !== 0) throw new DecodeError(`${describe(e)}: frame ${e.frame} band ${e.band}, where the triangles chunk is frame 0 band 0`);
      if (trianglesSeen) throw new DecodeError(`${describe(e)}: a second triangles chunk`);
      trianglesSeen = true;
    }
    if (e.kind >= ChunkKind.Charts && e.kind <= ChunkKind.Image) {
      // Appearance chunks: frame 0, once per kind and band, in a file with an appearance.
      const bandOk = e.kind === ChunkKind.Image ? a !== null && e.band < a.images : e.kind === ChunkKind.Attributes || e.band === 0;
      if (!a || e.frame !== 0 || !bandOk || seen.has(`${e.kind}/${e.band}`)) throw new DecodeError(`${describe(e)}: misplaced appearance chunk`);
      seen.add(`${e.kind}/${e.band}`);
    }
    const [least, most] = rawLenRange(h, e.kind, e.band);
    if (e.rawLen < least || e.rawLen > most) throw new DecodeError(`${describe(e)}: declared size ${e.rawLen} outside ${least}..${most}`);
  }
  // A banded index's table accounts for the whole chunk area (checked when it was read).
  if (!banded && end < dataLen) throw new DecodeError(`${dataLen - end} bytes after the end of the container`);
}

/** The decompressed sizes a chunk may declare (proto/container.md, "Limits"). */
function rawLenRange(h: Header, kind: ChunkKind, band: number): [number, number] {
  const t = h.triangleCount, n = h.levelSizes[band] ?? 0, belowTop = band < h.levelSizes.length - 1;
  switch (kind) {
    // Coding 1 (version 7) takes at least 4 bits a triangle after its two bytes `0 1`.
    case ChunkKind.Triangles: return [t === 0 ? 1 : 2 + Math.ceil(t / 2), 5 + 15 * t];
    // A bit-coded Key chunk (coding 1) takes at least a bit per parent; coding 3 (changes from
    // frame 0's) three bytes.
    case ChunkKind.Key: return belowTop ? [Math.min(1 + Math.ceil(n / 8), 3), 5 + 5 * n] : [1, 5];
    case ChunkKind.Delta: return [1, 5 + 10 * n];
    case ChunkKind.Faces: return [1, 5 + 20 * t];
    case ChunkKind.Corners: return [1, 5 + 25 * t];
    case ChunkKind.Charts: return [3, 15 + 25 * t];
    case ChunkKind.Attributes: return [1, 5 + (10 + 5 * (h.appearance ? channels(h.appearance) : 0)) * 3 * t];
    case ChunkKind.Materials: return [4, MAX_MATERIALS_LEN];
    case ChunkKind.Image: return [1, MAX_IMAGE_LEN];
    case ChunkKind.Bind: return [4 * n, 101 * n];
    case ChunkKind.Pose: { const p = (h.skin?.paletteLen ?? 0) * ENTRY; return [1 + p, 10 + 10 * p]; }
    case ChunkKind.Palette: { const p = (h.skin?.paletteLen ?? 0) * ENTRY; return [1, 10 + Math.floor(p / ENTRY / 8) + 1 + 10 * p]; }
    case ChunkKind.Joints: { const p = (h.skin?.paletteLen ?? 0) * ENTRY; return [2, 10 + 3 + Math.floor(p / ENTRY / 4) + 1 + 16 * p]; }
    default: return [1, 1024 + 24 * n];
  }
}

export function isKeyframe(h: Header, f: number): boolean { return f === 0 || (h.keyframeInterval > 0 && f % h.keyframeInterval === 0); }
export function keyframeBefore(h: Header, f: number): number { const k = h.keyframeInterval; return k === 0 ? 0 : f - (f % k); }

export function describe(e: ChunkEntry): string {
  switch (e.kind) {
    case ChunkKind.Triangles: return "triangles chunk";
    case ChunkKind.Charts: return "charts chunk";
    case ChunkKind.Materials: return "materials chunk";
    case ChunkKind.Image: return `image ${e.band} chunk`;
    case ChunkKind.Attributes: return `band ${e.band} attributes`;
  }
  return `frame ${e.frame} band ${e.band} ${ChunkKind[e.kind].toLowerCase()}`;
}
