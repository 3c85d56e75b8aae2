// Charts mode 4, grown charts, as `pmcodec_container::appearance::grown_charts`
// (proto/container.md, "Charts"): each chart grown over the triangles' edges from a seed, the
// answers (does the neighbour join?) coded as the lengths of the runs of yes.

import { readCodes } from "./codes.js";
import { DecodeError } from "./error.js";
import { Cursor } from "./payload.js";

/**
 * Each triangle's edge neighbours (the Rust `Neighbours`): for its edges v0v1, v1v2, v2v0 in
 * turn, the other triangles with that edge, either direction, in increasing index.
 */
function neighbours(tris: Uint32Array): { start: Uint32Array; list: Uint32Array } {
  const n = tris.length / 3, byEdge = new Map<number, number[]>();
  // Numeric keys, as neighbourCharts' (appearance.ts): a string a key would allocate per edge.
  let nv = 1;
  for (let i = 0; i < tris.length; i++) nv = Math.max(nv, tris[i] + 1);
  const key = (a: number, b: number): number => Math.min(a, b) * nv + Math.max(a, b);
  for (let t = 0; t < n; t++) {
    for (let i = 0; i < 3; i++) {
      const k = key(tris[3 * t + i], tris[3 * t + ((i + 1) % 3)]);
      const l = byEdge.get(k);
      if (l) l.push(t); else byEdge.set(k, [t]);
    }
  }
  const start = new Uint32Array(n + 1), list: number[] = [];
  for (let t = 0; t < n; t++) {
    for (let i = 0; i < 3; i++) {
      for (const u of byEdge.get(key(tris[3 * t + i], tris[3 * t + ((i + 1) % 3)]))!) if (u !== t) list.push(u);
    }
    start[t + 1] = list.length;
  }
  return { start, list: Uint32Array.from(list) };
}

/**
 * The charts part of a mode-4 Charts chunk (the Rust `read_grown`): S and a RESIDUALS section of
 * the seeds' codes (0 the next chart not yet seen, else chart + 1), R and a RESIDUALS section of
 * the runs of yes answers. The lowest triangle without a chart seeds a region, which grows
 * breadth first: each triangle taken from the queue asks each neighbour without a chart that
 * this region has not asked whether it joins.
 */
export function grownCharts(c: Cursor, raw: Uint8Array, charts: number, tris: Uint32Array, out: Uint32Array, what: string): void {
  const n = out.length;
  const s = c.count(n, "chart seeds"), seeds = readCodes(c, raw, s, 1, true, what);
  const r = c.count(n + 1, "chart runs"), runs = readCodes(c, raw, r, 1, true, what);
  const nb = neighbours(tris), NONE = 0xffffffff, asked = new Uint32Array(n), queue = new Uint32Array(n);
  out.fill(NONE);
  let nextSeed = 0, nextRun = 0, left = -1, nextChart = 0, region = 0;
  const same = (u: number): boolean => {
    if (left < 0) {
      if (r === 0) throw new DecodeError(`${what}: no chart runs`);
      left = runs[0];
      nextRun = 1;
    }
    if (left > 0) { left--; return true; }
    if (nextRun >= r) throw new DecodeError(`${what}: more than ${r} chart runs at triangle ${u}`);
    left = runs[nextRun++];
    return false;
  };
  for (let seed = 0; seed < n; seed++) {
    if (out[seed] !== NONE) continue;
    region++;
    if (nextSeed >= s) throw new DecodeError(`${what}: more than ${s} seeds at triangle ${seed}`);
    const code = seeds[nextSeed++], chart = code === 0 ? nextChart : code - 1;
    if (chart >= charts) throw new DecodeError(`${what}: chart ${chart} out of range (< ${charts}) at triangle ${seed}`);
    nextChart = Math.max(nextChart, chart + 1);
    out[seed] = chart;
    let head = 0, tail = 0;
    queue[tail++] = seed;
    while (head < tail) {
      const t = queue[head++];
      for (let i = nb.start[t]; i < nb.start[t + 1]; i++) {
        const u = nb.list[i];
        if (out[u] !== NONE || asked[u] === region) continue;
        asked[u] = region;
        if (same(u)) { out[u] = chart; queue[tail++] = u; }
      }
    }
  }
  const ended = left < 0 ? r === 1 && runs[0] === 0 : left === 0 && nextRun === r;
  if (nextSeed !== s || !ended) throw new DecodeError(`${what}: ${s} seeds and ${r} runs where the charts take ${nextSeed} and ${nextRun}`);
}
