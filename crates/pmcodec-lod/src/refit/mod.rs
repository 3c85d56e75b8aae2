//! Refitting an LOD's vertex positions, morph deltas and skin weights to the input surface over
//! all example poses.
//!
//! Greedy collapse places every vertex once, from quadrics that only know the planes of the
//! faces it absorbed; once the collapses are done, the coarse surface can still be moved closer
//! to the input. With the connectivity and every vertex's skin fixed, a vertex is an affine
//! function of its rest position `p` and morph deltas `d_t` together in every pose
//! ([`crate::attrs`]): `L_k (p + sum_t w_kt d_t) + t_k`. So a point of an LOD triangle at
//! barycentric coordinates `b` is linear in the unknowns of its corners. Given closest-point
//! correspondences in every pose (points of the input surface to their closest LOD points, and
//! points of the LOD to their closest input points, the two directions the error is measured
//! in), the squared distances summed over poses are a linear least-squares problem. We solve it
//! (conjugate gradients on the normal equations), recompute the correspondences and repeat a
//! few times: iterative closest point (Besl & McKay 1992; point-to-plane residuals after Chen &
//! Medioni 1992), in the spirit of the "fit" step of Hoppe et al.'s 1993 mesh optimisation,
//! with the skin of Houle & Poulin ("Simplification and Real-time Smooth Transitions of
//! Articulated Meshes", 2001, section 4.1) held fixed: the fit moves vertices in
//! bone space, i.e. in rest space before skinning. Refitting the deltas fits each vertex's
//! morph targets to the input's in the poses that use them (Berner & Rieger, "Surface
//! Simplification Guided by Morph-Targets", 2006, simplify against the targets; we also fit to
//! them).
//!
//! Skin weights are refitted in rounds of their own, alternating with the positions' after
//! the first two: with positions fixed a vertex is linear in its weights (`sum_c w_c M_c q`),
//! so each skinned vertex solves a small least-squares problem over at most four of its
//! candidate joints (its own and those of the input vertices merged into it), with the weights
//! non-negative and summing to 1 ([`skin_step`]). Those solves hold the neighbours still, so
//! all vertices moving at once can overshoot: a skin round that makes the objective worse is
//! undone and the rest of the refit runs on positions alone.
//!
//! This is our addition to the papers. It never increases the sampled objective: an iteration
//! whose result is worse than the best so far is dropped, and so is the move of any vertex that
//! would flip one of its triangles in any example pose.

use crate::attrs::{Vertex, VertexAttrs};
use crate::poses::Pose;
use glam::{DMat3, DVec3, Mat3, Vec3};
use pmcodec_eval::SurfaceIndex;
use pmcodec_eval::triangle::closest_point;
use pmcodec_mesh::TriMesh;
use std::collections::HashMap;

mod geometry;
mod normal;

use self::geometry::*;
use self::normal::*;

/// Most 3x3 blocks of the normal equations (72 bytes each) when morph deltas are refitted too;
/// beyond it (many vertices with many targets) only the rest positions are.
pub const MAX_BLOCKS: usize = 1 << 21;

/// Most posed input triangles kept over the poses of a round (about 100 bytes each with their
/// index); beyond it each pose's input is rebuilt in every round.
pub const MAX_CACHED_TRIANGLES: usize = 1 << 21;

/// Four joints and their weights.
pub type Skin = ([u16; 4], [f32; 4]);

/// Most joints a skin refit chooses a vertex's four influences among.
pub const MAX_CANDIDATES: usize = 8;

/// How the refit runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefitOptions {
    /// Correspondence-and-solve rounds; 0 turns the refit off.
    pub iterations: usize,
    /// Area-uniform points sampled on each surface per pose (vertices are added, as the error
    /// measure does).
    pub samples: usize,
    /// Most poses used (thinned evenly beyond it, the first kept).
    pub max_poses: usize,
    /// Share of point-to-point in the residual metric, the rest point-to-plane. Point-to-point
    /// alone converges slowly (a point cannot slide along the surface it already lies on): 0.1
    /// took the Parrot's 10% error from 0.53 to 0.52 and the Fox's 25% from 0.375 to 0.360.
    pub point_share: f64,
    /// Refit the morph deltas too (each vertex's position in a pose is linear in its rest
    /// position and deltas together). On the morph-animated Parrot this took the 10% error
    /// from 0.52 to 0.40 (meshoptimizer: 0.80).
    pub morph: bool,
    /// Refit skin weights too, in rounds alternating with the positions' (see [`skin_step`]).
    pub skin: bool,
}

