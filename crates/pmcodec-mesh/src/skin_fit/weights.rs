//! SSDR's weight step (Le and Deng, "Smooth Skinning Decomposition with Rigid Bones", 2012,
//! section 4.3): with the bones' transforms fixed, each vertex's weights are the non-negative
//! least-squares fit of its trajectory by its candidate bones' transforms of its rest
//! position, with an affinity (sum to one) row weighted heavily; then only the four largest
//! are kept and refitted on their own.

use super::cluster::near_bones;
use super::horn::Rigid;
use glam::{DVec3, Vec3};

/// Influences per vertex, the most linear blend skinning in glTF and in the container carries.
pub const MAX_INFLUENCES: usize = 4;

/// Each vertex's `k` candidate bones: the bones it already depends on (`keep`, so that a
/// weight step can only lower its error), then those whose transforms of its rest position
/// follow its trajectory over the `sample` frames most closely, best first. Le and Deng
/// restrict each vertex to its nearest bones the same way, which keeps the weight solve small;
/// choosing them again after every transform step lets a vertex move to a bone that has come
/// to fit it better.
pub fn candidates(
    rest: &[DVec3],
    frames: &[Vec<Vec3>],
    transforms: &[Rigid],
    bones: usize,
    k: usize,
    sample: &[usize],
    keep: Option<&[Vec<(u32, f64)>]>,
) -> Vec<Vec<u32>> {
    let k = k.min(bones).max(1);
    let mut out = Vec::with_capacity(rest.len());
    let mut scored: Vec<(f64, u32)> = Vec::with_capacity(bones);
    // Each vertex's main bone (the clustering's label before any weights), for nearness.
    let main: Vec<u32> = (0..rest.len()).map(|v| keep.and_then(|k| k.get(v)).and_then(|i| i.first()).map_or(0, |p| p.0)).collect();
    let near = near_bones(rest, &main, bones);
    for (v, &p) in rest.iter().enumerate() {
        scored.clear();
        for &b in &near[v] {
            let b = b as usize;
            let e: f64 = sample.iter().map(|&f| transforms[f * bones + b].apply(p).distance_squared(frames[f][v].as_dvec3())).sum();
            scored.push((e, b as u32));
        }
        scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut c: Vec<u32> =
            keep.and_then(|k| k.get(v)).map(|infl| infl.iter().filter(|p| p.1 > 0.0).map(|p| p.0).collect()).unwrap_or_default();
        for s in &scored {
            if c.len() >= k {
                break;
            }
            if !c.contains(&s.1) {
                c.push(s.1);
            }
        }
        out.push(c);
    }
    out
}

