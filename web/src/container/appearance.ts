// Version 6's appearance, as `pmcodec_container::appearance` (proto/container.md,
// "Appearance"): the Charts, Attributes and Materials chunks read, and a cut's per-corner
// texture coordinates, colours and normals computed bit for bit as the Rust decoder does.

import { breadthFirst, orientation, predictUv } from "./project.js";
import { DecodeError } from "./error.js";
import { AppearanceInfo, channels } from "./format.js";
import { Cursor, Postcard } from "./payload.js";
import { readCodes } from "./codes.js";
import { grownCharts } from "./grown.js";

/** Set in a table's mode (after its first byte 0): value residuals as a rANS section. */
const RANS_VALUES = 8;
/** Set with mode 3 or 1: representatives take their parent entry's values, no residual. */
const REPRESENTED = 16;

/** Frame 0's parents of a band's nodes (its Key chunk) and the band above's table. */
export interface Above { parent: Uint32Array; table: Table }

/**
 * Per entry of a table (entries of node n at first[n]..first[n+1]), the entry of the band above
 * it copies, or -1: the first entry, in table order, whose node's parent has an entry of the
 * same chart above, each entry above represented once (the Rust `representatives`).
 */
export function representatives(first: Uint32Array, charts: Uint32Array, above: Above): Int32Array {
  const t = above.table, claimed = new Uint8Array(t.charts.length), out = new Int32Array(charts.length).fill(-1);
  for (let n = 0; n + 1 < first.length && n < above.parent.length; n++) {
    const p = above.parent[n];
    if (p + 1 >= t.first.length) continue;
    for (let e = first[n]; e < first[n + 1]; e++) {
      for (let x = t.first[p]; x < t.first[p + 1]; x++) {
        if (t.charts[x] !== charts[e]) continue;
        if (!claimed[x]) { claimed[x] = 1; out[e] = x; }
        break;
      }
    }
  }
  return out;
}

/** Each triangle's chart and smoothing group, each chart's material. */
export interface Charts { triangleChart: Uint32Array; triangleGroup: Uint32Array; chartMaterial: Uint32Array }

/** One band's attribute table: entries of node n are first[n]..first[n+1]. */
export interface Table { first: Uint32Array; charts: Uint32Array; values: Int32Array }

export interface TextureRef { texture: number; texCoord: number; transform: { offset: number[]; rotation: number; scale: number[]; texCoord: number | null } | null }
export interface Material {
  name: string | null; baseColorFactor: number[]; baseColorTexture: TextureRef | null; metallicFactor: number; roughnessFactor: number;
  metallicRoughnessTexture: TextureRef | null; normalTexture: TextureRef | null; normalScale: number; occlusionTexture: TextureRef | null;
  occlusionStrength: number; emissiveTexture: TextureRef | null; emissiveFactor: number[]; alphaMode: number; alphaCutoff: number; doubleSided: boolean;
}
export interface Materials {
  materials: Material[];
  textures: { image: number; sampler: number | null }[];
  samplers: { magFilter: number | null; minFilter: number | null; wrapS: number; wrapT: number }[];
  images: { name: string | null; mimeType: string; byteLength: number }[];
}

function runs(c: Cursor, triangles: number, out: Uint32Array, value: () => number, what: string): void {
  const n = c.count(triangles, "runs");
  let at = 0;
  for (let i = 0; i < n; i++) {
    const v = value(), len = c.get();
    if (len === 0 || at + len > triangles) throw new DecodeError(`${what}: a run of ${len} triangles after ${at} of ${triangles}`);
    out.fill(v, at, at + len);
    at += len;
  }
  if (at !== triangles) throw new DecodeError(`${what}: runs cover ${at} of ${triangles} triangles`);
}

/**
 * Recent-chart runs (the Rust `write_charts_recent`): R, then a RESIDUALS section of 2 R codes,
 * per run its chart (0 the next new one, else its position among the charts seen, most recent
 * first) and its length minus 1.
 */
function recentRuns(c: Cursor, raw: Uint8Array, a: AppearanceInfo, triangles: number, out: Uint32Array, what: string): void {
  const n = c.count(triangles, "chart runs"), codes = readCodes(c, raw, n, 2, true, what), recent: number[] = [];
  let next = 0, at = 0;
  for (let i = 0; i < n; i++) {
    const s = codes[i];
    let chart: number;
    if (s === 0) chart = next++;
    else if (s < recent.length) chart = recent.splice(s, 1)[0];
    else throw new DecodeError(`${what}: recent chart ${s} of ${recent.length}`);
    if (chart >= a.charts) throw new DecodeError(`${what}: chart ${chart} out of range`);
    recent.unshift(chart);
    const len = codes[n + i] + 1;
    if (at + len > triangles) throw new DecodeError(`${what}: a run of ${len} triangles after ${at} of ${triangles}`);
    out.fill(chart, at, at + len);
    at += len;
  }
  if (at !== triangles) throw new DecodeError(`${what}: runs cover ${at} of ${triangles} triangles`);
}

/** Whether a Charts payload needs the triangles (mode 3, neighbour charts; mode 4, grown charts). */
export function chartsNeedTriangles(raw: Uint8Array): boolean {
  return raw.length > 1 && raw[0] === 0 && (raw[1] === 3 || raw[1] === 4);
}

/**
 * Neighbour charts (the Rust `write_charts_neighbours`): a RESIDUALS section of one code per
 * triangle: its chart's position among its candidates (the previous triangle's chart, then its
 * earlier edge neighbours' charts, each once), 4 the next new chart, 5 + p the p-th chart of
 * the list of charts seen, most recently used first.
 */
