//! SSDR's weight step (Le and Deng, "Smooth Skinning Decomposition with Rigid Bones", 2012,
//! section 4.3): with the bones' transforms fixed, each vertex's weights are the non-negative
//! least-squares fit of its trajectory by its candidate bones' transforms of its rest
//! position, with an affinity (sum to one) row weighted heavily; then only the four largest
//! are kept and refitted on their own.

use super::horn::Rigid;
use super::sample::Data;

/// Influences per vertex, the most linear blend skinning in glTF and in the container carries.
pub const MAX_INFLUENCES: usize = 4;

/// Candidate bones per vertex at most (the weight solve's fixed-size arrays).
pub const MAX_CANDIDATES: usize = 8;

/// A vertex's candidate bones: `len` of `bones`.
#[derive(Clone, Copy, Debug)]
pub struct Candidates {
    pub bones: [u32; MAX_CANDIDATES],
    pub len: usize,
}

impl Candidates {
    pub fn as_slice(&self) -> &[u32] {
        &self.bones[..self.len]
    }
}

/// Vertex `i`'s `k` candidate bones (`k` at most [`MAX_CANDIDATES`]): the bones it already
/// depends on (`keep`, so that a weight step can only lower its error), then those of `near`
/// whose transforms of its rest position follow its trajectory over the `score` frames (of
/// `data`) most closely, best first. Le and Deng restrict each vertex to its nearest bones the
/// same way, which keeps the weight solve small; choosing them again after every transform
/// step lets a vertex move to a bone that has come to fit it better.
pub fn candidates(data: &Data, i: usize, transforms: &[Rigid], k: usize, near: &[u32], score: &[usize], keep: &[(u32, f64)]) -> Candidates {
    let k = k.clamp(1, MAX_CANDIDATES);
    // `transforms` holds every bone for each of the data's frames.
    let bones = transforms.len() / data.frames.len().max(1);
    let mut out = Candidates { bones: [0; MAX_CANDIDATES], len: 0 };
    for &(b, w) in keep {
        if w > 0.0 && out.len < MAX_CANDIDATES && !out.as_slice().contains(&b) {
            out.bones[out.len] = b;
            out.len += 1;
        }
    }
    if out.len >= k {
        return out;
    }
    // The best k of the near bones by trajectory error, by insertion into a short sorted list.
    let p = data.rest[i];
    let mut best: [(f64, u32); MAX_CANDIDATES] = [(f64::INFINITY, u32::MAX); MAX_CANDIDATES];
    for &b in near {
        if out.as_slice().contains(&b) {
            continue;
        }
        let worst = best[k - 1].0;
        let mut e = 0.0;
        for &fi in score {
            e += transforms[fi * bones + b as usize].apply(p).distance_squared(data.at(fi, i));
            if e > worst {
                break;
            }
        }
        let entry = (e, b);
        if !(entry.0 < worst || (entry.0 == worst && entry.1 < best[k - 1].1)) {
            continue;
        }
        let mut j = k - 1;
        while j > 0 && (best[j - 1].0 > e || (best[j - 1].0 == e && best[j - 1].1 > b)) {
            best[j] = best[j - 1];
            j -= 1;
        }
        best[j] = entry;
    }
    for &(_, b) in best.iter().take(k) {
        if out.len >= k || b == u32::MAX {
            break;
        }
        out.bones[out.len] = b;
        out.len += 1;
    }
    if out.len == 0 {
        out.bones[0] = near.first().copied().unwrap_or(0);
        out.len = 1;
    }
    out
}

/// Vertex `i`'s weights on `bones_of` (at most [`MAX_INFLUENCES`] non-zero, summing to one,
/// largest first), fitted over every frame of `data`.
pub fn solve_vertex(data: &Data, i: usize, transforms: &[Rigid], bones: usize, bones_of: &[u32]) -> Vec<(u32, f64)> {
    let k = bones_of.len().min(MAX_CANDIDATES);
    if k == 0 {
        return Vec::new();
    }
    let bones_of = &bones_of[..k];
    let (g, h) = normal_equations(data, i, transforms, bones, bones_of);
    let w = constrained(&g, &h, k);
    let mut pairs: Vec<(u32, f64)> = bones_of.iter().copied().zip(w).filter(|p| p.1 > 0.0).collect();
    pairs.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    if pairs.len() > MAX_INFLUENCES {
        // Refit on the four largest alone rather than renormalising them: the dropped weights'
        // share goes where the least-squares fit puts it. The four's normal equations are a
        // submatrix of the ones already summed.
        pairs.truncate(MAX_INFLUENCES);
        let idx: Vec<usize> = pairs.iter().map(|p| bones_of.iter().position(|&b| b == p.0).unwrap_or(0)).collect();
        let m = idx.len();
        let mut gs = [0.0; MAX_CANDIDATES * MAX_CANDIDATES];
        let mut hs = [0.0; MAX_CANDIDATES];
        for (r, &a) in idx.iter().enumerate() {
            hs[r] = h[a];
            for (c, &b) in idx.iter().enumerate() {
                gs[r * m + c] = g[a * k + b];
            }
        }
        let sub: Vec<u32> = pairs.iter().map(|p| p.0).collect();
        pairs = sub.into_iter().zip(constrained(&gs, &hs, m)).filter(|p| p.1 > 0.0).collect();
        pairs.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    }
    let sum: f64 = pairs.iter().map(|p| p.1).sum();
    if !(sum > 0.0 && sum.is_finite()) {
        // Nothing fitted (a vertex that never moves away from all bones alike): its best bone.
        return vec![(bones_of[0], 1.0)];
    }
    round_weights(pairs.iter().map(|&(b, w)| (b, w / sum)).collect())
}