impl Default for RefitOptions {
    fn default() -> Self {
        RefitOptions { iterations: 8, samples: 3000, max_poses: 96, point_share: 0.1, morph: true, skin: true }
    }
}

/// Refits the rest positions (and, with [`RefitOptions::morph`], the morph deltas) of the
/// vertices `triangles` use (over input ids into `verts`) so that the LOD surface is closer to
/// the input surface `input_triangles` over `poses`.
pub fn refit(
    attrs: &VertexAttrs,
    input_triangles: &[[u32; 3]],
    poses: &[Pose],
    verts: &mut [Vertex],
    triangles: &[[u32; 3]],
    rep: &[u32],
    opts: &RefitOptions,
) {
    if opts.iterations == 0 || triangles.is_empty() || poses.is_empty() || input_triangles.is_empty() {
        return;
    }
    let poses: Vec<&Pose> = if poses.len() > opts.max_poses.max(1) {
        let max = opts.max_poses.max(1);
        (0..max).map(|i| &poses[i * poses.len() / max]).collect()
    } else {
        poses.iter().collect()
    };
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
    let f = poses.len();
    // Unknowns per vertex: the rest position, then its morph deltas when they are refitted.
    // (Positions alone when the deltas' blocks would not fit [`MAX_BLOCKS`].)
    let mut sys = System::new(m, &tris);
    let mut dim: Vec<usize> = ids.iter().map(|&id| if opts.morph { 1 + verts[id as usize].morph.len() } else { 1 }).collect();
    let blocks =
        dim.iter().map(|d| d * d).sum::<usize>() + sys.pairs.iter().map(|&(i, j)| dim[i as usize] * dim[j as usize]).sum::<usize>();
    if blocks > MAX_BLOCKS {
        dim.iter_mut().for_each(|d| *d = 1);
    }
    // Skins of the LOD vertices, and for skinned ones the joints a weight refit may use: their
    // own, then those of the input vertices merged into them, by weight (at most
    // [`MAX_CANDIDATES`]).
    let records: &[Vertex] = verts;
    let mut skins: Vec<Skin> = ids.iter().map(|&id| (records[id as usize].joints, records[id as usize].weights)).collect();
    let skin_of: Vec<Option<usize>> =
        ids.iter().map(|&id| attrs.classes.get(records[id as usize].class as usize).and_then(|c| c.skin)).collect();
    let mut cands: Vec<Vec<(u16, f64)>> = vec![Vec::new(); m];
    if opts.skin {
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
    }
    // Per LOD vertex and pose, the affine map from its unknowns' combination to the pose
    // (`maps[v * f + k]`), and the combination's coefficients (`coef[v * f + k]`).
    let build_maps = |skins: &[Skin]| -> Vec<(DMat3, DVec3)> {
        let mut maps = Vec::with_capacity(m * f);
        for (v, &id) in ids.iter().enumerate() {
            let rec = &records[id as usize];
            let morph = if dim[v] > 1 { Vec::new() } else { rec.morph.clone() };
            let skinned = Vertex { morph, joints: skins[v].0, weights: skins[v].1, ..rec.clone() };
            for pose in &poses {
                let (l, c): (Mat3, Vec3) = attrs.affine(&skinned, pose);
                maps.push((l.as_dmat3(), c.as_dvec3()));
            }
        }
        maps
    };
    let mut maps = build_maps(&skins);
    let mut coef: Vec<Vec<f64>> = Vec::with_capacity(m * f);
    for (v, &id) in ids.iter().enumerate() {
        let rec = &records[id as usize];
        let instance = attrs.classes.get(rec.class as usize).map(|c| c.instance);
        for pose in &poses {
            let w = instance.and_then(|i| pose.morph.get(i));
            coef.push((0..dim[v]).map(|s| if s == 0 { 1.0 } else { w.and_then(|w| w.get(s - 1)).map_or(0.0, |&x| x as f64) }).collect());
        }
    }
    // Per vertex and pose, its morph offset when the deltas are not unknowns.
    let fixed_morph: Vec<DVec3> = ids
        .iter()
        .enumerate()
        .flat_map(|(v, &id)| {
            let rec = &records[id as usize];
            let instance = attrs.classes.get(rec.class as usize).map(|c| c.instance);
            let fixed = dim[v] == 1;
            poses.iter().map(move |pose| match (fixed, instance.and_then(|i| pose.morph.get(i))) {
                (true, Some(w)) => rec.morph.iter().zip(w).map(|(d, &w)| d.as_dvec3() * w as f64).sum(),
                _ => DVec3::ZERO,
            })
        })
        .collect();
    // The input posed in every pose and its surface index: kept for all poses when they fit
    // [`MAX_CACHED_TRIANGLES`], else rebuilt pose by pose in every round.
    let n = attrs.len();
    let posed_input = |pose: &Pose| -> Option<(TriMesh, SurfaceIndex)> {
        let positions: Vec<Vec3> = (0..n).map(|v| attrs.posed(v, pose)).collect();
        let mesh = TriMesh { positions, triangles: input_triangles.to_vec() };
        let index = SurfaceIndex::new(&mesh).ok()?;
        Some((mesh, index))
    };
    let mut inputs: Vec<(TriMesh, SurfaceIndex)> = Vec::new();
    if input_triangles.len().saturating_mul(f) <= MAX_CACHED_TRIANGLES {
        for pose in &poses {
            let Some(input) = posed_input(pose) else { return };
            inputs.push(input);
        }
    }
    let rest_areas: Vec<f64> = input_triangles.iter().map(|t| area(t.map(|i| attrs.rest[i as usize]))).collect();
    let input_samples = sample_bary(input_triangles, &rest_areas, opts.samples, 0x1D0F);

    let mut big = Big::new(&dim, &sys.pairs);
    let mut x: Vec<DVec3> = Vec::with_capacity(big.rhs.len());
    for (v, &id) in ids.iter().enumerate() {
        let rec = &records[id as usize];
        x.push(rec.rest.as_dvec3());
        x.extend(rec.morph.iter().take(dim[v] - 1).map(|d| d.as_dvec3()));
    }
    let rest_of = |x: &[DVec3], big: &Big, v: usize| x[big.start[v]];
    // Vertex `v` in pose `k` for unknowns `x` under the affine maps `maps`.
    let starts = big.start.clone();
    let pose_with = |maps: &[(DMat3, DVec3)], x: &[DVec3], v: usize, k: usize| {
        let c = &coef[v * f + k];
        let u: DVec3 = (0..dim[v]).map(|s| x[starts[v] + s] * c[s]).sum();
        maps[v * f + k].0 * u + maps[v * f + k].1
    };
    // Whether triangle t flips in some example pose between two states (skins, unknowns).
    let flips_somewhere = |t: &[u32; 3], (maps_a, x_a): (&[(DMat3, DVec3)], &[DVec3]), (maps_b, x_b): (&[(DMat3, DVec3)], &[DVec3])| {
        (0..f).any(|k| flipped(t.map(|v| pose_with(maps_a, x_a, v as usize, k)), t.map(|v| pose_with(maps_b, x_b, v as usize, k))))
    };
    let mut skin_rounds = opts.skin && cands.iter().any(|c| !c.is_empty());
    let mut best: Option<(f64, Vec<DVec3>, Vec<Skin>)> = None;
    let mut weight_sys: Vec<(Vec<f64>, Vec<f64>)> = cands.iter().map(|c| (vec![0.0; c.len() * c.len()], vec![0.0; c.len()])).collect();
    let mut columns: Vec<DVec3> = Vec::new();
    let mut column_start: Vec<usize> = Vec::with_capacity(m + 1);
    let mut last_was_skin = false;
    // Set when the state was just restored to the best: its pass is the positions' next step.
    let mut restored = false;
    let mut iteration = 0;
    loop {
        // This round's step: the positions, or (rounds 2, 4, ...) the skin weights.
        let skin_now = skin_rounds && iteration >= 2 && iteration % 2 == 0 && iteration < opts.iterations;
        big.clear();
        for (h, g) in &mut weight_sys {
            h.iter_mut().for_each(|x| *x = 0.0);
            g.iter_mut().for_each(|x| *x = 0.0);
        }
        let mut objective = 0.0;
        let lod_areas: Vec<f64> = tris.iter().map(|t| area(t.map(|i| rest_of(&x, &big, i as usize).as_vec3()))).collect();
        let lod_samples = sample_bary(&tris, &lod_areas, opts.samples, 0x10D);
        let mut a: Vec<&[f64]> = Vec::with_capacity(m);
        for (k, pose) in poses.iter().enumerate() {
            let w = pose.weight;
            if !(w > 0.0) {
                continue;
            }
            sys.clear();
            let posed: Vec<DVec3> = (0..m)
                .map(|v| {
                    let c = &coef[v * f + k];
                    let u: DVec3 = (0..dim[v]).map(|s| x[big.start[v] + s] * c[s]).sum();
                    maps[v * f + k].0 * u + maps[v * f + k].1
                })
                .collect();
            if skin_now {
                // Each candidate joint's transform of the vertex (morph applied): the vertex is
                // `sum_c w_c P_c` for weights summing to 1.
                columns.clear();
                column_start.clear();
                for v in 0..m {
                    column_start.push(columns.len());
                    let c = &coef[v * f + k];
                    let unposed = (0..dim[v]).map(|s| x[big.start[v] + s] * c[s]).sum::<DVec3>() + fixed_morph[v * f + k];
                    let mats = skin_of[v].and_then(|s| pose.joints.get(s));
                    for &(j, _) in &cands[v] {
                        let mat = mats.and_then(|m| m.get(j as usize)).copied().unwrap_or(glam::Mat4::IDENTITY).as_dmat4();
                        columns.push(mat.transform_point3(unposed));
                    }
                }
                column_start.push(columns.len());
            }
            let lod_mesh = TriMesh { positions: posed.iter().map(|p| p.as_vec3()).collect(), triangles: tris.clone() };
            let Ok(lod_index) = SurfaceIndex::new(&lod_mesh) else { return };
            let owned;
            let (input, input_index) = match inputs.get(k) {
                Some(cached) => cached,
                None => {
                    let Some(input) = posed_input(pose) else { return };
                    owned = input;
                    &owned
                }
            };
            let mut add = |ltri: [u32; 3], b: [f64; 3], y: DVec3, n: DVec3| {
                let metric = metric(n, opts.point_share);
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
            // Input points to their closest LOD points.
            for &(t, b) in &input_samples {
                let tri = input_triangles[t as usize];
                let y: DVec3 = (0..3).map(|j| input.positions[tri[j] as usize].as_dvec3() * b[j]).sum();
                let (_, lt) = lod_index.closest(y.as_vec3());
                let Some(&ltri) = tris.get(lt as usize) else { continue };
                let corners = ltri.map(|v| posed[v as usize]);
                let q = closest_point(y, corners);
                objective += w * (q - y).length_squared();
                let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]).normalize_or_zero();
                add(ltri, barycentric(q, corners), y, n);
            }
            // LOD points to their closest input points.
            for &(t, b) in &lod_samples {
                let ltri = tris[t as usize];
                let p: DVec3 = (0..3).map(|j| posed[ltri[j] as usize] * b[j]).sum();
                let (_, it) = input_index.closest(p.as_vec3());
                let Some(&itri) = input_triangles.get(it as usize) else { continue };
                let ic = itri.map(|v| input.positions[v as usize].as_dvec3());
                let y = closest_point(p, ic);
                objective += w * (p - y).length_squared();
                add(ltri, b, y, (ic[1] - ic[0]).cross(ic[2] - ic[0]).normalize_or_zero());
            }
            if !skin_now {
                a.clear();
                a.extend((0..m).map(|v| coef[v * f + k].as_slice()));
                big.expand(&sys, &a);
            }
        }
        if restored {
            restored = false;
        } else if best.as_ref().is_none_or(|(o, _, _)| objective < *o) {
            best = Some((objective, x.clone(), skins.clone()));
        } else if last_was_skin && let Some((_, bx, bs)) = &best {
            // A skin round made it worse (its vertices moved all at once, each assuming its
            // neighbours stay): undo it and go on with positions alone.
            x = bx.clone();
            skins = bs.clone();
            maps = build_maps(&skins);
            skin_rounds = false;
            last_was_skin = false;
            restored = true;
            continue;
        } else {
            // Worse than the best so far: stop (the best is what is kept).
            break;
        }
        if iteration >= opts.iterations {
            break;
        }
        iteration += 1;
        last_was_skin = skin_now;
        if skin_now {
            let old_skins = skins.clone();
            let old_maps = maps.clone();
            for v in 0..m {
                if cands[v].is_empty() {
                    continue;
                }
                let (h, g) = &weight_sys[v];
                let (joints, weights) = skins[v];
                let current: Vec<f64> = cands[v]
                    .iter()
                    .map(|&(j, _)| joints.iter().zip(&weights).filter(|(jj, _)| **jj == j).map(|(_, w)| *w as f64).sum())
                    .collect();
                if let Some(skin) = skin_step(h, g, &current, &cands[v]) {
                    skins[v] = skin;
                }
            }
            maps = build_maps(&skins);
            // Undo the new skin of the corners of any triangle it would flip in an example
            // pose, until none does (undone skins stay undone, so this ends).
            loop {
                let mut undone = false;
                for t in &tris {
                    if flips_somewhere(t, (&old_maps, &x), (&maps, &x)) {
                        for &v in t {
                            if skins[v as usize] != old_skins[v as usize] {
                                skins[v as usize] = old_skins[v as usize];
                                undone = true;
                            }
                        }
                    }
                }
                if !undone {
                    break;
                }
                maps = build_maps(&skins);
            }
            continue;
        }
        big.regularise(&x, 1e-3, 1e-6);
        let mut next = x.clone();
        big.solve(&mut next, 300);
        // Halve, then drop, the moves of vertices on triangles that flip in any example pose,
        // until none does (the collapses only check the rest pose, see `crate::simplify`; moving vertices
        // after the fact must not add flips anywhere).
        // Dropped moves stay dropped, so this ends after at most `m` more rounds, and a
        // triangle whose corners all stay has not flipped.
        for round in 0.. {
            let mut reverted = false;
            for t in &tris {
                if flips_somewhere(t, (&maps, &x), (&maps, &next)) {
                    for &v in t {
                        let range = big.start[v as usize]..big.start[v as usize] + dim[v as usize];
                        if next[range.clone()] != x[range.clone()] {
                            // Halve the move; from the tenth round on, drop it.
                            for i in range {
                                next[i] = if round >= 9 { x[i] } else { (x[i] + next[i]) * 0.5 };
                            }
                            reverted = true;
                        }
                    }
                }
            }
            if !reverted {
                break;
            }
        }
        if next.iter().all(|p| p.is_finite()) {
            x = next;
        }
    }
    let Some((_, x, skins)) = best else { return };
    for (v, &id) in ids.iter().enumerate() {
        let unknowns = &x[big.start[v]..big.start[v] + dim[v]];
        if !unknowns.iter().all(|p| p.as_vec3().is_finite()) {
            continue;
        }
        let rec = &mut verts[id as usize];
        rec.rest = unknowns[0].as_vec3();
        (rec.joints, rec.weights) = skins[v];
        for (d, u) in rec.morph.iter_mut().zip(&unknowns[1..]) {
            *d = u.as_vec3();
        }
    }
}