function neighbourCharts(c: Cursor, raw: Uint8Array, a: AppearanceInfo, tris: Uint32Array, out: Uint32Array, what: string): void {
  const n = out.length, codes = readCodes(c, raw, n, 1, true, what), recent: number[] = [], cands: number[] = [];
  let nv = 1;
  for (let i = 0; i < 3 * n; i++) nv = Math.max(nv, tris[i] + 1);
  const edges = new Map<number, number>(), key = (x: number, y: number): number => Math.min(x, y) * nv + Math.max(x, y);
  let next = 0;
  for (let t = 0; t < n; t++) {
    cands.length = 0;
    if (recent.length > 0) cands.push(recent[0]);
    for (let i = 0; i < 3; i++) {
      const u = edges.get(key(tris[3 * t + i], tris[3 * t + ((i + 1) % 3)]));
      if (u !== undefined && !cands.includes(out[u])) cands.push(out[u]);
    }
    const code = codes[t];
    let chart: number;
    if (code < 4) {
      if (code >= cands.length) throw new DecodeError(`${what}: candidate ${code} of ${cands.length} at triangle ${t}`);
      chart = cands[code];
    } else if (code === 4) chart = next;
    else {
      if (code - 5 >= recent.length) throw new DecodeError(`${what}: recent chart ${code} at triangle ${t}`);
      chart = recent[code - 5];
    }
    if (chart >= a.charts) throw new DecodeError(`${what}: chart ${chart} out of range (< ${a.charts}) at triangle ${t}`);
    if (chart === next) next++;
    const at = recent.indexOf(chart);
    if (at >= 0) recent.splice(at, 1);
    recent.unshift(chart);
    out[t] = chart;
    for (let i = 0; i < 3; i++) {
      const k = key(tris[3 * t + i], tris[3 * t + ((i + 1) % 3)]);
      if (!edges.has(k)) edges.set(k, t);
    }
  }
}

/** The Charts chunk; `tris` (the Triangles chunk's corners) for a chunk with neighbour or grown charts (modes 3, 4). */
export function readCharts(raw: Uint8Array, a: AppearanceInfo, triangles: number, tris: Uint32Array | null = null): Charts {
  const what = "charts chunk", c = new Cursor(raw, what);
  // A first byte 0 (a count of charts is at least 1): a coding mode, 1 = new-chart runs,
  // 2 = recent-chart runs, 3 = neighbour charts, 4 = grown charts.
  const coded = raw.length > 0 && raw[0] === 0;
  let mode = 0;
  if (coded) {
    c.get();
    mode = c.get();
    if (mode < 1 || mode > 4) throw new DecodeError(`${what}: charts coding ${mode} unknown`);
    if (mode >= 3 && !tris) throw new DecodeError(`${what}: neighbour charts without the triangles`);
    if (mode >= 3 && tris!.length !== 3 * triangles) throw new DecodeError(`${what}: ${tris!.length / 3} triangles where the header says ${triangles}`);
  }
  const newRuns = mode === 1;
  const n = c.count(a.charts, "charts");
  if (n !== a.charts || n > raw.length) throw new DecodeError(`${what}: ${n} charts where the header says ${a.charts}`);
  const chartMaterial = new Uint32Array(n);
  for (let i = 0; i < n; i++) chartMaterial[i] = c.id(Math.max(a.materials, 1), "material");
  const triangleChart = new Uint32Array(triangles), triangleGroup = new Uint32Array(triangles);
  let next = 0;
  if (mode === 2) recentRuns(c, raw, a, triangles, triangleChart, what);
  else if (mode === 3) neighbourCharts(c, raw, a, tris!, triangleChart, what);
  else if (mode === 4) grownCharts(c, raw, a.charts, tris!, triangleChart, what);
  else runs(c, triangles, triangleChart, () => {
    if (!newRuns) return c.id(a.charts, "chart");
    const x = c.get(), chart = x === 0 ? next++ : x - 1;
    if (chart >= a.charts) throw new DecodeError(`${what}: chart ${chart} out of range`);
    return chart;
  }, what);
  let last = 0;
  runs(c, triangles, triangleGroup, () => {
    const g = (last + c.zigzag()) >>> 0;
    if (g >= a.groups) throw new DecodeError(`${what}: smoothing group ${g} out of range`);
    return (last = g);
  }, what);
  c.finish();
  return { triangleChart, triangleGroup, chartMaterial };
}

/** Set with mode 3: the entries coded from the band above's (`readEntriesAbove`). */
const ENTRIES_ABOVE = 32;

/** `m` entries listed (node differences, charts as is or as differences within a node), ascending. */
function readEntries(c: Cursor, m: number, nodes: number, nCharts: number, what: string): [number, number][] {
  const out: [number, number][] = [];
  let pn = -1, pc = -1;
  for (let e = 0; e < m; e++) {
    const d = c.get(), rc = c.get();
    let node: number, chart: number;
    if (pn >= 0 && d === 0) { node = pn; chart = pc + rc + 1; } else if (pn >= 0) { node = pn + d; chart = rc; } else { node = d; chart = rc; }
    if (node >= nodes || chart >= nCharts) throw new DecodeError(`${what}: entry (node ${node}, chart ${chart}) out of range`);
    pn = node; pc = chart;
    out.push([node, chart]);
  }
  return out;
}

