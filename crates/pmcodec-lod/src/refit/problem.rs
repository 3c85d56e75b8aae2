//! The refit as a problem type: [`Refit::new`] sets it up (local numbering, unknowns, skin
//! candidates, the posed input), [`Refit::run`] alternates its rounds: an ICP step
//! ([`Refit::icp_step`], correspondences in every pose and the normal equations they give),
//! then a position round ([`Refit::position_round`]) or a skin round ([`Refit::skin_round`]),
//! each followed by the one flip repair ([`super::flips`]).

use super::flips::{Moves, repair_flips};
use super::*;
use rayon::prelude::*;

/// Samples per parallel task of the closest-point walks: enough to be worth a task, few enough
/// that two cores share a pose's 3,000-odd samples a direction.
const CHUNK: usize = 512;

/// An affine map from a vertex's combined unknowns to one pose.
type Map = (DMat3, DVec3);

/// The refit of one LOD: what stays fixed over its rounds, and its state (`x`, `skins`, `maps`).
pub(super) struct Refit<'a> {
    attrs: &'a VertexAttrs,
    input_triangles: &'a [[u32; 3]],
    records: &'a [Vertex],
    opts: &'a RefitOptions,
    poses: Vec<&'a Pose>,
    /// Input id of each LOD vertex (local numbering), and the LOD triangles in it.
    ids: Vec<u32>,
    tris: Vec<[u32; 3]>,
    /// Unknowns per vertex: the rest position, then its morph deltas when they are refitted.
    dim: Vec<usize>,
    /// Per vertex, the skin its class uses (`None`: rigid), and the joints a weight refit may
    /// choose among with their priorities.
    skin_of: Vec<Option<usize>>,
    cands: Vec<Vec<(u16, f64)>>,
    /// Per vertex and pose (`[v * f + k]`): the coefficients of its unknowns' combination, and
    /// its morph offset when the deltas are not unknowns.
    coef: Vec<Vec<f64>>,
    fixed_morph: Vec<DVec3>,
    /// The input posed in every pose with its surface index, when they fit
    /// [`MAX_CACHED_TRIANGLES`] (else rebuilt pose by pose in every round).
    inputs: Vec<(TriMesh, SurfaceIndex)>,
    input_samples: Vec<(u32, [f64; 3])>,
    sys: System,
    big: Big,
    /// Per skinned vertex, its weights' least-squares system `(H, g)` in a skin round, and
    /// each candidate joint's transform of the vertex in the current pose.
    weight_sys: Vec<(Vec<f64>, Vec<f64>)>,
    columns: Vec<DVec3>,
    column_start: Vec<usize>,
    // The state.
    x: Vec<DVec3>,
    skins: Vec<Skin>,
    /// Per vertex and pose, the affine map of its skin (`[v * f + k]`).
    maps: Vec<Map>,
    /// Per pose, each input sample's closest LOD triangle, then each LOD sample's closest input
    /// triangle, from the last round (`u32::MAX`: none yet).
    hints: Vec<Vec<u32>>,
}

/// What a refit found: per LOD vertex (input id), its unknowns and skin.
pub(super) struct Fitted {
    pub(super) ids: Vec<u32>,
    pub(super) start: Vec<usize>,
    pub(super) dim: Vec<usize>,
    pub(super) x: Vec<DVec3>,
    pub(super) skins: Vec<Skin>,
}