/// One vertex's new skin: the weights over at most four of `cands` (joint, priority) that
/// minimise `w' H w - 2 g' w` (`h` row-major) with the weights summing to 1 and none negative,
/// pulled slightly toward `current`. Every support of one to four candidates is tried (the
/// equality-constrained minimum by its KKT system, kept when no weight is negative): at most
/// 162 for eight candidates. `None` when the system says nothing. Our addition: the linear
/// blend skinning weights of Mohr & Gleicher ("Deformation Sensitive Decimation", 2003, section
/// 4.3) fitted to sampled surface correspondences instead of blended from the endpoints.
pub fn skin_step(h: &[f64], g: &[f64], current: &[f64], cands: &[(u16, f64)]) -> Option<Skin> {
    let n = cands.len();
    if n == 0 || h.len() != n * n || g.len() != n || current.len() != n {
        return None;
    }
    let trace: f64 = (0..n).map(|i| h[i * n + i]).sum();
    if !(trace > 0.0) || !trace.is_finite() {
        return None;
    }
    let mu = 1e-4 * trace / n as f64;
    let hr = |i: usize, j: usize| h[i * n + j] + if i == j { mu } else { 0.0 };
    let gr = |i: usize| g[i] + mu * current[i];
    let mut best: Option<(f64, Vec<usize>, Vec<f64>)> = None;
    let mut support: Vec<usize> = Vec::with_capacity(4);
    while next_support(&mut support, n, 4) {
        let s = support.len();
        // KKT: [2H 1; 1' 0] [w; l] = [2g; 1], rows of s + 2 (the last is the right side).
        let k = s + 1;
        let mut a = vec![0.0; k * (k + 1)];
        for (r, &i) in support.iter().enumerate() {
            for (c, &j) in support.iter().enumerate() {
                a[r * (k + 1) + c] = 2.0 * hr(i, j);
            }
            a[r * (k + 1) + s] = 1.0;
            a[r * (k + 1) + k] = 2.0 * gr(i);
            a[s * (k + 1) + r] = 1.0;
        }
        a[s * (k + 1) + k] = 1.0;
        let Some(sol) = solve_dense(&mut a, k) else { continue };
        if sol[..s].iter().any(|&x| !(x >= -1e-9)) {
            continue;
        }
        let w: Vec<f64> = sol[..s].iter().map(|&x| x.max(0.0)).collect();
        let mut e = 0.0;
        for (p, &i) in support.iter().enumerate() {
            e -= 2.0 * gr(i) * w[p];
            for (q, &j) in support.iter().enumerate() {
                e += w[p] * hr(i, j) * w[q];
            }
        }
        if best.as_ref().is_none_or(|(b, _, _)| e < *b) {
            best = Some((e, support.clone(), w));
        }
    }
    let (_, support, w) = best?;
    let mut pairs: Vec<(u16, f64)> = support.iter().zip(&w).map(|(&i, &w)| (cands[i].0, w)).filter(|p| p.1 > 0.0).collect();
    pairs.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let sum: f64 = pairs.iter().map(|p| p.1).sum();
    if !(sum > 0.0) || !sum.is_finite() {
        return None;
    }
    let mut joints = [0u16; 4];
    let mut weights = [0f32; 4];
    for (slot, (j, w)) in pairs.iter().enumerate().take(4) {
        joints[slot] = *j;
        weights[slot] = (*w / sum) as f32;
    }
    Some((joints, weights))
}

