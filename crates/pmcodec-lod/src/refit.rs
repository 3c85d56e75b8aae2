//! Refitting an LOD's vertex positions to the input surface over all example poses.
//!
//! Greedy collapse places every vertex once, from quadrics that only know the planes of the
//! faces it absorbed; once the collapses are done, the coarse surface can still be moved closer
//! to the input. With the connectivity and every vertex's skin and morph deltas fixed, a vertex
//! is an affine function of its rest position in every pose ([`crate::attrs`]), so a point of
//! an LOD triangle at barycentric coordinates `b` is `sum_j b_j (L_jk p_j + c_jk)` in pose `k`:
//! linear in the rest positions `p`. Given closest-point correspondences in every pose (points
//! of the input surface to their closest LOD points, and points of the LOD to their closest
//! input points, the two directions the error is measured in), the squared distances summed
//! over poses are a linear least-squares problem in the rest positions. We solve it, recompute
//! the correspondences and repeat a few times (iterative closest point, Besl & McKay 1992, in
//! the spirit of Hoppe et al.'s 1993 mesh optimisation "fit" step, with the vertex skin of
//! Houle & Poulin, seed 000 section 4.1, held fixed: the fit moves vertices in bone space,
//! i.e. in rest space before skinning).
//!
//! This is our addition to the seeds. It never increases the sampled objective: an iteration
//! whose result is worse than the best so far is dropped, and so is the move of any vertex that
//! would flip one of its triangles in the rest pose.

use crate::attrs::{Vertex, VertexAttrs};
use crate::poses::Pose;
use glam::{DMat3, DVec3, Mat3, Vec3};
use pmcodec_eval::SurfaceIndex;
use pmcodec_eval::triangle::closest_point;
use pmcodec_mesh::TriMesh;
use std::collections::HashMap;

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
}

impl Default for RefitOptions {
    fn default() -> Self {
        RefitOptions { iterations: 6, samples: 3000, max_poses: 96 }
    }
}

/// Tiny deterministic generator for the sample positions.
struct SplitMix(u64);

impl SplitMix {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Barycentric sample points `(triangle, b)`: about `count` spread by `areas`, plus every
/// corner once (the error measure samples the vertices too).
fn sample_bary(triangles: &[[u32; 3]], areas: &[f64], count: usize, seed: u64) -> Vec<(u32, [f64; 3])> {
    let total: f64 = areas.iter().sum();
    let mut out = Vec::with_capacity(count + triangles.len() * 3);
    let mut rng = SplitMix(seed);
    let mut carry = 0.0;
    for (t, &a) in areas.iter().enumerate() {
        if !(total > 0.0) {
            break;
        }
        carry += count as f64 * a / total;
        while carry >= 1.0 {
            carry -= 1.0;
            let (mut u, mut v) = (rng.unit(), rng.unit());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            out.push((t as u32, [1.0 - u - v, u, v]));
        }
    }
    let mut seen: HashMap<u32, ()> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for (k, &c) in tri.iter().enumerate() {
            if seen.insert(c, ()).is_none() {
                let mut b = [0.0; 3];
                b[k] = 1.0;
                out.push((t as u32, b));
            }
        }
    }
    out
}

fn area(p: [Vec3; 3]) -> f64 {
    let [a, b, c] = p.map(|x| x.as_dvec3());
    0.5 * (b - a).cross(c - a).length()
}

/// Barycentric coordinates of `q` (a point of the triangle) in `t`, clamped to the triangle.
fn barycentric(q: DVec3, t: [DVec3; 3]) -> [f64; 3] {
    let (v0, v1, v2) = (t[1] - t[0], t[2] - t[0], q - t[0]);
    let (d00, d01, d11, d20, d21) = (v0.dot(v0), v0.dot(v1), v1.dot(v1), v2.dot(v0), v2.dot(v1));
    let den = d00 * d11 - d01 * d01;
    if !(den.abs() > 1e-300) {
        return [1.0 / 3.0; 3];
    }
    let v = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0);
    let s = v + w;
    let (v, w) = if s > 1.0 { (v / s, w / s) } else { (v, w) };
    [1.0 - v - w, v, w]
}

/// The normal equations of the fit: per vertex a 3x3 diagonal block, per LOD edge one
/// off-diagonal block (`H[i][j]` for `i < j`; `H[j][i]` is its transpose), and the right side.
struct System {
    diag: Vec<DMat3>,
    off: Vec<DMat3>,
    /// `(i, j)` with `i < j` for every entry of `off`.
    pairs: Vec<(u32, u32)>,
    index: HashMap<(u32, u32), u32>,
    rhs: Vec<DVec3>,
}