impl<'a> Refit<'a> {
    /// Sets up the refit of the vertices `triangles` use; `None` when the input surface cannot
    /// be indexed in some pose.
    pub(super) fn new(
        attrs: &'a VertexAttrs,
        input_triangles: &'a [[u32; 3]],
        poses: &'a [Pose],
        records: &'a [Vertex],
        triangles: &[[u32; 3]],
        rep: &[u32],
        opts: &'a RefitOptions,
    ) -> Option<Self> {
        let max = opts.max_poses.max(1);
        let poses: Vec<&Pose> =
            if poses.len() > max { (0..max).map(|i| &poses[i * poses.len() / max]).collect() } else { poses.iter().collect() };
        // Local numbering of the LOD's vertices.
        let mut local: HashMap<u32, u32> = HashMap::new();
        let mut ids: Vec<u32> = Vec::new();
        let tris: Vec<[u32; 3]> = triangles
            .iter()
            .map(|t| {
                t.map(|id| {
                    *local.entry(id).or_insert_with(|| {
                        ids.push(id);
                        ids.len() as u32 - 1
                    })
                })
            })
            .collect();
        let m = ids.len();
        // Positions alone when the deltas' blocks would not fit [`MAX_BLOCKS`].
        let sys = System::new(m, &tris);
        let mut dim: Vec<usize> = ids.iter().map(|&id| if opts.morph { 1 + records[id as usize].morph.len() } else { 1 }).collect();
        let blocks =
            dim.iter().map(|d| d * d).sum::<usize>() + sys.pairs.iter().map(|&(i, j)| dim[i as usize] * dim[j as usize]).sum::<usize>();
        if blocks > MAX_BLOCKS {
            dim.iter_mut().for_each(|d| *d = 1);
        }
        let skins: Vec<Skin> = ids.iter().map(|&id| (records[id as usize].joints, records[id as usize].weights)).collect();
        let skin_of: Vec<Option<usize>> =
            ids.iter().map(|&id| attrs.classes.get(records[id as usize].class as usize).and_then(|c| c.skin)).collect();
        let cands = if opts.skin { candidates(attrs, records, rep, &local, &skins, &skin_of) } else { vec![Vec::new(); m] };
        let big = Big::new(&dim, &sys.pairs);
        let mut x: Vec<DVec3> = Vec::with_capacity(big.rhs.len());
        for (v, &id) in ids.iter().enumerate() {
            let rec = &records[id as usize];
            x.push(rec.rest.as_dvec3());
            x.extend(rec.morph.iter().take(dim[v] - 1).map(|d| d.as_dvec3()));
        }
        let rest_areas: Vec<f64> = input_triangles.iter().map(|t| area(t.map(|i| attrs.rest[i as usize]))).collect();
        let weight_sys = cands.iter().map(|c| (vec![0.0; c.len() * c.len()], vec![0.0; c.len()])).collect();
        let mut fit = Refit {
            attrs,
            input_triangles,
            records,
            opts,
            poses,
            ids,
            tris,
            dim,
            skin_of,
            cands,
            coef: Vec::new(),
            fixed_morph: Vec::new(),
            inputs: Vec::new(),
            input_samples: sample_bary(input_triangles, &rest_areas, opts.samples, 0x1D0F),
            sys,
            big,
            weight_sys,
            columns: Vec::new(),
            column_start: Vec::with_capacity(m + 1),
            x,
            skins,
            maps: Vec::new(),
            hints: Vec::new(),
        };
        fit.hints = vec![Vec::new(); fit.poses.len()];
        fit.maps = fit.build_maps(&fit.skins);
        fit.combinations();
        if fit.input_triangles.len().saturating_mul(fit.poses.len()) <= MAX_CACHED_TRIANGLES {
            for pose in &fit.poses {
                let input = fit.posed_input(pose)?;
                fit.inputs.push(input);
            }
        }
        Some(fit)
    }

    /// Fills `coef` (each vertex's unknowns' coefficients in each pose: 1 for the rest position,
    /// the pose's morph weights for the deltas) and `fixed_morph` (the morph offset of vertices
    /// whose deltas are not unknowns).
    fn combinations(&mut self) {
        let (attrs, records) = (self.attrs, self.records);
        for (v, &id) in self.ids.iter().enumerate() {
            let rec = &records[id as usize];
            let instance = attrs.classes.get(rec.class as usize).map(|c| c.instance);
            for pose in &self.poses {
                let w = instance.and_then(|i| pose.morph.get(i));
                let c = (0..self.dim[v]).map(|s| if s == 0 { 1.0 } else { w.and_then(|w| w.get(s - 1)).map_or(0.0, |&x| x as f64) });
                self.coef.push(c.collect());
                self.fixed_morph.push(match (self.dim[v] == 1, w) {
                    (true, Some(w)) => rec.morph.iter().zip(w).map(|(d, &w)| d.as_dvec3() * w as f64).sum(),
                    _ => DVec3::ZERO,
                });
            }
        }
    }

