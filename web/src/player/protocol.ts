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
  | { type: "open"; source: Source; cacheBytes?: number; readAhead?: number; headers?: Record<string, string> }
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
  decodeMs: number; cutMs: number;
  /** Container bytes received and requests made so far, and bytes the cache holds. */
  fetched: number; requests: number; cached: number;
}

export type FromWorker =
  | { type: "opened"; info: OpenedInfo }
  | FramePayload
  | LooksPayload
  | { type: "error"; message: string };