impl System {
    fn new(m: usize, triangles: &[[u32; 3]]) -> Self {
        let mut pairs = Vec::new();
        let mut index = HashMap::new();
        for tri in triangles {
            for k in 0..3 {
                let (a, b) = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
                if a != b {
                    index.entry((a, b)).or_insert_with(|| {
                        pairs.push((a, b));
                        pairs.len() as u32 - 1
                    });
                }
            }
        }
        System { diag: vec![DMat3::ZERO; m], off: vec![DMat3::ZERO; pairs.len()], pairs, index, rhs: vec![DVec3::ZERO; m] }
    }

    fn clear(&mut self) {
        self.diag.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.off.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.rhs.iter_mut().for_each(|x| *x = DVec3::ZERO);
    }

    /// Adds `w |sum_j b_j (L_j p_j + c_j) - y|^2` for the corners `tri` of one LOD triangle.
    fn add(&mut self, tri: [u32; 3], b: [f64; 3], maps: [&(DMat3, DVec3); 3], y: DVec3, w: f64) {
        let offset: DVec3 = (0..3).map(|j| maps[j].1 * b[j]).sum();
        let r = y - offset;
        for i in 0..3 {
            if b[i] == 0.0 {
                continue;
            }
            let li = maps[i].0;
            self.rhs[tri[i] as usize] += li.transpose() * r * (w * b[i]);
            for j in 0..3 {
                if b[j] == 0.0 {
                    continue;
                }
                let block = li.transpose() * maps[j].0 * (w * b[i] * b[j]);
                let (a, c) = (tri[i], tri[j]);
                if a == c {
                    self.diag[a as usize] += block;
                } else if a < c
                    && let Some(&e) = self.index.get(&(a, c))
                {
                    self.off[e as usize] += block;
                }
                // a > c: the transpose of the (c, a) entry, added when i and j swap.
            }
        }
    }

    fn mul(&self, x: &[DVec3], out: &mut [DVec3]) {
        for (o, (d, v)) in out.iter_mut().zip(self.diag.iter().zip(x)) {
            *o = *d * *v;
        }
        for (m, &(i, j)) in self.off.iter().zip(&self.pairs) {
            out[i as usize] += *m * x[j as usize];
            out[j as usize] += m.transpose() * x[i as usize];
        }
    }

    /// Preconditioned conjugate gradients from `x` (block Jacobi preconditioner).
    fn solve(&self, x: &mut [DVec3], iterations: usize) {
        let m = x.len();
        let inv: Vec<DMat3> =
            self.diag.iter().map(|d| if d.determinant().abs() > 1e-300 { d.inverse() } else { DMat3::IDENTITY }).collect();
        let mut ax = vec![DVec3::ZERO; m];
        self.mul(x, &mut ax);
        let mut r: Vec<DVec3> = self.rhs.iter().zip(&ax).map(|(b, a)| *b - *a).collect();
        let mut z: Vec<DVec3> = r.iter().zip(&inv).map(|(r, p)| *p * *r).collect();
        let mut d = z.clone();
        let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a.dot(*b)).sum();
        let r0: f64 = r.iter().map(|v| v.length_squared()).sum();
        let mut ad = vec![DVec3::ZERO; m];
        for _ in 0..iterations {
            if !(rz.abs() > 0.0) {
                break;
            }
            self.mul(&d, &mut ad);
            let dad: f64 = d.iter().zip(&ad).map(|(a, b)| a.dot(*b)).sum();
            if !(dad > 0.0) {
                break;
            }
            let alpha = rz / dad;
            for k in 0..m {
                x[k] += d[k] * alpha;
                r[k] -= ad[k] * alpha;
            }
            let rr: f64 = r.iter().map(|v| v.length_squared()).sum();
            if rr <= 1e-20 * r0 {
                break;
            }
            for k in 0..m {
                z[k] = inv[k] * r[k];
            }
            let rz1: f64 = r.iter().zip(&z).map(|(a, b)| a.dot(*b)).sum();
            let beta = rz1 / rz;
            rz = rz1;
            for k in 0..m {
                d[k] = z[k] + d[k] * beta;
            }
        }
    }
}