    /// Per LOD vertex and pose, the affine map from its unknowns' combination to the pose.
    fn build_maps(&self, skins: &[Skin]) -> Vec<Map> {
        let mut maps = Vec::with_capacity(self.ids.len() * self.poses.len());
        for (v, &id) in self.ids.iter().enumerate() {
            let rec = &self.records[id as usize];
            let morph = if self.dim[v] > 1 { Vec::new() } else { rec.morph.clone() };
            let skinned = Vertex { morph, joints: skins[v].0, weights: skins[v].1, ..rec.clone() };
            for pose in &self.poses {
                let (l, c): (Mat3, Vec3) = self.attrs.affine(&skinned, pose);
                maps.push((l.as_dmat3(), c.as_dvec3()));
            }
        }
        maps
    }

    /// The input posed in `pose` and its surface index.
    fn posed_input(&self, pose: &Pose) -> Option<(TriMesh, SurfaceIndex)> {
        let positions: Vec<Vec3> = (0..self.attrs.len()).map(|v| self.attrs.posed(v, pose)).collect();
        let mesh = TriMesh { positions, triangles: self.input_triangles.to_vec() };
        let index = SurfaceIndex::new(&mesh).ok()?;
        Some((mesh, index))
    }

    /// Vertex `v`'s unknowns combined for pose `k` (rest position plus weighted deltas).
    fn unposed(&self, x: &[DVec3], v: usize, k: usize) -> DVec3 {
        let c = &self.coef[v * self.poses.len() + k];
        (0..self.dim[v]).map(|s| x[self.big.start[v] + s] * c[s]).sum()
    }

    /// Vertex `v` in pose `k` for unknowns `x` under the affine maps `maps`.
    fn pose_with(&self, maps: &[Map], x: &[DVec3], v: usize, k: usize) -> DVec3 {
        let (l, c) = maps[v * self.poses.len() + k];
        l * self.unposed(x, v, k) + c
    }

    /// Runs the rounds; `None` when a surface could not be indexed on the way (nothing is
    /// written then).
    pub(super) fn run(mut self) -> Option<Fitted> {
        let iterations = self.opts.iterations;
        let mut skin_rounds = self.opts.skin && self.cands.iter().any(|c| !c.is_empty());
        let mut best: Option<(f64, Vec<DVec3>, Vec<Skin>)> = None;
        let mut last_was_skin = false;
        // Set when the state was just restored to the best: its pass is the positions' next step.
        let mut restored = false;
        let mut iteration = 0;
        loop {
            // This round's step: the positions, or (rounds 2, 4, ...) the skin weights.
            let skin_now = skin_rounds && iteration >= 2 && iteration % 2 == 0 && iteration < iterations;
            let objective = self.icp_step(skin_now)?;
            if restored {
                restored = false;
            } else if best.as_ref().is_none_or(|(o, _, _)| objective < *o) {
                best = Some((objective, self.x.clone(), self.skins.clone()));
            } else if last_was_skin && let Some((_, bx, bs)) = &best {
                // A skin round made it worse (its vertices moved all at once, each assuming its
                // neighbours stay): undo it and go on with positions alone.
                self.x = bx.clone();
                self.skins = bs.clone();
                self.maps = self.build_maps(&self.skins);
                skin_rounds = false;
                last_was_skin = false;
                restored = true;
                continue;
            } else {
                // Worse than the best so far: stop (the best is what is kept).
                break;
            }
            if iteration >= iterations {
                break;
            }
            iteration += 1;
            last_was_skin = skin_now;
            if skin_now {
                self.skin_round();
            } else {
                self.position_round();
            }
        }
        let (_, x, skins) = best?;
        Some(Fitted { ids: self.ids, start: self.big.start, dim: self.dim, x, skins })
    }

