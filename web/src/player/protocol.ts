// Messages between a player (main thread) and its worker. Buffers travel by transfer.

import type { Materials } from "../container/appearance.js";

/**
 * How the mesh is coloured: "authored" draws a stream's appearance (texture coordinates,
 * vertex colours, materials and their images; streams without it draw as "plain"), "plain" one
 * flat material, "level" each vertex's hierarchy level, "error" its split priority.
 */
export type ColourMode = "authored" | "plain" | "level" | "error";

/** A run of triangles (indices start..start+count) drawn with material `material`. */
export interface MaterialGroup { start: number; count: number; material: number }

/** Where a container comes from: a pmcodec server and an asset id, or a .pmc URL on any host. */
export type Source = { server: string; asset: string } | { url: string };

export type ToWorker =
  | { type: "open"; source: Source; cacheBytes?: number; readAhead?: number; headers?: Record<string, string>; gpuSkin?: boolean }
  /** The frame the page shows now, and whether it plays (the worker decodes ahead only then). */
  | { type: "playhead"; frame: number; playing: boolean }
  /**
   * A jump: frames decoded before it are of no use; `seq` tags what follows. With `coarse`, a
   * coarse cut comes first when the budget's takes a keyframe and steps.
   */
  | { type: "seek"; frame: number; seq: number; coarse: boolean }
  | { type: "budget"; triangles: number }
  | { type: "colour"; mode: ColourMode };

export interface OpenedInfo {
  frames: number; frameRate: number; vertices: number; triangles: number; levels: number[];
  trianglesPerLevel: number[]; keyframeInterval: number; bboxMin: number[]; bboxMax: number[];
  /** Container bytes, and its format version. */
  bytes: number; version: number;
  /** Whether the stream carries appearance (version 6): texture coordinates, colours, materials. */
  appearance: boolean;
  /**
   * Skinned streams drawn by skinning on the GPU: the palette's entries (the skeleton's bones);
   * 0 when frames carry posed positions.
   */
  gpuSkinJoints: number;
}

/**
 * A skinned stream's frame when the GPU skins it (FramePayload.skin): the vertex shader draws
 * each vertex at sum_k w_k M_k b + o, with b its bind position, (joint, weight) pairs w_k and
 * M_k from the palette, and o its offset (the decoder's DecoderOptions.skinOffsets).
 */
export interface SkinFrame {
  /**
   * The cut's per-vertex skin: bind positions (3 floats a vertex), four palette entries and
   * weights, and normals of the bind pose (skinned by the shader with the positions); sent when
   * `version` changes (the cut changed), absent otherwise.
   */
  version: number;
  bind?: Float32Array; joints?: Uint16Array; weights?: Float32Array; normals?: Float32Array;
  /** The frame's palette: 16 floats per entry, column-major (three.js Matrix4 elements). */
  palette: Float32Array;
  /**
   * Offsets, versioned as the index buffers: with `offsets`, version `offsetsVersion` is that
   * array (3 floats a vertex); with `changed` and `values`, it is version `offsetsVersion - 1`
   * with the vertices `changed` set to `values` (3 floats each); with neither, the frame uses
   * version `offsetsVersion` as sent before. Every payload that carries offsets reaches the page.
   */
  offsetsVersion: number;
  offsets?: Float32Array; changed?: Uint32Array; values?: Float32Array;
  /** A geomorph's start: each vertex's bind position and offset blend from these to its own. */
  startBind?: Float32Array; startOffsets?: Float32Array;
}

/** A stream's materials and images (the encoded bytes, decoded on the page). */
export interface LooksPayload {
  type: "looks"; materials: Materials; images: { name: string | null; mimeType: string; bytes: Uint8Array }[];
  /** Whether vertices carry colours (COLOR_0), which multiply the base colour. */
  vertexColors: boolean;
  /** Whether the input had normals; without them glTF draws flat (see BuildOptions.flatShading). */
  normals: boolean;
}

export interface FramePayload {
  type: "frame";
  /** The seek this frame answers (frames of an older seek are dropped). */
  seq: number;
  frame: number; budget: number; level: number; triangles: number;
  /** The level the budget asks for (the session's `levelFor`): `level` above it is a coarse stand-in. */
  budgetLevel: number;
  /**
   * The cut's vertices (3 floats each) and their normals; its 3 indices per triangle, left out
   * when they equal those of the index version sent last (`indexVersion` names them).
   */
  positions: Float32Array; normals: Float32Array; indices?: Uint32Array; indexVersion: number; indexCount: number;
  /**
   * Where each vertex starts a geomorph from, when the cut changed with the budget; frames of
   * one morph share `morphId` (the page keeps one clock for them).
   */
  starts?: Float32Array; morphId: number;
  /** "level" and "error" modes: 3 floats per vertex; "authored" with vertex colours: 4 (RGBA). */
  colours?: Float32Array;
  /**
   * "authored" mode on a stream with appearance: one vertex per (cut node, chart, smoothing
   * group), its texture coordinates (2 floats per vertex per set) and where a geomorph starts
   * them; triangles sorted by material, one group per material.
   */
  uvs?: Float32Array; uv1?: Float32Array; uvStarts?: Float32Array; uv1Starts?: Float32Array; groups?: MaterialGroup[];
  /** Skinned streams drawn by skinning on the GPU: then `positions` and `normals` are empty. */
  skin?: SkinFrame;
  decodeMs: number; cutMs: number;
  /** Container bytes received and requests made so far, and bytes the cache holds. */
  fetched: number; requests: number; cached: number;
}

export type FromWorker =
  | { type: "opened"; info: OpenedInfo }
  | FramePayload
  | LooksPayload
  | { type: "error"; message: string };