/** The charts of the band above's entries of node's parent (first and end into its table), or none. */
function candidates(above: Above, node: number): [number, number] {
  if (node >= above.parent.length) return [0, 0];
  const p = above.parent[node], t = above.table;
  return p + 1 < t.first.length ? [t.first[p], t.first[p + 1]] : [0, 0];
}

/**
 * ENTRIES FROM ABOVE (the Rust `put_entries_above`): `n`, a bit per (node c < n, chart of an
 * entry of c's parent above), then the entries in charts their parent has none in, listed.
 */
function readEntriesAbove(c: Cursor, raw: Uint8Array, nodes: number, nCharts: number, limit: number, above: Above, what: string): [number, number][] {
  const n = c.get();
  if (n > nodes) throw new DecodeError(`${what}: entries of ${n} nodes where the band has ${nodes}`);
  let total = 0;
  for (let node = 0; node < n; node++) { const [lo, hi] = candidates(above, node); total += hi - lo; }
  const len = Math.ceil(total / 8);
  if (c.pos + len > raw.length) throw new DecodeError(`${what}: ${len} bytes wanted at byte ${c.pos} of ${raw.length}`);
  const bits = raw.subarray(c.pos, c.pos + len);
  c.pos += len;
  const out: [number, number][] = [];
  let at = 0;
  for (let node = 0; node < n; node++) {
    const [lo, hi] = candidates(above, node);
    for (let x = lo; x < hi; x++, at++) if ((bits[at >> 3] >> (at & 7)) & 1) out.push([node, above.table.charts[x]]);
  }
  if (at % 8 !== 0 && bits[len - 1] >> (at % 8) !== 0) throw new DecodeError(`${what}: bits set beyond the candidates`);
  const x = c.count(limit, "listed entries");
  if (2 * x > raw.length - c.pos) throw new DecodeError(`${what}: ${x} listed entries in ${raw.length - c.pos} bytes`);
  const extras = readEntries(c, x, n, nCharts, what);
  if (out.length + x > limit) throw new DecodeError(`${what}: ${out.length + x} entries, more than ${limit}`);
  out.push(...extras);
  out.sort((p, q) => p[0] - q[0] || p[1] - q[1]);
  for (let e = 1; e < out.length; e++) if (out[e][0] === out[e - 1][0] && out[e][1] === out[e - 1][1]) throw new DecodeError(`${what}: an entry both in its parent's charts and listed`);
  return out;
}

/** Set with mode 3: the values are predicted across the band's faces in frame 0 (`bandFaces`). */
const ACROSS_FACES = 64;

/** Whether a table's payload needs the band above: values from it (mode 3), represented (| 16), entries from it (| 32) or across the faces (| 64). */
export function needsAbove(raw: Uint8Array): boolean {
  return raw.length > 1 && raw[0] === 0 && ((raw[1] & ~RANS_VALUES) === 3 || (raw[1] & (REPRESENTED | ENTRIES_ABOVE | ACROSS_FACES)) !== 0);
}

/** Whether a table's payload predicts its values across the band's faces (mode 3 | 64; its reader needs `bandFaces`). */
export function needsFaces(raw: Uint8Array): boolean {
  return raw.length > 1 && raw[0] === 0 && (raw[1] & ACROSS_FACES) !== 0;
}

/** A band's faces in frame 0: corners (3 per face) and each face's chart. */
export interface Faces { corners: Uint32Array; charts: Uint32Array }

/**
 * Band j's faces in frame 0 (the Rust `band_faces`): every input triangle, in input order,
 * whose corners walked up `parents` (frame 0's parent maps of levels 0..j, finest first) are
 * three distinct level-j nodes, with those nodes and the triangle's chart.
 */
export function bandFaces(triangles: Uint32Array, triangleChart: Uint32Array, parents: Uint32Array[], what: string): Faces {
  const corners: number[] = [], charts: number[] = [], c = [0, 0, 0];
  for (let t = 0; t < triangleChart.length; t++) {
    for (let i = 0; i < 3; i++) {
      let v = triangles[3 * t + i];
      for (const p of parents) {
        if (v >= p.length) throw new DecodeError(`${what}: a frame 0 parent map misses a node`);
        v = p[v];
      }
      c[i] = v;
    }
    if (c[0] !== c[1] && c[1] !== c[2] && c[2] !== c[0]) { corners.push(c[0], c[1], c[2]); charts.push(triangleChart[t]); }
  }
  return { corners: Uint32Array.from(corners), charts: Uint32Array.from(charts) };
}

/**
 * The values of a table across its faces (the Rust `across::read_values`): representatives
 * known, then the faces traversed in order (parallelogram, mean or one known corner, each
 * averaged with the parent entry's value above; with no known corner that value, else the
 * chart's last, else the last), then the entries no face reached in table order (the parent
 * entry's value, else the entry before's).
 */