    /// The ICP step: correspondences in every pose for the current state, accumulated as the
    /// normal equations of the positions or (`skin_now`) each vertex's weight system. Returns
    /// the sampled objective (squared distances, both directions, weighted by pose).
    fn icp_step(&mut self, skin_now: bool) -> Option<f64> {
        self.big.clear();
        for (h, g) in &mut self.weight_sys {
            h.iter_mut().for_each(|x| *x = 0.0);
            g.iter_mut().for_each(|x| *x = 0.0);
        }
        let mut objective = 0.0;
        let lod_areas: Vec<f64> = self.tris.iter().map(|t| area(t.map(|i| self.x[self.big.start[i as usize]].as_vec3()))).collect();
        let lod_samples = sample_bary(&self.tris, &lod_areas, self.opts.samples, 0x10D);
        for k in 0..self.poses.len() {
            if self.poses[k].weight > 0.0 {
                self.correspond(k, skin_now, &lod_samples, &mut objective)?;
            }
        }
        Some(objective)
    }

    /// One pose of the ICP step: input points to their closest LOD points and LOD points to
    /// their closest input points, each added to the pose's system (or the weight systems).
    fn correspond(&mut self, k: usize, skin_now: bool, lod_samples: &[(u32, [f64; 3])], objective: &mut f64) -> Option<()> {
        let (f, m) = (self.poses.len(), self.ids.len());
        let pose = self.poses[k];
        let w = pose.weight;
        self.sys.clear();
        let posed: Vec<DVec3> = (0..m).map(|v| self.pose_with(&self.maps, &self.x, v, k)).collect();
        if skin_now {
            self.skin_columns(k);
        }
        let lod_mesh = TriMesh { positions: posed.iter().map(|p| p.as_vec3()).collect(), triangles: self.tris.clone() };
        let lod_index = SurfaceIndex::new(&lod_mesh).ok()?;
        let owned;
        let (input, input_index) = match self.inputs.get(k) {
            Some(cached) => cached,
            None => {
                owned = self.posed_input(pose)?;
                &owned
            }
        };
        let (sys, weight_sys, maps, cands) = (&mut self.sys, &mut self.weight_sys, &self.maps, &self.cands);
        let (columns, column_start, point_share) = (&self.columns, &self.column_start, self.opts.point_share);
        let mut add = |ltri: [u32; 3], b: [f64; 3], y: DVec3, n: DVec3| {
            let metric = metric(n, point_share);
            if !skin_now {
                sys.add(ltri, b, ltri.map(|v| &maps[v as usize * f + k]), y, w, &metric);
                return;
            }
            for i in 0..3 {
                let v = ltri[i] as usize;
                if b[i] == 0.0 || cands[v].is_empty() {
                    continue;
                }
                let other: DVec3 = (0..3).filter(|&j| j != i).map(|j| posed[ltri[j] as usize] * b[j]).sum();
                let r = y - other;
                let cols = &columns[column_start[v]..column_start[v + 1]];
                let (h, g) = &mut weight_sys[v];
                let nc = cols.len();
                for c in 0..nc {
                    let mc = metric * cols[c];
                    g[c] += w * b[i] * mc.dot(r);
                    for d in 0..nc {
                        h[c * nc + d] += w * b[i] * b[i] * mc.dot(cols[d]);
                    }
                }
            }
        };
        // Each sample's answer in this pose last round starts its query: the surfaces move
        // little from one round to the next. The walks (most of the refit's time) run in
        // parallel; their answers are accumulated in sample order, so the result does not depend
        // on the schedule.
        let hints = &mut self.hints[k];
        hints.resize(self.input_samples.len() + lod_samples.len(), u32::MAX);
        let (in_hints, lod_hints) = hints.split_at_mut(self.input_samples.len());
        let (input_triangles, tris) = (self.input_triangles, &self.tris);
        // Input points to their closest LOD points.
        let found: Vec<(DVec3, u32)> = self
            .input_samples
            .par_iter()
            .zip(in_hints.par_iter_mut())
            .with_min_len(CHUNK)
            .map(|(&(t, b), hint)| {
                let tri = input_triangles[t as usize];
                let y: DVec3 = (0..3).map(|j| input.positions[tri[j] as usize].as_dvec3() * b[j]).sum();
                *hint = lod_index.closest_near(y.as_vec3(), *hint).1;
                (y, *hint)
            })
            .collect();
        for (y, lt) in found {
            let Some(&ltri) = tris.get(lt as usize) else { continue };
            let corners = ltri.map(|v| posed[v as usize]);
            let q = closest_point(y, corners);
            *objective += w * (q - y).length_squared();
            let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]).normalize_or_zero();
            add(ltri, barycentric(q, corners), y, n);
        }
        // LOD points to their closest input points.
        let found: Vec<(DVec3, u32)> = lod_samples
            .par_iter()
            .zip(lod_hints.par_iter_mut())
            .with_min_len(CHUNK)
            .map(|(&(t, b), hint)| {
                let ltri = tris[t as usize];
                let p: DVec3 = (0..3).map(|j| posed[ltri[j] as usize] * b[j]).sum();
                *hint = input_index.closest_near(p.as_vec3(), *hint).1;
                (p, *hint)
            })
            .collect();
        for (&(t, b), (p, it)) in lod_samples.iter().zip(found) {
            let ltri = tris[t as usize];
            let Some(&itri) = input_triangles.get(it as usize) else { continue };
            let ic = itri.map(|v| input.positions[v as usize].as_dvec3());
            let y = closest_point(p, ic);
            *objective += w * (p - y).length_squared();
            add(ltri, b, y, (ic[1] - ic[0]).cross(ic[2] - ic[0]).normalize_or_zero());
        }
        if !skin_now {
            let a: Vec<&[f64]> = (0..m).map(|v| self.coef[v * f + k].as_slice()).collect();
            self.big.expand(&self.sys, &a);
        }
        Some(())
    }

    /// Each candidate joint's transform of every vertex in pose `k` (morph applied): a skinned
    /// vertex is `sum_c w_c P_c` for weights summing to 1.
    fn skin_columns(&mut self, k: usize) {
        let f = self.poses.len();
        let pose = self.poses[k];
        self.columns.clear();
        self.column_start.clear();
        for v in 0..self.ids.len() {
            self.column_start.push(self.columns.len());
            let unposed = self.unposed(&self.x, v, k) + self.fixed_morph[v * f + k];
            let mats = self.skin_of[v].and_then(|s| pose.joints.get(s));
            for &(j, _) in &self.cands[v] {
                let mat = mats.and_then(|m| m.get(j as usize)).copied().unwrap_or(glam::Mat4::IDENTITY).as_dmat4();
                self.columns.push(mat.transform_point3(unposed));
            }
        }
        self.column_start.push(self.columns.len());
    }

    /// A position round: solve the regularised normal equations, step back the moves that
    /// flip a triangle in some example pose, keep the result when it is finite.
    fn position_round(&mut self) {
        self.big.regularise(&self.x, 1e-3, 1e-6);
        let mut next = self.x.clone();
        self.big.solve(&mut next, 300);
        repair_flips(&self.tris, self.poses.len(), &mut PositionMoves { fit: self, next: &mut next });
        if next.iter().all(|p| p.is_finite()) {
            self.x = next;
        }
    }

    /// A skin round: each skinned vertex's best weights over its candidates ([`skin_step`]),
    /// then the new skins of the corners of triangles that flip in some example pose undone.
    fn skin_round(&mut self) {
        let old_skins = self.skins.clone();
        let old_maps = self.maps.clone();
        let mut skins = self.skins.clone();
        for (v, cands) in self.cands.iter().enumerate() {
            if cands.is_empty() {
                continue;
            }
            let (h, g) = &self.weight_sys[v];
            let (joints, weights) = skins[v];
            let current: Vec<f64> =
                cands.iter().map(|&(j, _)| joints.iter().zip(&weights).filter(|(jj, _)| **jj == j).map(|(_, w)| *w as f64).sum()).collect();
            if let Some(skin) = skin_step(h, g, &current, cands) {
                skins[v] = skin;
            }
        }
        let maps = self.build_maps(&skins);
        let mut moves = SkinMoves { fit: self, old_skins, old_maps, skins, maps };
        repair_flips(&self.tris, self.poses.len(), &mut moves);
        let SkinMoves { skins, maps, .. } = moves;
        self.skins = skins;
        self.maps = maps;
    }
}

