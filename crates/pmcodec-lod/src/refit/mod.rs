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

mod flips;
mod geometry;
mod normal;
mod problem;

use self::geometry::*;
use self::normal::*;
use self::problem::Refit;

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
    /// Refit skin weights too, in rounds alternating with the positions' (see `skin_step`).
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
    let Some(fit) = Refit::new(attrs, input_triangles, poses, verts, triangles, rep, opts).and_then(Refit::run) else { return };
    for (v, &id) in fit.ids.iter().enumerate() {
        let unknowns = &fit.x[fit.start[v]..fit.start[v] + fit.dim[v]];
        if !unknowns.iter().all(|p| p.as_vec3().is_finite()) {
            continue;
        }
        let rec = &mut verts[id as usize];
        rec.rest = unknowns[0].as_vec3();
        (rec.joints, rec.weights) = fit.skins[v];
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