function acrossValues(first: Uint32Array, charts: Uint32Array, nodeOf: Uint32Array, reps: Int32Array, ch: number, above: Above, faces: Faces, codes: Uint32Array, coded: number, what: string): Int32Array {
  const m = charts.length, values = new Int32Array(m * ch), known = new Uint8Array(m), up = above.table;
  for (let e = 0; e < m; e++) {
    if (reps[e] < 0) continue;
    if ((reps[e] + 1) * ch > up.values.length) throw new DecodeError(`${what}: band above without values`);
    for (let s = 0; s < ch; s++) values[e * ch + s] = up.values[reps[e] * ch + s];
    known[e] = 1;
  }
  const find = (t: Table | { first: Uint32Array; charts: Uint32Array }, v: number, k: number): number => {
    if (v + 1 >= t.first.length) return -1;
    for (let x = t.first[v]; x < t.first[v + 1]; x++) if (t.charts[x] === k) return x;
    return -1;
  };
  // The band above's entry (parent, chart) of each entry, or -1.
  const parentEntry = new Int32Array(m).fill(-1);
  for (let e = 0; e < m; e++) if (nodeOf[e] < above.parent.length) parentEntry[e] = find(up, above.parent[nodeOf[e]], charts[e]);
  const parentValue = (x: number, s: number): number | null => {
    const a = parentEntry[x];
    return a >= 0 && (a + 1) * ch <= up.values.length ? up.values[a * ch + s] : null;
  };
  let k = 0;
  const pred = new Int32Array(ch);
  const visit = (x: number): void => {
    if (k >= coded) throw new DecodeError(`${what}: fewer residuals than entries`);
    for (let s = 0; s < ch; s++) { const z = codes[s * coded + k]; values[x * ch + s] = (pred[s] + ((z >>> 1) ^ -(z & 1))) | 0; }
    k++;
    known[x] = 1;
  };
  const nf = faces.charts.length, e = [0, 0, 0];
  let nc = 0;
  for (let f = 0; f < nf; f++) nc = Math.max(nc, faces.charts[f] + 1);
  const last = new Int32Array(ch), chartLast = new Int32Array(nc * ch), chartSeen = new Uint8Array(nc);
  const opposite = new Map<number, number>(), key = (x: number, y: number): number => Math.min(x, y) * m + Math.max(x, y);
  const entries = new Int32Array(3 * nf);
  for (let f = 0; f < nf; f++) {
    for (let i = 0; i < 3; i++) {
      const x = find({ first, charts }, faces.corners[3 * f + i], faces.charts[f]);
      if (x < 0) throw new DecodeError(`${what}: no entry for node ${faces.corners[3 * f + i]}, chart ${faces.charts[f]} of face ${f}`);
      entries[3 * f + i] = x;
    }
  }
  for (let f = 0; f < nf; f++) {
    const chart = faces.charts[f];
    for (let i = 0; i < 3; i++) e[i] = entries[3 * f + i];
    for (let i = 0; i < 3; i++) {
      const x = e[i];
      if (known[x]) continue;
      const a = e[(i + 1) % 3], b = e[(i + 2) % 3], ka = known[a] === 1, kb = known[b] === 1, o = opposite.get(key(a, b));
      for (let s = 0; s < ch; s++) {
        const va = values[a * ch + s], vb = values[b * ch + s], p = parentValue(x, s);
        let fromCorners: number | null = null;
        if (ka && kb) fromCorners = o !== undefined ? (va + vb - values[o * ch + s]) | 0 : ((va + vb) | 0) >> 1;
        else if (ka) fromCorners = va;
        else if (kb) fromCorners = vb;
        if (fromCorners !== null) pred[s] = p !== null ? ((fromCorners + p) | 0) >> 1 : fromCorners;
        else if (p !== null) pred[s] = p;
        else pred[s] = chartSeen[chart] ? chartLast[chart * ch + s] : last[s];
      }
      visit(x);
      for (let s = 0; s < ch; s++) last[s] = chartLast[chart * ch + s] = values[x * ch + s];
      chartSeen[chart] = 1;
    }
    for (let i = 0; i < 3; i++) {
      const kk = key(e[i], e[(i + 1) % 3]);
      if (!opposite.has(kk)) opposite.set(kk, e[(i + 2) % 3]);
    }
  }
  for (let x = 0; x < m; x++) {
    if (known[x]) continue;
    for (let s = 0; s < ch; s++) pred[s] = parentValue(x, s) ?? (x > 0 ? values[(x - 1) * ch + s] : 0);
    visit(x);
  }
  return values;
}

/**
 * `above`: frame 0's parents of the band's nodes (its Key chunk) and the band above's table,
 * which a table predicting its values from the band above needs (mode 3).
 */