/// Weights are rounded to multiples of this: a stored skin then repeats few distinct values
/// and drops influences below half of it, which its bind chunks compress to far fewer bytes,
/// for a prediction error that the transform step (fitted to the rounded weights) absorbs.
pub const WEIGHT_QUANTUM: f64 = 1.0 / 32.0;

/// `pairs` (summing to one, largest first) rounded to [`WEIGHT_QUANTUM`], still summing to one
/// (the largest takes the rounding), influences that round to nothing dropped.
fn round_weights(pairs: Vec<(u32, f64)>) -> Vec<(u32, f64)> {
    let steps = (1.0 / WEIGHT_QUANTUM).round() as i64;
    let mut q: Vec<(u32, i64)> = pairs.iter().map(|&(b, w)| (b, (w * steps as f64).round() as i64)).filter(|p| p.1 > 0).collect();
    if q.is_empty() {
        return pairs.first().map(|p| vec![(p.0, 1.0)]).unwrap_or_default();
    }
    let rest: i64 = q[1..].iter().map(|p| p.1).sum();
    q[0].1 = steps - rest;
    q.into_iter().filter(|p| p.1 > 0).map(|(b, w)| (b, w as f64 / steps as f64)).collect()
}

/// `G = A^T A` (row-major, `k` x `k`) and `h = A^T x` for the columns `A_k` = bone k's
/// transforms of vertex `i`'s rest position stacked over the data's frames, and its stacked
/// trajectory `x`.
fn normal_equations(
    data: &Data,
    i: usize,
    transforms: &[Rigid],
    bones: usize,
    bones_of: &[u32],
) -> ([f64; MAX_CANDIDATES * MAX_CANDIDATES], [f64; MAX_CANDIDATES]) {
    let k = bones_of.len();
    let (mut g, mut h) = ([0.0; MAX_CANDIDATES * MAX_CANDIDATES], [0.0; MAX_CANDIDATES]);
    let mut cols = [glam::DVec3::ZERO; MAX_CANDIDATES];
    let rest = data.rest[i];
    for fi in 0..data.frames.len() {
        let x = data.at(fi, i);
        for (c, &b) in cols.iter_mut().zip(bones_of) {
            *c = transforms[fi * bones + b as usize].apply(rest);
        }
        for r in 0..k {
            h[r] += cols[r].dot(x);
            for c in r..k {
                g[r * k + c] += cols[r].dot(cols[c]);
            }
        }
    }
    for r in 0..k {
        for c in 0..r {
            g[r * k + c] = g[c * k + r];
        }
    }
    (g, h)
}

/// `min |A w - x|^2 + lambda (1^T w - 1)^2` over `w >= 0`, with `lambda` large beside `G`'s
/// diagonal, so the weights sum to one up to rounding (Le and Deng's affinity constraint as a
/// weighted row).
fn constrained(g: &[f64], h: &[f64], k: usize) -> [f64; MAX_CANDIDATES] {
    let mean_diag = (0..k).map(|i| g[i * k + i]).sum::<f64>() / k as f64;
    let lambda = 1e3 * mean_diag.max(1e-300);
    let mut ga = [0.0; MAX_CANDIDATES * MAX_CANDIDATES];
    let mut ha = [0.0; MAX_CANDIDATES];
    for i in 0..k {
        ha[i] = h[i] + lambda;
        for j in 0..k {
            ga[i * k + j] = g[i * k + j] + lambda;
        }
    }
    nnls(&ga, &ha, k)
}