/// Vertex `v`'s weights on `bones_of` (at most [`MAX_INFLUENCES`] non-zero, summing to one,
/// largest first), fitted over every frame.
pub fn solve_vertex(v: usize, rest: DVec3, frames: &[Vec<Vec3>], transforms: &[Rigid], bones: usize, bones_of: &[u32]) -> Vec<(u32, f64)> {
    let k = bones_of.len();
    if k == 0 {
        return Vec::new();
    }
    let (g, h) = normal_equations(v, rest, frames, transforms, bones, bones_of);
    let w = constrained(&g, &h, k);
    let mut pairs: Vec<(u32, f64)> = bones_of.iter().copied().zip(w).filter(|p| p.1 > 0.0).collect();
    pairs.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    if pairs.len() > MAX_INFLUENCES {
        // Refit on the four largest alone rather than renormalising them: the dropped weights'
        // share goes where the least-squares fit puts it.
        pairs.truncate(MAX_INFLUENCES);
        let sub: Vec<u32> = pairs.iter().map(|p| p.0).collect();
        let (g, h) = normal_equations(v, rest, frames, transforms, bones, &sub);
        pairs = sub.into_iter().zip(constrained(&g, &h, MAX_INFLUENCES)).filter(|p| p.1 > 0.0).collect();
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

/// `G = A^T A` and `h = A^T x` for the columns `A_k` = bone k's transforms of `rest` stacked
/// over frames, and the vertex's stacked trajectory `x`.
fn normal_equations(
    v: usize,
    rest: DVec3,
    frames: &[Vec<Vec3>],
    transforms: &[Rigid],
    bones: usize,
    bones_of: &[u32],
) -> (Vec<f64>, Vec<f64>) {
    let k = bones_of.len();
    let (mut g, mut h) = (vec![0.0; k * k], vec![0.0; k]);
    let mut cols: Vec<DVec3> = vec![DVec3::ZERO; k];
    for (f, frame) in frames.iter().enumerate() {
        let x = frame[v].as_dvec3();
        for (c, &b) in cols.iter_mut().zip(bones_of) {
            *c = transforms[f * bones + b as usize].apply(rest);
        }
        for i in 0..k {
            h[i] += cols[i].dot(x);
            for j in i..k {
                g[i * k + j] += cols[i].dot(cols[j]);
            }
        }
    }
    for i in 0..k {
        for j in 0..i {
            g[i * k + j] = g[j * k + i];
        }
    }
    (g, h)
}

/// `min |A w - x|^2 + lambda (1^T w - 1)^2` over `w >= 0`, with `lambda` large beside `G`'s
/// diagonal, so the weights sum to one up to rounding (Le and Deng's affinity constraint as a
/// weighted row).
fn constrained(g: &[f64], h: &[f64], k: usize) -> Vec<f64> {
    let mean_diag = (0..k).map(|i| g[i * k + i]).sum::<f64>() / k as f64;
    let lambda = 1e3 * mean_diag.max(1e-300);
    let mut g = g.to_vec();
    let mut h = h.to_vec();
    for i in 0..k {
        h[i] += lambda;
        for j in 0..k {
            g[i * k + j] += lambda;
        }
    }
    nnls(&g, &h, k)
}

/// Non-negative least squares in normal-equation form, `min w^T G w / 2 - h^T w` over
/// `w >= 0` for a symmetric positive semi-definite `G`: Lawson and Hanson's active set method
/// ("Solving Least Squares Problems", 1974, chapter 23), with the passive subproblems solved by
/// Gaussian elimination.
pub fn nnls(g: &[f64], h: &[f64], k: usize) -> Vec<f64> {
    let mut w = vec![0.0; k];
    let mut passive = vec![false; k];
    let scale = (0..k).map(|i| g[i * k + i].abs()).fold(0.0, f64::max).max(1e-300);
    let tol = 1e-12 * scale;
    // Each outer step adds one index; inner steps remove at least one; 3k bounds both.
    for _ in 0..3 * k {
        let grad: Vec<f64> = (0..k).map(|i| h[i] - (0..k).map(|j| g[i * k + j] * w[j]).sum::<f64>()).collect();
        let Some(add) = (0..k).filter(|&i| !passive[i] && grad[i] > tol).max_by(|&a, &b| grad[a].total_cmp(&grad[b]).then(b.cmp(&a)))
        else {
            break;
        };
        passive[add] = true;
        for _ in 0..3 * k {
            let set: Vec<usize> = (0..k).filter(|&i| passive[i]).collect();
            let z = solve_subset(g, h, k, &set);
            if set.iter().zip(&z).all(|(_, &zi)| zi > 0.0) {
                for (&i, &zi) in set.iter().zip(&z) {
                    w[i] = zi;
                }
                break;
            }
            // Step from w toward z until the first passive weight reaches zero.
            let mut alpha: f64 = 1.0;
            for (&i, &zi) in set.iter().zip(&z) {
                if zi <= 0.0 {
                    alpha = alpha.min(w[i] / (w[i] - zi));
                }
            }
            for (&i, &zi) in set.iter().zip(&z) {
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
fn solve_subset(g: &[f64], h: &[f64], k: usize, set: &[usize]) -> Vec<f64> {
    let m = set.len();
    let mut a = vec![0.0; m * (m + 1)];
    let ridge = 1e-12 * set.iter().map(|&i| g[i * k + i].abs()).fold(0.0, f64::max).max(1e-300);
    for (r, &i) in set.iter().enumerate() {
        for (c, &j) in set.iter().enumerate() {
            a[r * (m + 1) + c] = g[i * k + j] + if r == c { ridge } else { 0.0 };
        }
        a[r * (m + 1) + m] = h[i];
    }
    for col in 0..m {
        let pivot =
            (col..m).max_by(|&x, &y| a[x * (m + 1) + col].abs().total_cmp(&a[y * (m + 1) + col].abs()).then(y.cmp(&x))).unwrap_or(col);
        if pivot != col {
            for c in 0..=m {
                a.swap(col * (m + 1) + c, pivot * (m + 1) + c);
            }
        }
        let d = a[col * (m + 1) + col];
        if d.abs() < 1e-300 {
            continue;
        }
        for r in col + 1..m {
            let factor = a[r * (m + 1) + col] / d;
            for c in col..=m {
                a[r * (m + 1) + c] -= factor * a[col * (m + 1) + c];
            }
        }
    }
    let mut z = vec![0.0; m];
    for r in (0..m).rev() {
        let d = a[r * (m + 1) + r];
        let s: f64 = (r + 1..m).map(|c| a[r * (m + 1) + c] * z[c]).sum();
        z[r] = if d.abs() < 1e-300 { 0.0 } else { (a[r * (m + 1) + m] - s) / d };
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