/// For each skinned LOD vertex, the joints a weight refit may use: its own, then those of the
/// input vertices merged into it (`rep`), by weight, at most [`MAX_CANDIDATES`].
fn candidates(
    attrs: &VertexAttrs,
    records: &[Vertex],
    rep: &[u32],
    local: &HashMap<u32, u32>,
    skins: &[Skin],
    skin_of: &[Option<usize>],
) -> Vec<Vec<(u16, f64)>> {
    let mut cands: Vec<Vec<(u16, f64)>> = vec![Vec::new(); skins.len()];
    for (v, (j, w)) in skins.iter().enumerate() {
        if skin_of[v].is_some() {
            for (&j, &w) in j.iter().zip(w) {
                if w > 0.0 {
                    cands[v].push((j, 1e9 * w as f64));
                }
            }
        }
    }
    for (u, &r) in rep.iter().enumerate() {
        let (Some(&v), Some(rec)) = (local.get(&r), attrs.verts.get(u)) else { continue };
        if skin_of[v as usize].is_none() || rec.class != records[r as usize].class {
            continue;
        }
        let list = &mut cands[v as usize];
        for (&j, &w) in rec.joints.iter().zip(&rec.weights) {
            if w > 0.0 {
                match list.iter_mut().find(|c| c.0 == j) {
                    Some(c) => c.1 += w as f64,
                    None => list.push((j, w as f64)),
                }
            }
        }
    }
    for list in &mut cands {
        list.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        list.truncate(MAX_CANDIDATES);
    }
    cands
}