/// Refits the rest positions of the vertices `triangles` use (over input ids into `verts`) so
/// that the LOD surface is closer to the input surface `input_triangles` over `poses`.
pub fn refit(
    attrs: &VertexAttrs,
    input_triangles: &[[u32; 3]],
    poses: &[Pose],
    verts: &mut [Vertex],
    triangles: &[[u32; 3]],
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
    // Per LOD vertex and pose, the affine map from rest to pose: `maps[v * f + k]`.
    let records: &[Vertex] = verts;
    let maps: Vec<(DMat3, DVec3)> = ids
        .iter()
        .flat_map(|&id| {
            poses.iter().map(move |pose| {
                let (l, c): (Mat3, Vec3) = attrs.affine(&records[id as usize], pose);
                (l.as_dmat3(), c.as_dvec3())
            })
        })
        .collect();
    // The input posed in every pose, its surface index and its sample points.
    let n = attrs.len();
    let mut inputs: Vec<(TriMesh, SurfaceIndex)> = Vec::with_capacity(f);
    for pose in &poses {
        let positions: Vec<Vec3> = (0..n).map(|v| attrs.posed(v, pose)).collect();
        let mesh = TriMesh { positions, triangles: input_triangles.to_vec() };
        let Ok(index) = SurfaceIndex::new(&mesh) else { return };
        inputs.push((mesh, index));
    }
    let rest_areas: Vec<f64> = input_triangles.iter().map(|t| area(t.map(|i| attrs.rest[i as usize]))).collect();
    let input_samples = sample_bary(input_triangles, &rest_areas, opts.samples, 0x1D0F);

    let mut rest: Vec<DVec3> = ids.iter().map(|&id| verts[id as usize].rest.as_dvec3()).collect();
    let mut sys = System::new(m, &tris);
    let mut best: Option<(f64, Vec<DVec3>)> = None;
    for iteration in 0..=opts.iterations {
        sys.clear();
        let mut objective = 0.0;
        let lod_areas: Vec<f64> = tris.iter().map(|t| area(t.map(|i| rest[i as usize].as_vec3()))).collect();
        let lod_samples = sample_bary(&tris, &lod_areas, opts.samples, 0x10D);
        for (k, pose) in poses.iter().enumerate() {
            let w = pose.weight;
            if !(w > 0.0) {
                continue;
            }
            let posed: Vec<DVec3> = (0..m).map(|v| maps[v * f + k].0 * rest[v] + maps[v * f + k].1).collect();
            let lod_mesh = TriMesh { positions: posed.iter().map(|p| p.as_vec3()).collect(), triangles: tris.clone() };
            let Ok(lod_index) = SurfaceIndex::new(&lod_mesh) else { return };
            let (input, input_index) = &inputs[k];
            // Input points to their closest LOD points.
            for &(t, b) in &input_samples {
                let tri = input_triangles[t as usize];
                let y: DVec3 = (0..3).map(|j| input.positions[tri[j] as usize].as_dvec3() * b[j]).sum();
                let (_, lt) = lod_index.closest(y.as_vec3());
                let Some(&ltri) = tris.get(lt as usize) else { continue };
                let corners = ltri.map(|v| posed[v as usize]);
                let q = closest_point(y, corners);
                objective += w * (q - y).length_squared();
                let bb = barycentric(q, corners);
                sys.add(ltri, bb, ltri.map(|v| &maps[v as usize * f + k]), y, w);
            }
            // LOD points to their closest input points.
            for &(t, b) in &lod_samples {
                let ltri = tris[t as usize];
                let x: DVec3 = (0..3).map(|j| posed[ltri[j] as usize] * b[j]).sum();
                let (_, it) = input_index.closest(x.as_vec3());
                let Some(&itri) = input_triangles.get(it as usize) else { continue };
                let y = closest_point(x, itri.map(|v| input.positions[v as usize].as_dvec3()));
                objective += w * (x - y).length_squared();
                sys.add(ltri, b, ltri.map(|v| &maps[v as usize * f + k]), y, w);
            }
        }
        if best.as_ref().is_none_or(|(o, _)| objective < *o) {
            best = Some((objective, rest.clone()));
        } else {
            // Worse than the best so far: stop (the best is what is kept).
            break;
        }
        if iteration == opts.iterations {
            break;
        }
        // Keep the system positive definite where few samples land: a small pull toward the
        // current position, relative to the vertex's own block.
        let mean_trace = sys.diag.iter().map(|d| d.x_axis.x + d.y_axis.y + d.z_axis.z).sum::<f64>() / m.max(1) as f64;
        for (v, d) in sys.diag.iter_mut().enumerate() {
            let mu = 1e-3 * (d.x_axis.x + d.y_axis.y + d.z_axis.z) / 3.0 + 1e-6 * mean_trace + 1e-30;
            *d += DMat3::from_diagonal(DVec3::splat(mu));
            sys.rhs[v] += rest[v] * mu;
        }
        let mut next = rest.clone();
        sys.solve(&mut next, 200);
        // Drop moves that flip a triangle in the rest pose, until none does.
        for _ in 0..8 {
            let mut reverted = false;
            for t in &tris {
                let before = t.map(|v| rest[v as usize]);
                let after = t.map(|v| next[v as usize]);
                let n0 = (before[1] - before[0]).cross(before[2] - before[0]);
                let n1 = (after[1] - after[0]).cross(after[2] - after[0]);
                if n0.length_squared() > 0.0 && !(n0.dot(n1) > 0.0) {
                    for &v in t {
                        if next[v as usize] != rest[v as usize] {
                            next[v as usize] = rest[v as usize];
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
            rest = next;
        }
    }
    let Some((_, rest)) = best else { return };
    for (&id, p) in ids.iter().zip(&rest) {
        let p = p.as_vec3();
        if p.is_finite() {
            verts[id as usize].rest = p;
        }
    }
}
