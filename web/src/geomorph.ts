// Geomorphs between cuts (J. Houle and P. Poulin, "Simplification and Real-time Smooth
// Transitions of Articulated Meshes", 2001, section 5): when the cut changes (the
// budget moved, or the hierarchy changed between frames), each vertex of the new mesh starts at
// the position of the node that stood for it before and moves to its own position over a short
// time, instead of popping.
//
// The correspondence comes from the hierarchy itself: a new cut node whose ancestor was in the
// old cut starts at that ancestor (a refinement: children spread out of their parent); a new
// cut node that is an ancestor of old cut nodes starts at their centroid (a coarsening: the
// parts slide together); a node in both cuts does not morph.

import { NONE, Replay } from "./container/index.js";

/** Render-ready mesh of a cut: one vertex per used cut node, indices into them. */
export interface CutMesh {
  /** Global node id of each vertex. */
  nodes: Uint32Array;
  indices: Uint32Array;
}

/** Slot of each global node in the mesh being built (-1: none), reused between calls. */
let slotOf = new Int32Array(0);

/** Builds the index buffer of the replay's shown triangles over its cut nodes. */
export function buildCutMesh(replay: Replay): CutMesh {
  const rep = replay.cutNodes();
  if (slotOf.length < rep.length) slotOf = new Int32Array(rep.length).fill(-1);
  const shown = replay.shown, corners = replay.corners, base = replay.offsets[replay.minLevel];
  const indices = new Uint32Array(shown.length * 3);
  // At most one vertex per corner; trimmed below.
  const nodes = new Uint32Array(indices.length);
  let n = 0, used = 0;
  for (let k = 0; k < shown.length; k++) {
    const t = shown[k];
    for (let c = 0; c < 3; c++) {
      const g = rep[base + corners[3 * t + c]];
      let i = slotOf[g];
      if (i < 0) { i = used++; slotOf[g] = i; nodes[i] = g; }
      indices[n++] = i;
    }
  }
  // Leave the table clean for the next call: only the slots this mesh set.
  for (let i = 0; i < used; i++) slotOf[nodes[i]] = -1;
  return { nodes: nodes.slice(0, used), indices };
}

/**
 * Start positions for a geomorph from `oldNodes` (the previous cut's vertices) to `mesh`, with
 * `positions` the current frame's node positions (3 floats per global node) and `parentOf`
 * giving each node's parent (NONE at the top).
 */
export function morphStarts(mesh: CutMesh, oldNodes: Uint32Array, positions: Float32Array, parentOf: (g: number) => number): Float32Array {
  const wasCut = new Set<number>(oldNodes);
  const start = new Float32Array(mesh.nodes.length * 3);
  // Centroids of old cut nodes under each new node that is their ancestor (coarsening).
  const sum = new Map<number, [number, number, number, number]>();
  const newSet = new Set<number>(mesh.nodes);
  for (const o of oldNodes) {
    let a = parentOf(o);
    while (a !== NONE && !newSet.has(a)) a = parentOf(a);
    if (a === NONE) continue;
    const s = sum.get(a) ?? [0, 0, 0, 0];
    s[0] += positions[3 * o]; s[1] += positions[3 * o + 1]; s[2] += positions[3 * o + 2]; s[3] += 1;
    sum.set(a, s);
  }
  for (let i = 0; i < mesh.nodes.length; i++) {
    const g = mesh.nodes[i];
    let from = g;
    if (!wasCut.has(g)) {
      let a = parentOf(g);
      while (a !== NONE && !wasCut.has(a)) a = parentOf(a);
      if (a !== NONE) from = a; // refinement: start at the old ancestor
      else {
        const s = sum.get(g);
        if (s && s[3] > 0) { start[3 * i] = s[0] / s[3]; start[3 * i + 1] = s[1] / s[3]; start[3 * i + 2] = s[2] / s[3]; continue; }
      }
    }
    start[3 * i] = positions[3 * from]; start[3 * i + 1] = positions[3 * from + 1]; start[3 * i + 2] = positions[3 * from + 2];
  }
  return start;
}

/**
 * Start values of a per-vertex attribute (texture coordinates) for the geomorph that
 * `morphStarts` gives the positions, so the texture slides with the surface instead of
 * popping. Hoppe ("Progressive Meshes", 1996, section 4.2) morphs every attribute of a vertex
 * split with its position; here a vertex is a (node, chart) pair, and a node has values only in
 * the charts it touches, so the start is taken in the vertex's own chart: a refinement starts
 * at the old ancestor's values, a coarsening at the mean over the old descendants that have
 * values in that chart; a node in both cuts, or one whose source has no values in the chart
 * (a chart that appears with the split), starts at its own values and does not morph.
 *
 * `nodes` and `charts` give each vertex's node and chart, `own` its values (`width` each);
 * `valueOf(g, chart, out, at)` writes node g's values in that chart at out[at..] and tells
 * whether it has any.
 */
export function morphAttributeStarts(
  nodes: Uint32Array, charts: Uint32Array, oldNodes: Uint32Array, own: Float32Array, width: number,
  parentOf: (g: number) => number, valueOf: (g: number, chart: number, out: Float32Array, at: number) => boolean,
): Float32Array {
  const wasCut = new Set<number>(oldNodes), newSet = new Set<number>(nodes);
  const start = own.slice();
  // Old cut nodes under each new node that is their ancestor (coarsening).
  const under = new Map<number, number[]>();
  for (const o of oldNodes) {
    let a = parentOf(o);
    while (a !== NONE && !newSet.has(a)) a = parentOf(a);
    if (a === NONE) continue;
    const list = under.get(a);
    if (list) list.push(o); else under.set(a, [o]);
  }
  const scratch = new Float32Array(width);
  for (let i = 0; i < nodes.length; i++) {
    const g = nodes[i], chart = charts[i];
    if (wasCut.has(g)) continue;
    let a = parentOf(g);
    while (a !== NONE && !wasCut.has(a)) a = parentOf(a);
    if (a !== NONE) { valueOf(a, chart, start, width * i); continue; }
    const list = under.get(g);
    if (!list) continue;
    let n = 0;
    const sum = new Float64Array(width);
    for (const o of list) if (valueOf(o, chart, scratch, 0)) { n++; for (let k = 0; k < width; k++) sum[k] += scratch[k]; }
    if (n > 0) for (let k = 0; k < width; k++) start[width * i + k] = sum[k] / n;
  }
  return start;
}

/** Writes the morphed positions at blend `alpha` (0 = start, 1 = target) into `out`. */
export function blend(mesh: CutMesh, start: Float32Array, positions: Float32Array, alpha: number, out: Float32Array): void {
  const a = Math.min(1, Math.max(0, alpha));
  // Smoothstep: no velocity jump at either end of the morph.
  const s = a * a * (3 - 2 * a);
  for (let i = 0; i < mesh.nodes.length; i++) {
    const g = mesh.nodes[i];
    for (let c = 0; c < 3; c++) out[3 * i + c] = start[3 * i + c] + (positions[3 * g + c] - start[3 * i + c]) * s;
  }
}