export function readTable(raw: Uint8Array, what: string, nodes: number, a: AppearanceInfo, triangles: number, above: Above | null = null, faces: Faces | null = null): Table {
  const ch = channels(a), c = new Cursor(raw, what);
  // A first byte 0 with more after it: a coding mode (2: values chart-wise; 3: from the band
  // above, else chart-wise, | 16 with represented values; 1 is band 0's).
  let chartwise = false, rans = false, represented = false, entriesAbove = false, across = false, fromAbove: Above | null = null;
  if (raw.length > 1 && raw[0] === 0) {
    c.get();
    const coding = c.get();
    rans = (coding & RANS_VALUES) !== 0;
    entriesAbove = (coding & ENTRIES_ABOVE) !== 0;
    across = (coding & ACROSS_FACES) !== 0;
    const mode = coding & ~(RANS_VALUES | ENTRIES_ABOVE | ACROSS_FACES);
    if ((mode & ~REPRESENTED) === 1 && !entriesAbove && !across) throw new DecodeError(`${what}: derived entries outside band 0`);
    const known = entriesAbove || across ? mode === 3 || mode === (3 | REPRESENTED) : mode === 2 || mode === 3 || mode === (3 | REPRESENTED) || (mode === 0 && rans);
    if (!known) throw new DecodeError(`${what}: table coding ${coding} unknown`);
    if ((mode & 3) === 3 && !above) throw new DecodeError(`${what}: values from the band above, at the top or without it`);
    chartwise = mode !== 0;
    represented = (mode & REPRESENTED) !== 0;
    if ((mode & 3) === 3) fromAbove = above;
  }
  const limit = Math.min(nodes * a.charts, 3 * triangles);
  let list: [number, number][];
  if (entriesAbove && fromAbove) list = readEntriesAbove(c, raw, nodes, a.charts, limit, fromAbove, what);
  else {
    const count = c.count(limit, "entries");
    // Entries take two bytes at least; varint values one more each (rANS or represented values may take less).
    if (count * (rans || represented ? 2 : 2 + ch) > raw.length) throw new DecodeError(`${what}: ${count} entries in ${raw.length} bytes`);
    list = readEntries(c, count, nodes, a.charts, what);
  }
  const m = list.length;
  const first = new Uint32Array(nodes + 1), charts = new Uint32Array(m), nodeOf = new Uint32Array(m);
  list.forEach(([node, chart], e) => { nodeOf[e] = node; charts[e] = chart; first[node + 1]++; });
  for (let n = 0; n < nodes; n++) first[n + 1] += first[n];
  const reps = represented && fromAbove ? representatives(first, charts, fromAbove) : new Int32Array(m).fill(-1);
  let coded = m;
  for (let e = 0; e < m; e++) if (reps[e] >= 0) coded--;
  const codes = readCodes(c, raw, coded, ch, rans, what);
  if (across) {
    if (!fromAbove || !faces) throw new DecodeError(`${what}: values across the band's faces without its faces`);
    const values = acrossValues(first, charts, nodeOf, reps, ch, fromAbove, faces, codes, coded, what);
    c.finish();
    return { first, charts, values };
  }
  const values = new Int32Array(m * ch);
  for (let k = 0; k < ch; k++) {
    // The previous value of the entry's chart (chart-wise) or of any entry (slot 0).
    const last = new Int32Array(chartwise ? a.charts : 1);
    let at = k * coded;
    for (let e = 0; e < m; e++) {
      const slot = chartwise ? charts[e] : 0;
      if (reps[e] >= 0) {
        // A representative: its parent entry's value, no residual (0 past the band above's values).
        last[slot] = values[e * ch + k] = fromAbove!.table.values[reps[e] * ch + k] ?? 0;
        continue;
      }
      let pred = last[slot];
      if (fromAbove && nodeOf[e] < fromAbove.parent.length) {
        // The entry (parent, chart) of the band above, when it has one.
        const t = fromAbove.table, p = fromAbove.parent[nodeOf[e]];
        if (p + 1 < t.first.length) for (let x = t.first[p]; x < t.first[p + 1]; x++) if (t.charts[x] === charts[e]) { pred = t.values[x * ch + k]; break; }
      }
      const z = codes[at++];
      last[slot] = values[e * ch + k] = (pred + ((z >>> 1) ^ -(z & 1))) | 0;
    }
  }
  c.finish();
  return { first, charts, values };
}

/** Band 0's entries: every triangle corner's (vertex, chart), ascending, as [vertex, chart] pairs. */
export function band0Entries(triangles: Uint32Array, triangleChart: Uint32Array): [number, number][] {
  const seen = new Set<number>(), out: [number, number][] = [];
  // Exact keys (below 2^53 for any mesh a browser holds): vertex * charts + chart.
  let nc = 1;
  for (let t = 0; t < triangleChart.length; t++) nc = Math.max(nc, triangleChart[t] + 1);
  for (let t = 0; t < triangleChart.length; t++) {
    for (let i = 0; i < 3; i++) {
      const v = triangles[3 * t + i], k = triangleChart[t], key = v * nc + k;
      if (!seen.has(key)) { seen.add(key); out.push([v, k]); }
    }
  }
  return out.sort((a, b) => a[0] - b[0] || a[1] - b[1]);
}

/**
 * The Attributes chunk of band 0, whichever its coding: entries listed (`readTable`) or, after a
 * first byte 0 and the mode 1, derived from the triangles and charts, with values predicted
 * across the triangles (proto/container.md, "Attributes, band 0 with derived entries"; the
 * Rust `read_table_with`).
 */
/** Set with mode 1 (band 0): texture coordinate set 0 predicted from the bind positions of the Bind chunk of band 0 (`predictUv`). */
const BIND_POSITIONS = 4;

/** Whether band 0's payload predicts texture coordinates from the bind positions of the level-0 nodes (`readBand0Table` then needs them). */
export function needsBind(raw: Uint8Array): boolean {
  return raw.length > 1 && raw[0] === 0 && (raw[1] & ~(RANS_VALUES | REPRESENTED | ACROSS_FACES | BIND_POSITIONS)) === 1 && (raw[1] & BIND_POSITIONS) !== 0;
}

