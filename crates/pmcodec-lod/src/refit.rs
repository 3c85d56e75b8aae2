//! Refitting an LOD's vertex positions (and morph deltas) to the input surface over all example
//! poses.
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
//! with the skin of Houle & Poulin (seed 000, section 4.1) held fixed: the fit moves vertices in
//! bone space, i.e. in rest space before skinning. Refitting the deltas fits each vertex's
//! morph targets to the input's in the poses that use them (Berner & Rieger, seed 003, simplify
//! against the targets; we also fit to them).
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

/// Most 3x3 blocks of the normal equations (72 bytes each) when morph deltas are refitted too;
/// beyond it (many vertices with many targets) only the rest positions are.
pub const MAX_BLOCKS: usize = 1 << 21;

/// Most posed input triangles kept over the poses of a round (about 100 bytes each with their
/// index); beyond it each pose's input is rebuilt in every round.
pub const MAX_CACHED_TRIANGLES: usize = 1 << 21;

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
}

impl Default for RefitOptions {
    fn default() -> Self {
        RefitOptions { iterations: 6, samples: 3000, max_poses: 96, point_share: 0.1, morph: true }
    }
}

/// `(1 - share) n n' + share I`: point-to-plane (Chen & Medioni 1992) along the face normal
/// `n`, blended with point-to-point; point-to-point alone when `n` is zero.
fn metric(n: DVec3, share: f64) -> DMat3 {
    if n == DVec3::ZERO {
        return DMat3::IDENTITY;
    }
    let nn = DMat3::from_cols(n * n.x, n * n.y, n * n.z);
    nn * (1.0 - share) + DMat3::IDENTITY * share
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

/// The normal equations of one pose: per vertex a 3x3 diagonal block, per LOD edge one
/// off-diagonal block (`H[i][j]` for `i < j`; `H[j][i]` is its transpose), and the right side,
/// all over the vertices' posed-space affine maps with the morph deltas held (see [`Big`]).
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

    /// Adds `w |sum_j b_j (L_j p_j + c_j) - y|^2` for the corners `tri` of one LOD triangle,
    /// the residual measured in the metric `metric` (the identity for point-to-point).
    fn add(&mut self, tri: [u32; 3], b: [f64; 3], maps: [&(DMat3, DVec3); 3], y: DVec3, w: f64, metric: &DMat3) {
        let offset: DVec3 = (0..3).map(|j| maps[j].1 * b[j]).sum();
        let r = *metric * (y - offset);
        for i in 0..3 {
            if b[i] == 0.0 {
                continue;
            }
            let lt = maps[i].0.transpose();
            self.rhs[tri[i] as usize] += lt * r * (w * b[i]);
            let ltm = lt * *metric;
            for j in 0..3 {
                if b[j] == 0.0 {
                    continue;
                }
                let block = ltm * maps[j].0 * (w * b[i] * b[j]);
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
}

/// The normal equations over all poses, in the unknowns of every LOD vertex: its rest position
/// and, when its morph deltas are refitted, each delta (all 3-vectors, flat, vertex after
/// vertex). In pose `k` the vertex is `L (p + sum_t w_kt d_t) + t`, so with `a_k = (1, w_k1,
/// ...)` a pose's 3x3 block `G` between two vertices becomes the blocks `a_ks a_kr G` between
/// their unknowns `s` and `r`: each pose is accumulated as a [`System`] first and expanded once.
struct Big {
    /// Per vertex, its first unknown and its number of unknowns.
    start: Vec<usize>,
    dim: Vec<usize>,
    /// Per vertex, `dim^2` blocks (row-major by unknown) from `diag_start[v]`.
    diag_start: Vec<usize>,
    diag: Vec<DMat3>,
    /// Per pair of [`System::pairs`], `dim_i * dim_j` blocks from `off_start[e]`.
    off_start: Vec<usize>,
    off: Vec<DMat3>,
    pairs: Vec<(u32, u32)>,
    rhs: Vec<DVec3>,
}

// Index loops on purpose: one index runs over several flat arrays at once.
#[allow(clippy::needless_range_loop)]
impl Big {
    fn new(dim: &[usize], pairs: &[(u32, u32)]) -> Self {
        let mut start = Vec::with_capacity(dim.len());
        let mut diag_start = Vec::with_capacity(dim.len());
        let (mut n, mut nd) = (0, 0);
        for &d in dim {
            start.push(n);
            diag_start.push(nd);
            n += d;
            nd += d * d;
        }
        let mut off_start = Vec::with_capacity(pairs.len());
        let mut no = 0;
        for &(i, j) in pairs {
            off_start.push(no);
            no += dim[i as usize] * dim[j as usize];
        }
        Big {
            start,
            dim: dim.to_vec(),
            diag_start,
            diag: vec![DMat3::ZERO; nd],
            off_start,
            off: vec![DMat3::ZERO; no],
            pairs: pairs.to_vec(),
            rhs: vec![DVec3::ZERO; n],
        }
    }

    fn clear(&mut self) {
        self.diag.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.off.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.rhs.iter_mut().for_each(|x| *x = DVec3::ZERO);
    }

    /// Adds one pose's system; `a[v]` gives vertex `v`'s coefficients `(1, w_k1, ...)`.
    fn expand(&mut self, sys: &System, a: &[&[f64]]) {
        for v in 0..self.dim.len() {
            let (d, av) = (self.dim[v], a[v]);
            let g = sys.diag[v];
            if g != DMat3::ZERO {
                for s in 0..d {
                    for r in 0..d {
                        self.diag[self.diag_start[v] + s * d + r] += g * (av[s] * av[r]);
                    }
                }
            }
            for s in 0..d {
                self.rhs[self.start[v] + s] += sys.rhs[v] * av[s];
            }
        }
        for (e, &(i, j)) in self.pairs.iter().enumerate() {
            let g = sys.off[e];
            if g == DMat3::ZERO {
                continue;
            }
            let (di, dj) = (self.dim[i as usize], self.dim[j as usize]);
            let (ai, aj) = (a[i as usize], a[j as usize]);
            for s in 0..di {
                for r in 0..dj {
                    self.off[self.off_start[e] + s * dj + r] += g * (ai[s] * aj[r]);
                }
            }
        }
    }

    fn mul(&self, x: &[DVec3], out: &mut [DVec3]) {
        for v in 0..self.dim.len() {
            let (d, st, ds) = (self.dim[v], self.start[v], self.diag_start[v]);
            for s in 0..d {
                let mut acc = DVec3::ZERO;
                for r in 0..d {
                    acc += self.diag[ds + s * d + r] * x[st + r];
                }
                out[st + s] = acc;
            }
        }
        for (e, &(i, j)) in self.pairs.iter().enumerate() {
            let (di, dj) = (self.dim[i as usize], self.dim[j as usize]);
            let (si, sj, os) = (self.start[i as usize], self.start[j as usize], self.off_start[e]);
            for s in 0..di {
                for r in 0..dj {
                    let m = self.off[os + s * dj + r];
                    out[si + s] += m * x[sj + r];
                    out[sj + r] += m.transpose() * x[si + s];
                }
            }
        }
    }

    /// The diagonal 3x3 block of unknown `s` of vertex `v`.
    fn own(&self, v: usize, s: usize) -> DMat3 {
        self.diag[self.diag_start[v] + s * self.dim[v] + s]
    }

    /// Adds `mu |x_(v,s) - x0|^2` for every unknown: `mu` is `relative` times the unknown's own
    /// block's mean eigenvalue plus `absolute` times the mean over all rest-position blocks.
    /// This keeps the system positive definite where few samples land.
    fn regularise(&mut self, x0: &[DVec3], relative: f64, absolute: f64) {
        let trace = |m: DMat3| m.x_axis.x + m.y_axis.y + m.z_axis.z;
        let m = self.dim.len().max(1);
        let mean = (0..self.dim.len()).map(|v| trace(self.own(v, 0))).sum::<f64>() / m as f64;
        for v in 0..self.dim.len() {
            for s in 0..self.dim[v] {
                let mu = relative * trace(self.own(v, s)) / 3.0 + absolute * mean + 1e-30;
                let k = self.diag_start[v] + s * self.dim[v] + s;
                self.diag[k] += DMat3::from_diagonal(DVec3::splat(mu));
                self.rhs[self.start[v] + s] += x0[self.start[v] + s] * mu;
            }
        }
    }

    /// Preconditioned conjugate gradients from `x` (3x3 block Jacobi preconditioner).
    fn solve(&self, x: &mut [DVec3], iterations: usize) {
        let n = x.len();
        let mut inv = vec![DMat3::IDENTITY; n];
        for v in 0..self.dim.len() {
            for s in 0..self.dim[v] {
                let d = self.own(v, s);
                if d.determinant().abs() > 1e-300 {
                    inv[self.start[v] + s] = d.inverse();
                }
            }
        }
        let dot = |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).map(|(x, y)| x.dot(*y)).sum::<f64>();
        let mut ax = vec![DVec3::ZERO; n];
        self.mul(x, &mut ax);
        let mut r: Vec<DVec3> = self.rhs.iter().zip(&ax).map(|(b, a)| *b - *a).collect();
        let mut z: Vec<DVec3> = r.iter().zip(&inv).map(|(r, p)| *p * *r).collect();
        let mut d = z.clone();
        let mut rz = dot(&r, &z);
        let r0 = dot(&r, &r);
        let mut ad = vec![DVec3::ZERO; n];
        for _ in 0..iterations {
            if !(rz.abs() > 0.0) {
                break;
            }
            self.mul(&d, &mut ad);
            let dad = dot(&d, &ad);
            if !(dad > 0.0) {
                break;
            }
            let alpha = rz / dad;
            for k in 0..n {
                x[k] += d[k] * alpha;
                r[k] -= ad[k] * alpha;
            }
            if dot(&r, &r) <= 1e-20 * r0 {
                break;
            }
            for k in 0..n {
                z[k] = inv[k] * r[k];
            }
            let rz1 = dot(&r, &z);
            let beta = rz1 / rz;
            rz = rz1;
            for k in 0..n {
                d[k] = z[k] + d[k] * beta;
            }
        }
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
    // Per LOD vertex and pose, the affine map from its unknowns' combination to the pose
    // (`maps[v * f + k]`), and the combination's coefficients (`coef[v * f + k]`).
    let records: &[Vertex] = verts;
    let mut maps: Vec<(DMat3, DVec3)> = Vec::with_capacity(m * f);
    let mut coef: Vec<Vec<f64>> = Vec::with_capacity(m * f);
    for (v, &id) in ids.iter().enumerate() {
        let rec = &records[id as usize];
        let bare = Vertex { morph: Vec::new(), ..rec.clone() };
        let instance = attrs.classes.get(rec.class as usize).map(|c| c.instance);
        for pose in &poses {
            let (l, c): (Mat3, Vec3) = attrs.affine(if dim[v] > 1 { &bare } else { rec }, pose);
            maps.push((l.as_dmat3(), c.as_dvec3()));
            let w = instance.and_then(|i| pose.morph.get(i));
            coef.push((0..dim[v]).map(|s| if s == 0 { 1.0 } else { w.and_then(|w| w.get(s - 1)).map_or(0.0, |&x| x as f64) }).collect());
        }
    }
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
    let mut best: Option<(f64, Vec<DVec3>)> = None;
    for iteration in 0..=opts.iterations {
        big.clear();
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
                let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]).normalize_or_zero();
                sys.add(ltri, bb, ltri.map(|v| &maps[v as usize * f + k]), y, w, &metric(n, opts.point_share));
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
                let n = (ic[1] - ic[0]).cross(ic[2] - ic[0]).normalize_or_zero();
                sys.add(ltri, b, ltri.map(|v| &maps[v as usize * f + k]), y, w, &metric(n, opts.point_share));
            }
            a.clear();
            a.extend((0..m).map(|v| coef[v * f + k].as_slice()));
            big.expand(&sys, &a);
        }
        if best.as_ref().is_none_or(|(o, _)| objective < *o) {
            best = Some((objective, x.clone()));
        } else {
            // Worse than the best so far: stop (the best is what is kept).
            break;
        }
        if iteration == opts.iterations {
            break;
        }
        big.regularise(&x, 1e-3, 1e-6);
        let mut next = x.clone();
        big.solve(&mut next, 300);
        // Drop the moves of vertices on triangles that flip in the rest pose, until none does.
        for _ in 0..8 {
            let mut reverted = false;
            for t in &tris {
                let before = t.map(|v| rest_of(&x, &big, v as usize));
                let after = t.map(|v| rest_of(&next, &big, v as usize));
                let n0 = (before[1] - before[0]).cross(before[2] - before[0]);
                let n1 = (after[1] - after[0]).cross(after[2] - after[0]);
                if n0.length_squared() > 0.0 && !(n0.dot(n1) > 0.0) {
                    for &v in t {
                        let range = big.start[v as usize]..big.start[v as usize] + dim[v as usize];
                        if next[range.clone()] != x[range.clone()] {
                            next[range.clone()].copy_from_slice(&x[range]);
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
    let Some((_, x)) = best else { return };
    for (v, &id) in ids.iter().enumerate() {
        let unknowns = &x[big.start[v]..big.start[v] + dim[v]];
        if !unknowns.iter().all(|p| p.as_vec3().is_finite()) {
            continue;
        }
        let rec = &mut verts[id as usize];
        rec.rest = unknowns[0].as_vec3();
        for (d, u) in rec.morph.iter_mut().zip(&unknowns[1..]) {
            *d = u.as_vec3();
        }
    }
}
