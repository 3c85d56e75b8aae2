//! The refit's least-squares problem: per-pose normal equations, their expansion over the
//! morph unknowns, and a dense solver for the small skin systems.

use super::*;

/// The normal equations of one pose: per vertex a 3x3 diagonal block, per LOD edge one
/// off-diagonal block (`H[i][j]` for `i < j`; `H[j][i]` is its transpose), and the right side,
/// all over the vertices' posed-space affine maps with the morph deltas held (see [`Big`]).
pub(super) struct System {
    pub(super) diag: Vec<DMat3>,
    pub(super) off: Vec<DMat3>,
    /// `(i, j)` with `i < j` for every entry of `off`.
    pub(super) pairs: Vec<(u32, u32)>,
    pub(super) index: HashMap<(u32, u32), u32>,
    pub(super) rhs: Vec<DVec3>,
}

impl System {
    pub(super) fn new(m: usize, triangles: &[[u32; 3]]) -> Self {
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

    pub(super) fn clear(&mut self) {
        self.diag.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.off.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.rhs.iter_mut().for_each(|x| *x = DVec3::ZERO);
    }

    /// Adds `w |sum_j b_j (L_j p_j + c_j) - y|^2` for the corners `tri` of one LOD triangle,
    /// the residual measured in the metric `metric` (the identity for point-to-point).
    pub(super) fn add(&mut self, tri: [u32; 3], b: [f64; 3], maps: [&(DMat3, DVec3); 3], y: DVec3, w: f64, metric: &DMat3) {
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
pub(super) struct Big {
    /// Per vertex, its first unknown and its number of unknowns.
    pub(super) start: Vec<usize>,
    pub(super) dim: Vec<usize>,
    /// Per vertex, `dim^2` blocks (row-major by unknown) from `diag_start[v]`.
    pub(super) diag_start: Vec<usize>,
    pub(super) diag: Vec<DMat3>,
    /// Per pair of [`System::pairs`], `dim_i * dim_j` blocks from `off_start[e]`.
    pub(super) off_start: Vec<usize>,
    pub(super) off: Vec<DMat3>,
    pub(super) pairs: Vec<(u32, u32)>,
    pub(super) rhs: Vec<DVec3>,
}

// Index loops on purpose: one index runs over several flat arrays at once.
#[allow(clippy::needless_range_loop)]
impl Big {
    pub(super) fn new(dim: &[usize], pairs: &[(u32, u32)]) -> Self {
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

    pub(super) fn clear(&mut self) {
        self.diag.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.off.iter_mut().for_each(|x| *x = DMat3::ZERO);
        self.rhs.iter_mut().for_each(|x| *x = DVec3::ZERO);
    }

    /// Adds one pose's system; `a[v]` gives vertex `v`'s coefficients `(1, w_k1, ...)`.
    pub(super) fn expand(&mut self, sys: &System, a: &[&[f64]]) {
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

    pub(super) fn mul(&self, x: &[DVec3], out: &mut [DVec3]) {
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
    pub(super) fn own(&self, v: usize, s: usize) -> DMat3 {
        self.diag[self.diag_start[v] + s * self.dim[v] + s]
    }

    /// Adds `mu |x_(v,s) - x0|^2` for every unknown: `mu` is `relative` times the unknown's own
    /// block's mean eigenvalue plus `absolute` times the mean over all rest-position blocks.
    /// This keeps the system positive definite where few samples land.
    pub(super) fn regularise(&mut self, x0: &[DVec3], relative: f64, absolute: f64) {
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
    pub(super) fn solve(&self, x: &mut [DVec3], iterations: usize) {
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

/// Solves the `k x k` system in the augmented row-major matrix `a` (`k` rows of `k + 1`) by
/// Gaussian elimination with partial pivoting; `None` when it is singular.
pub(super) fn solve_dense(a: &mut [f64], k: usize) -> Option<Vec<f64>> {
    let w = k + 1;
    for col in 0..k {
        let pivot = (col..k).max_by(|&x, &y| a[x * w + col].abs().total_cmp(&a[y * w + col].abs()))?;
        if !(a[pivot * w + col].abs() > 1e-300) {
            return None;
        }
        if pivot != col {
            for c in 0..w {
                a.swap(pivot * w + c, col * w + c);
            }
        }
        for r in col + 1..k {
            let factor = a[r * w + col] / a[col * w + col];
            if factor != 0.0 {
                for c in col..w {
                    a[r * w + c] -= factor * a[col * w + c];
                }
            }
        }
    }
    let mut x = vec![0.0; k];
    for r in (0..k).rev() {
        let mut acc = a[r * w + k];
        for c in r + 1..k {
            acc -= a[r * w + c] * x[c];
        }
        x[r] = acc / a[r * w + r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}