export function readBand0Table(raw: Uint8Array, what: string, nodes: number, a: AppearanceInfo, triangles: Uint32Array, triangleChart: Uint32Array, above: Above | null = null, bind: BigInt64Array | null = null): Table {
  if (raw.length <= 1 || raw[0] !== 0 || (raw[1] & ~(RANS_VALUES | REPRESENTED | ACROSS_FACES | BIND_POSITIONS)) !== 1) return readTable(raw, what, nodes, a, triangleChart.length, above);
  const ch = channels(a), c = new Cursor(raw, what);
  c.get();
  const coding = c.get(), rans = (coding & RANS_VALUES) !== 0, represented = (coding & REPRESENTED) !== 0, across = (coding & ACROSS_FACES) !== 0;
  const byBind = (coding & BIND_POSITIONS) !== 0;
  if ((across && (!represented || byBind)) || (byBind && a.uvSets === 0)) throw new DecodeError(`${what}: table coding ${coding} unknown`);
  if (byBind && !bind) throw new DecodeError(`${what}: bind positions needed and not given`);
  if (represented && !above) throw new DecodeError(`${what}: represented values without the band above`);
  if (triangles.length !== 3 * triangleChart.length) throw new DecodeError(`${what}: triangles and charts disagree`);
  const entries = band0Entries(triangles, triangleChart), m = entries.length;
  for (const [n, k] of entries) if (n >= nodes || k >= a.charts) throw new DecodeError(`${what}: entry (node ${n}, chart ${k}) out of range`);
  const first = new Uint32Array(nodes + 1), charts = new Uint32Array(m);
  entries.forEach(([n, k], e) => { first[n + 1]++; charts[e] = k; });
  for (let n = 0; n < nodes; n++) first[n + 1] += first[n];
  if (across) {
    // Mode 1 | 16 | 64: values across the triangles (band 0's faces), averaged with the parent entry's.
    const nodeOf = Uint32Array.from(entries, ([n]) => n), reps = representatives(first, charts, above!);
    let coded = m;
    for (let e = 0; e < m; e++) if (reps[e] >= 0) coded--;
    const codes = readCodes(c, raw, coded, ch, rans, what);
    c.finish();
    const values = acrossValues(first, charts, nodeOf, reps, ch, above!, bandFaces(triangles, triangleChart, [], what), codes, coded, what);
    return { first, charts, values };
  }
  // Representatives take their parent entry's values before the traversal, which skips them.
  const values = new Int32Array(m * ch), known = new Uint8Array(m);
  let coded = m;
  if (represented) {
    const reps = representatives(first, charts, above!), up = above!.table.values;
    for (let e = 0; e < m; e++) {
      if (reps[e] < 0) continue;
      if ((reps[e] + 1) * ch > up.length) throw new DecodeError(`${what}: band above without values`);
      for (let s = 0; s < ch; s++) values[e * ch + s] = up[reps[e] * ch + s];
      known[e] = 1;
      coded--;
    }
  }
  if (!rans && coded * ch > raw.length) throw new DecodeError(`${what}: ${coded} entries in ${raw.length} bytes`);
  const residuals = new Int32Array(coded * ch), codes = readCodes(c, raw, coded, ch, rans, what);
  for (let i = 0; i < coded * ch; i++) residuals[i] = (codes[i] >>> 1) ^ -(codes[i] & 1);
  c.finish();
  const find = (v: number, k: number): number => {
    if (v >= nodes) return -1;
    for (let x = first[v]; x < first[v + 1]; x++) if (charts[x] === k) return x;
    return -1;
  };
  // The traversal of the Rust `traverse`: triangles in input order, corners in order; an
  // unknown corner is predicted by the parallelogram across an earlier triangle's edge, else
  // the mean of two known corners, else one known corner, else the last entry made known in
  // the triangle's chart, else the last entry made known.
  const last = new Int32Array(ch), e = [0, 0, 0], predicted = new Int32Array(ch);
  // The last entry made known in each chart, if any.
  let nc = 0;
  for (let t = 0; t < triangleChart.length; t++) nc = Math.max(nc, triangleChart[t] + 1);
  const chartLast = new Int32Array(nc * ch), chartSeen = new Uint8Array(nc);
  const opposite = new Map<number, number>();
  const key = (x: number, y: number): number => Math.min(x, y) * m + Math.max(x, y);
  // With bind positions, each chart's orientation in texture space: its last whole triangle's.
  const side = new Int32Array(nc).fill(1), uv = (x: number): [number, number] => [values[x * ch], values[x * ch + 1]];
  let visited = 0;
  // With bind positions, the triangles breadth first within their charts; else in input order.
  const order = bind ? breadthFirst(triangles, triangleChart) : null;
  for (let o = 0; o < triangleChart.length; o++) {
    const t = order ? order[o] : o, chart = triangleChart[t];
    for (let i = 0; i < 3; i++) {
      e[i] = find(triangles[3 * t + i], chart);
      if (e[i] < 0) throw new DecodeError(`${what}: no entry for vertex ${triangles[3 * t + i]}, chart ${chart} of triangle ${t}`);
    }
    for (let i = 0; i < 3; i++) {
      const x = e[i];
      if (known[x]) continue;
      const p = e[(i + 1) % 3], q = e[(i + 2) % 3], kp = known[p] === 1, kq = known[q] === 1, o = opposite.get(key(p, q));
      for (let s = 0; s < ch; s++) {
        const vp = values[p * ch + s], vq = values[q * ch + s];
        let pred: number;
        if (kp && kq) pred = o !== undefined ? (vp + vq - values[o * ch + s]) | 0 : ((vp + vq) | 0) >> 1;
        else if (kp) pred = vp;
        else if (kq) pred = vq;
        else pred = chartSeen[chart] ? chartLast[chart * ch + s] : last[s];
        predicted[s] = pred;
      }
      // Texture coordinate set 0 from the bind positions, where both edge corners are known.
      if (bind && kp && kq && ch >= 2) {
        const [va, vb, vx] = [1, 2, 0].map((r) => triangles[3 * t + ((i + r) % 3)]);
        if (3 * Math.max(va, vb, vx) + 2 >= bind.length) throw new DecodeError(`${what}: no position for vertex ${Math.max(va, vb, vx)} of triangle ${t}`);
        const uvx = predictUv(bind, va, vb, vx, uv(p), uv(q), side[chart]);
        if (uvx) [predicted[0], predicted[1]] = uvx;
      }
      for (let s = 0; s < ch; s++) values[x * ch + s] = (predicted[s] + residuals[s * coded + visited]) | 0;
      visited++;
      known[x] = 1;
      for (let s = 0; s < ch; s++) last[s] = chartLast[chart * ch + s] = values[x * ch + s];
      chartSeen[chart] = 1;
    }
    if (e[0] !== e[1] && e[1] !== e[2] && e[2] !== e[0]) {
      for (let i = 0; i < 3; i++) {
        const k = key(e[i], e[(i + 1) % 3]);
        if (!opposite.has(k)) opposite.set(k, e[(i + 2) % 3]);
      }
      if (bind && ch >= 2) {
        const o = orientation(uv(e[0]), uv(e[1]), uv(e[2]));
        if (o !== 0) side[chart] = o;
      }
    }
  }
  return { first, charts, values };
}

