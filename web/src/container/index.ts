// A decoder of the .pmc container written from proto/container.md, its modules mirroring the
// Rust crate `pmcodec_container` so the two decoders read side by side:
//
// - format.ts: magic number, versions, preamble, header, index, limits, CRC-32 (`format`);
// - payload.ts: postcard and varint readers, the chunks' payloads (`payload`);
// - rans.ts: the position residuals' entropy decoder (`rans`);
// - predict.ts: band 0's neighbours and stencils, motion, node prediction (`predict`);
// - read.ts: `Reader`, which opens a file and fetches checked chunks (`Reader`);
// - decode.ts: `Decoder`, which replays frames and selects cuts (`Decoder`);
// - replay.ts: the progressive hierarchy's replay (`pmcodec_hierarchy::progressive::Replay`);
// - appearance.ts: version 6's charts, attribute tables, materials and a cut's appearance
//   (`appearance`); codes.ts: their residual sections, rANS or adaptive Rice
//   (`appearance::codes`); grown.ts: charts grown over the triangles (`appearance::grown_charts`);
// - error.ts: `DecodeError` (`ContainerError`).

export { DecodeError } from "./error.js";
export {
  ChunkKind, MAGIC, MAX_FRAMES, MAX_NODES, MAX_TABLE_LEN, MAX_TRIANGLES, MAX_VERTICES, Motion, OLDEST_READABLE, PREAMBLE_LEN, VERSION,
  VertexOrder, crc32, describe, readAt,
} from "./format.js";
export type { AppearanceInfo, ChunkEntry, Header } from "./format.js";
export { attributeEntry, band0Entries, bandFaces, chartsNeedTriangles, dequantizeUv, needsAbove, needsBind, needsFaces, readBand0Table, readCharts, readMaterials, readTable, texturedMesh } from "./appearance.js";
export type { Charts, Faces, Material, Materials, Table, TextureRef, TexturedMesh } from "./appearance.js";
export { readCodes } from "./codes.js";
export { Cursor, readPositions } from "./payload.js";
export { affineMotion, keyedMotion, lowerNeighbours, stencilWeights } from "./predict.js";
export type { LowerNeighbours } from "./predict.js";
export { Reader } from "./read.js";
export type { ReadAt } from "./read.js";
export { Decoder, bandedPriority } from "./decode.js";
export type { DecoderOptions, RevealFrom, SkinAttributes } from "./decode.js";
export type { SkinHeader } from "./skin.js";
export { BELOW, MaxHeap, NONE, Replay } from "./replay.js";
export type { CornerUpdate, FrameDelta, KeyBand, Swap } from "./replay.js";