/// Non-negative least squares in normal-equation form, `min w^T G w / 2 - h^T w` over
/// `w >= 0` for a symmetric positive semi-definite `G` (`k` x `k`, row-major, `k` at most
/// [`MAX_CANDIDATES`]): Lawson and Hanson's active set method ("Solving Least Squares
/// Problems", 1974, chapter 23), with the passive subproblems solved by Gaussian elimination.
/// Fixed-size arrays: a fit solves one per vertex per alternation.
pub fn nnls(g: &[f64], h: &[f64], k: usize) -> [f64; MAX_CANDIDATES] {
    let k = k.min(MAX_CANDIDATES);
    let mut w = [0.0; MAX_CANDIDATES];
    let mut passive = [false; MAX_CANDIDATES];
    let scale = (0..k).map(|i| g[i * k + i].abs()).fold(0.0, f64::max).max(1e-300);
    let tol = 1e-12 * scale;
    // Each outer step adds one index; inner steps remove at least one; 3k bounds both.
    for _ in 0..3 * k {
        let mut grad = [0.0; MAX_CANDIDATES];
        for i in 0..k {
            grad[i] = h[i] - (0..k).map(|j| g[i * k + j] * w[j]).sum::<f64>();
        }
        let Some(add) = (0..k).filter(|&i| !passive[i] && grad[i] > tol).max_by(|&a, &b| grad[a].total_cmp(&grad[b]).then(b.cmp(&a)))
        else {
            break;
        };
        passive[add] = true;
        for _ in 0..3 * k {
            let mut set = [0usize; MAX_CANDIDATES];
            let mut m = 0;
            for i in (0..k).filter(|&i| passive[i]) {
                set[m] = i;
                m += 1;
            }
            let set = &set[..m];
            let z = solve_subset(g, h, k, set);
            let z = &z[..m];
            if z.iter().all(|&zi| zi > 0.0) {
                for (&i, &zi) in set.iter().zip(z) {
                    w[i] = zi;
                }
                break;
            }
            // Step from w toward z until the first passive weight reaches zero.
            let mut alpha: f64 = 1.0;
            for (&i, &zi) in set.iter().zip(z) {
                if zi <= 0.0 {
                    alpha = alpha.min(w[i] / (w[i] - zi));
                }
            }
            for (&i, &zi) in set.iter().zip(z) {
                w[i] += alpha * (zi - w[i]);
                if w[i] <= 1e-14 {
                    w[i] = 0.0;
                    passive[i] = false;
                }
            }
            if set.iter().all(|&i| !passive[i]) {
                break;
            }
        }
    }
    w
}

/// `G_SS z = h_S` for the index set `S`, by Gaussian elimination with partial pivoting and a
/// tiny ridge, so that a singular subset (two bones moving alike) still gives a solution.
fn solve_subset(g: &[f64], h: &[f64], k: usize, set: &[usize]) -> [f64; MAX_CANDIDATES] {
    const W: usize = MAX_CANDIDATES + 1;
    let m = set.len();
    let mut a = [[0.0; W]; MAX_CANDIDATES];
    let ridge = 1e-12 * set.iter().map(|&i| g[i * k + i].abs()).fold(0.0, f64::max).max(1e-300);
    for (r, &i) in set.iter().enumerate() {
        for (c, &j) in set.iter().enumerate() {
            a[r][c] = g[i * k + j] + if r == c { ridge } else { 0.0 };
        }
        a[r][m] = h[i];
    }
    for col in 0..m {
        let pivot = (col..m).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()).then(y.cmp(&x))).unwrap_or(col);
        a.swap(col, pivot);
        let d = a[col][col];
        if d.abs() < 1e-300 {
            continue;
        }
        for r in col + 1..m {
            let factor = a[r][col] / d;
            for c in col..=m {
                a[r][c] -= factor * a[col][c];
            }
        }
    }
    let mut z = [0.0; MAX_CANDIDATES];
    for r in (0..m).rev() {
        let d = a[r][r];
        let s: f64 = (r + 1..m).map(|c| a[r][c] * z[c]).sum();
        z[r] = if d.abs() < 1e-300 { 0.0 } else { (a[r][m] - s) / d };
    }
    z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nnls_matches_an_unconstrained_positive_solution_and_clips_negative_ones() {
        // G = I, h = (1, -2, 3): the solution is h clipped at zero.
        let g = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let w = nnls(&g, &[1.0, -2.0, 3.0], 3);
        assert!((w[0] - 1.0).abs() < 1e-9 && w[1] == 0.0 && (w[2] - 3.0).abs() < 1e-9, "{w:?}");
        // A coupled system whose unconstrained solution (2, -1) is infeasible: w = (h0/g00, 0).
        let g = [2.0, 1.0, 1.0, 2.0];
        let w = nnls(&g, &[3.0, 0.0], 2);
        assert!((w[0] - 1.5).abs() < 1e-9 && w[1] == 0.0, "{w:?}");
    }

    #[test]
    fn affinity_row_makes_weights_sum_to_one() {
        let g = [1.0, 0.2, 0.2, 1.0];
        let w = constrained(&g, &[0.1, 0.1], 2);
        assert!((w[0] + w[1] - 1.0).abs() < 1e-2, "{w:?}");
        assert!((w[0] - w[1]).abs() < 1e-9);
    }
}