/** The Materials chunk (postcard). */
export function readMaterials(raw: Uint8Array, a: AppearanceInfo): Materials {
  const p = new Postcard(raw, "materials chunk");
  const ref = (): TextureRef => ({
    texture: p.varint(), texCoord: p.varint(),
    transform: p.option(() => ({ offset: [p.f32(), p.f32()], rotation: p.f32(), scale: [p.f32(), p.f32()], texCoord: p.option(() => p.varint()) })),
  });
  const materials = p.seq((): Material => ({
    name: p.option(() => p.str()), baseColorFactor: [p.f32(), p.f32(), p.f32(), p.f32()], baseColorTexture: p.option(ref),
    metallicFactor: p.f32(), roughnessFactor: p.f32(), metallicRoughnessTexture: p.option(ref), normalTexture: p.option(ref), normalScale: p.f32(),
    occlusionTexture: p.option(ref), occlusionStrength: p.f32(), emissiveTexture: p.option(ref), emissiveFactor: [p.f32(), p.f32(), p.f32()],
    alphaMode: p.u8(), alphaCutoff: p.f32(), doubleSided: p.bool(),
  }), 1 << 16);
  const textures = p.seq(() => ({ image: p.varint(), sampler: p.option(() => p.varint()) }), 1 << 16);
  const samplers = p.seq(() => ({ magFilter: p.option(() => p.varint()), minFilter: p.option(() => p.varint()), wrapS: p.varint(), wrapT: p.varint() }), 1 << 16);
  const images = p.seq(() => ({ name: p.option(() => p.str()), mimeType: p.str(), byteLength: p.varint() }), 1 << 12);
  if (p.pos !== raw.length) throw new DecodeError(`materials chunk: ${raw.length - p.pos} bytes left over`);
  if (materials.length !== a.materials || images.length !== a.images) throw new DecodeError("materials chunk: counts disagree with the header");
  for (const m of materials) {
    if (m.alphaMode > 2) throw new DecodeError(`materials chunk: alpha mode ${m.alphaMode}`);
    for (const r of [m.baseColorTexture, m.metallicRoughnessTexture, m.normalTexture, m.occlusionTexture, m.emissiveTexture]) {
      if (r && r.texture >= textures.length) throw new DecodeError(`materials chunk: texture ${r.texture} out of range`);
    }
  }
  for (const t of textures) {
    if (t.image >= images.length || (t.sampler !== null && t.sampler >= samplers.length)) throw new DecodeError("materials chunk: image or sampler out of range");
  }
  return { materials, textures, samplers, images };
}

/** A cut's mesh with its appearance: one vertex per (cut node, chart, group). */
export interface TexturedMesh {
  positions: Float32Array; normals: Float32Array; uv0: Float32Array | null; uv1: Float32Array | null; colors: Float32Array | null;
  indices: Uint32Array; triangleMaterial: Uint32Array;
  /** Each vertex's cut node (global id) and chart: what a geomorph needs to find its start. */
  nodes: Uint32Array; charts: Uint32Array;
  /** Vertices whose (node, chart) entry was missing and filled in (`lenient` only; else 0). */
  missing: number;
}

/** The level a global node id belongs to, `offsets` the levels' first global ids. */
function levelOfNode(offsets: number[], g: number): number {
  let l = 0;
  while (l + 1 < offsets.length && offsets[l + 1] <= g) l++;
  return l;
}

/**
 * The quantized attribute values (texture coordinates, then colours: `channels` of them) of
 * node `g` (global id) in `chart`, or null when the node has no entry for that chart or its
 * band's table is not read. A geomorph starts a vertex's texture coordinates at those of the
 * node it comes from, in the vertex's own chart.
 */
export function attributeEntry(a: AppearanceInfo, tables: (Table | null)[], offsets: number[], g: number, chart: number): Int32Array | null {
  const ch = channels(a), level = levelOfNode(offsets, g), tb = tables[level];
  if (!tb) return null;
  const local = g - offsets[level];
  if (local < 0 || local + 1 >= tb.first.length) return null;
  for (let x = tb.first[local]; x < tb.first[local + 1]; x++) if (tb.charts[x] === chart) return tb.values.subarray(x * ch, x * ch + ch);
  return null;
}

/** Texture coordinate `q` (quantized) on `axis`, as `texturedMesh` dequantizes it. */
export function dequantizeUv(a: AppearanceInfo, axis: number, q: number): number {
  return a.uvMin[axis] + q * a.uvStep[axis];
}

/**
 * The appearance of a cut: `shown` lists the shown triangles in mesh order, `cut` their corners'
 * cut nodes (global ids, 3 per triangle); `offsets` the levels' first global ids; `positions`
 * 3 floats per global id (proto/container.md, "Drawing a cut's appearance").
 */