/// A position round's moves: from the current unknowns to `next`. Stepping back halves a
/// vertex's move, and from the tenth round on drops it.
struct PositionMoves<'f, 'a> {
    fit: &'f Refit<'a>,
    next: &'f mut [DVec3],
}

impl Moves for PositionMoves<'_, '_> {
    fn before(&self, v: usize, k: usize) -> DVec3 {
        self.fit.pose_with(&self.fit.maps, &self.fit.x, v, k)
    }

    fn after(&self, v: usize, k: usize) -> DVec3 {
        self.fit.pose_with(&self.fit.maps, self.next, v, k)
    }

    fn step_back(&mut self, v: usize, round: usize) -> bool {
        let x = &self.fit.x;
        let range = self.fit.big.start[v]..self.fit.big.start[v] + self.fit.dim[v];
        if self.next[range.clone()] == x[range.clone()] {
            return false;
        }
        for i in range {
            self.next[i] = if round >= 9 { x[i] } else { (x[i] + self.next[i]) * 0.5 };
        }
        true
    }
}

/// A skin round's moves: from the old skins to the new. Stepping back restores a vertex's old
/// skin; the maps follow once per sweep.
struct SkinMoves<'f, 'a> {
    fit: &'f Refit<'a>,
    old_skins: Vec<Skin>,
    old_maps: Vec<Map>,
    skins: Vec<Skin>,
    maps: Vec<Map>,
}

impl Moves for SkinMoves<'_, '_> {
    fn before(&self, v: usize, k: usize) -> DVec3 {
        self.fit.pose_with(&self.old_maps, &self.fit.x, v, k)
    }

    fn after(&self, v: usize, k: usize) -> DVec3 {
        self.fit.pose_with(&self.maps, &self.fit.x, v, k)
    }

    fn step_back(&mut self, v: usize, _round: usize) -> bool {
        if self.skins[v] == self.old_skins[v] {
            return false;
        }
        self.skins[v] = self.old_skins[v];
        true
    }

    fn refresh(&mut self) {
        self.maps = self.fit.build_maps(&self.skins);
    }
}