/// Advances `support` (increasing indices below `n`, at most `max` of them) to the next subset
/// in depth-first lexicographic order, starting from the empty one; false when done.
fn next_support(support: &mut Vec<usize>, n: usize, max: usize) -> bool {
    if support.len() < max.min(n) {
        let start = support.last().map_or(0, |&l| l + 1);
        if start < n {
            support.push(start);
            return true;
        }
    }
    while let Some(last) = support.pop() {
        if last + 1 < n {
            support.push(last + 1);
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn supports_of_up_to_four() {
        let mut s = Vec::new();
        let mut count = 0;
        while next_support(&mut s, 8, 4) {
            assert!(!s.is_empty() && s.len() <= 4 && s.windows(2).all(|w| w[0] < w[1]));
            count += 1;
        }
        assert_eq!(count, 8 + 28 + 56 + 70);
    }

    #[test]
    fn skin_step_finds_the_constrained_minimum() {
        // Five candidates; the unconstrained minimum is (0.5, 0.3, 0.2, 0, 0) for H = I.
        let n = 5;
        let mut h = vec![0.0; n * n];
        (0..n).for_each(|i| h[i * n + i] = 1.0);
        let g = [0.5, 0.3, 0.2, 0.0, -0.4];
        let cands: Vec<(u16, f64)> = (0..n as u16).map(|j| (j + 10, 1.0)).collect();
        let (joints, weights) = skin_step(&h, &g, &[0.2; 5], &cands).expect("a skin");
        assert!((weights.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert!(weights.iter().all(|&w| w >= 0.0));
        assert_eq!(joints[..3], [10, 11, 12]);
        assert!((weights[0] - 0.5).abs() < 1e-3 && (weights[1] - 0.3).abs() < 1e-3 && weights[3] < 1e-3, "{weights:?}");
    }
}
