// Unit tests of the viewer's replay and geomorph logic on a small hand-made hierarchy.
import { test } from "node:test";
import assert from "node:assert/strict";
import { Replay, NONE, DecodeError } from "../src/container/index.js";
import { buildCutMesh, morphStarts, blend } from "../src/geomorph.js";

// A 3x3 vertex grid (8 triangles); level 1 has 3 clusters, level 2 has 1 root.
const tris = Uint32Array.from([0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4, 3, 4, 7, 3, 7, 6, 4, 5, 8, 4, 8, 7]);
function make(): Replay {
  const r = new Replay([9, 3, 1], 0, 8);
  r.loadKeyframe(
    [
      { parent: Uint32Array.from([0, 0, 1, 0, 0, 1, 2, 2, 2]), faces: [] },
      { parent: Uint32Array.from([0, 0, 0]), faces: [] },
      { parent: new Uint32Array(0), faces: [] },
    ],
    tris,
  );
  return r;
}

test("coarsest cut shows nothing, finest shows everything", () => {
  const r = make();
  assert.equal(r.shown.length, 0);
  for (let g = 9; g < 13; g++) r.expand(g);
  assert.equal(r.shown.length, 8);
  const mesh = buildCutMesh(r);
  assert.equal(mesh.nodes.length, 9);
  assert.equal(mesh.indices.length, 24);
});

test("budget cut never exceeds the budget, by whole splits and by partial splits", () => {
  const r = make();
  const pos = new Float32Array(13 * 3).map((_, i) => (i * 7919) % 13);
  const err = r.splitBenefits(pos), reveal = r.revealBenefits(pos);
  for (const budget of [0, 1, 3, 5, 8]) {
    r.selectTriangles(budget, err);
    assert.ok(r.shown.length <= budget, `whole: ${r.shown.length} > ${budget}`);
    r.selectTriangles(budget, reveal, true);
    assert.ok(r.shown.length <= budget, `partial: ${r.shown.length} > ${budget}`);
  }
});

test("deltas move triangles and reject bad data", () => {
  const r = make();
  r.expand(12);
  const before = r.shown.length;
  // Move vertex 2 from cluster 1 to cluster 0 is invalid (empties cluster 1? no: 5 stays).
  r.apply({ swaps: [{ level: 0, v: 2, to: 0 }], corners: [] });
  assert.equal(r.parent[0][2], 0);
  assert.equal(r.shown.length, before);
  assert.throws(() => r.apply({ swaps: [{ level: 0, v: 99, to: 0 }], corners: [] }), DecodeError);
  assert.throws(() => r.apply({ swaps: [{ level: 0, v: 5, to: 0 }], corners: [] }), DecodeError);
});

test("geomorph starts refinements at the parent and ends at the target", () => {
  const r = make();
  r.expand(12);
  const coarse = buildCutMesh(r);
  r.expand(9);
  r.expand(10);
  r.expand(11);
  const fine = buildCutMesh(r);
  const pos = new Float32Array(13 * 3);
  for (let g = 0; g < 13; g++) { pos[3 * g] = g; pos[3 * g + 1] = 2 * g; pos[3 * g + 2] = 0; }
  const parentOf = (g: number) => r.parentGlobal(g);
  const start = morphStarts(fine, coarse.nodes, pos, parentOf);
  for (let i = 0; i < fine.nodes.length; i++) {
    const g = fine.nodes[i];
    const p = parentOf(g);
    assert.equal(start[3 * i], pos[3 * p], `vertex ${g} starts at its parent ${p}`);
  }
  const out = new Float32Array(fine.nodes.length * 3);
  blend(fine, start, pos, 1, out);
  for (let i = 0; i < fine.nodes.length; i++) assert.equal(out[3 * i], pos[3 * fine.nodes[i]]);
  assert.notEqual(NONE, 0);
});