export function texturedMesh(
  a: AppearanceInfo, charts: Charts, tables: (Table | null)[], offsets: number[], positions: Float32Array, shown: ArrayLike<number>, cut: ArrayLike<number>,
  options: { lenient?: boolean } = {},
): TexturedMesh {
  let missing = 0;
  const ch = channels(a), nt = shown.length;
  const vertexOf = new Map<string, number>();
  const key: number[] = [], nodeOfVertex: number[] = [], chartOfVertex: number[] = [], values: number[] = [];
  const sums = new Map<string, number[]>();
  const indices = new Uint32Array(3 * nt), triangleMaterial = new Uint32Array(nt);
  const levelOf = (g: number): number => levelOfNode(offsets, g);
  // Pushes the `ch` values of (g, chart) for corner g of shown triangle i.
  const lookUp = (g: number, i: number, chart: number): void => {
    const level = levelOf(g), local = g - offsets[level], tb = tables[level];
    let e = -1;
    if (tb) for (let x = tb.first[local]; x < tb.first[local + 1]; x++) if (tb.charts[x] === chart) { e = x; break; }
    if (tb && e >= 0) for (let q = 0; q < ch; q++) values.push(tb.values[e * ch + q]);
    else if (options.lenient && tb) {
      // A viewer's choice, not the format's (the specification makes a missing entry a
      // corrupt file): the mean of the triangle's other corners' entries in the chart,
      // else the node's first entry, else zeros, so one bad entry does not blank a frame.
      missing++;
      const others = [cut[3 * i], cut[3 * i + 1], cut[3 * i + 2]].filter((x) => x !== g)
        .map((x) => attributeEntry(a, tables, offsets, x, chart)).filter((x): x is Int32Array => x !== null);
      for (let q = 0; q < ch; q++) {
        if (others.length > 0) values.push(Math.round(others.reduce((acc, x) => acc + x[q], 0) / others.length));
        else values.push(tb.first[local] < tb.first[local + 1] ? tb.values[tb.first[local] * ch + q] : 0);
      }
    } else throw new DecodeError(`band ${level} attributes: no entry for node ${local}, chart ${chart}`);
  };
  for (let i = 0; i < nt; i++) {
    const t = shown[i], chart = charts.triangleChart[t], group = charts.triangleGroup[t];
    const g0 = cut[3 * i], g1 = cut[3 * i + 1], g2 = cut[3 * i + 2];
    const e1x = positions[3 * g1] - positions[3 * g0], e1y = positions[3 * g1 + 1] - positions[3 * g0 + 1], e1z = positions[3 * g1 + 2] - positions[3 * g0 + 2];
    const e2x = positions[3 * g2] - positions[3 * g0], e2y = positions[3 * g2 + 1] - positions[3 * g0 + 1], e2z = positions[3 * g2 + 2] - positions[3 * g0 + 2];
    const n = [e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x];
    for (let c = 0; c < 3; c++) {
      const g = cut[3 * i + c], k = `${g}/${chart}/${group}`;
      let v = vertexOf.get(k);
      if (v === undefined) {
        v = nodeOfVertex.length;
        vertexOf.set(k, v);
        // Without channels there are no tables and nothing to look up.
        if (ch > 0) lookUp(g, i, chart);
        nodeOfVertex.push(g);
        chartOfVertex.push(chart);
        key.push(group);
      }
      indices[3 * i + c] = v;
      const sk = `${g}/${group}`;
      const s = sums.get(sk);
      if (s) { s[0] += n[0]; s[1] += n[1]; s[2] += n[2]; } else sums.set(sk, [0 + n[0], 0 + n[1], 0 + n[2]]); // from (0, 0, 0), as specified: 0 + -0 is 0
    }
    triangleMaterial[i] = charts.chartMaterial[chart];
  }
  const nv = nodeOfVertex.length;
  const out: TexturedMesh = {
    positions: new Float32Array(3 * nv), normals: new Float32Array(3 * nv),
    uv0: a.uvSets >= 1 ? new Float32Array(2 * nv) : null, uv1: a.uvSets >= 2 ? new Float32Array(2 * nv) : null,
    colors: a.colors ? new Float32Array(4 * nv) : null, indices, triangleMaterial,
    nodes: Uint32Array.from(nodeOfVertex), charts: Uint32Array.from(chartOfVertex), missing,
  };
  // binary64 from the binary32 fields, rounded once (Float32Array stores round to binary32).
  const uv = (axis: number, q: number): number => dequantizeUv(a, axis, q);
  for (let v = 0; v < nv; v++) {
    const g = nodeOfVertex[v];
    out.positions.set(positions.subarray(3 * g, 3 * g + 3), 3 * v);
    const s = sums.get(`${g}/${key[v]}`)!;
    const len = Math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    if (len > 0 && Number.isFinite(len)) { out.normals[3 * v] = s[0] / len; out.normals[3 * v + 1] = s[1] / len; out.normals[3 * v + 2] = s[2] / len; }
    else out.normals[3 * v + 2] = 1;
    let k = 0;
    if (out.uv0) { out.uv0[2 * v] = uv(0, values[v * ch]); out.uv0[2 * v + 1] = uv(1, values[v * ch + 1]); k = 2; }
    if (out.uv1) { out.uv1[2 * v] = uv(0, values[v * ch + 2]); out.uv1[2 * v + 1] = uv(1, values[v * ch + 3]); k = 4; }
    if (out.colors) for (let c = 0; c < 4; c++) out.colors[4 * v + c] = values[v * ch + k + c] / 255;
  }
  return out;
}
