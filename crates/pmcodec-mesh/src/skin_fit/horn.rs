//! The rotation that best carries one weighted point set onto another: Horn's closed form by
//! unit quaternions (Horn, "Closed-form solution of absolute orientation using unit
//! quaternions", 1987). Its quaternion is the eigenvector of the largest eigenvalue of a
//! symmetric 4x4 matrix, found here by cyclic Jacobi rotations (glam has no eigen solver or
//! SVD). Unlike Kabsch's SVD it always gives a proper rotation, and for degenerate sets (one
//! point, collinear points, zero weights) still a rotation rather than a reflection or NaN.

use glam::{DMat3, DQuat, DVec3};

/// A rigid transform `x -> r x + t` (`r` a rotation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid {
    pub r: DMat3,
    pub t: DVec3,
}

impl Rigid {
    pub const IDENTITY: Rigid = Rigid { r: DMat3::IDENTITY, t: DVec3::ZERO };

    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.r * p + self.t
    }
}

/// The rotation `R` maximising `sum_i (R a_i) . b_i` for the cross-covariance
/// `s = sum_i a_i b_i^T` (`s.col(c)[r]` = sum of `a_r b_c`) of centred point sets: Horn's
/// equation 4.
pub fn rotation_from_covariance(s: DMat3) -> DMat3 {
    // s_xy = sum a_x b_y, with glam's column-major storage: s.col(y)[x].
    let e = |x: usize, y: usize| s.col(y)[x];
    let (sxx, sxy, sxz) = (e(0, 0), e(0, 1), e(0, 2));
    let (syx, syy, syz) = (e(1, 0), e(1, 1), e(1, 2));
    let (szx, szy, szz) = (e(2, 0), e(2, 1), e(2, 2));
    let mut n = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let q = match largest_eigenvector(&n) {
        Some(v) => DQuat::from_xyzw(v[1], v[2], v[3], v[0]),
        None => {
            let (values, vectors) = jacobi4(&mut n);
            // Ties go to the lowest index, so an all-zero covariance gives the identity
            // quaternion.
            let mut best = 0;
            for k in 1..4 {
                if values[k] > values[best] {
                    best = k;
                }
            }
            DQuat::from_xyzw(vectors[1][best], vectors[2][best], vectors[3][best], vectors[0][best])
        }
    };
    let len = q.length();
    if !(len.is_finite() && len > 1e-300) {
        return DMat3::IDENTITY;
    }
    DMat3::from_quat(q / len)
}

/// The eigenvector of the largest eigenvalue of Horn's traceless symmetric `n`, by the
/// quaternion characteristic polynomial (Theobald, "Rapid calculation of RMSDs using a
/// quaternion-based characteristic polynomial", 2005): Newton's method on
/// `det(n - x I)` from an upper bound of its roots (all real, so it descends monotonically to
/// the largest), then the eigenvector as the largest column of the adjugate of `n - x I`.
/// `None` when that column vanishes (the largest eigenvalue repeated, or `n` zero): the
/// caller then uses Jacobi's method. A fit solves one of these per bone per frame.
fn largest_eigenvector(n: &[[f64; 4]; 4]) -> Option<[f64; 4]> {
    let sum2: f64 = n.iter().flatten().map(|x| x * x).sum();
    if !(sum2 > 1e-300 && sum2.is_finite()) {
        return None;
    }
    // Traceless with sum of squared eigenvalues sum2: none exceeds sqrt(3 sum2 / 4).
    let mut x = (0.75 * sum2).sqrt() * (1.0 + 1e-9);
    let scale = x;
    // det(n - x I) = x^4 + c2 x^2 + c1 x + c0 for traceless n.
    let mut n3 = 0.0;
    for i in 0..4 {
        for j in 0..4 {
            for k in 0..4 {
                n3 += n[i][j] * n[j][k] * n[k][i];
            }
        }
    }
    let (c2, c1, c0) = (-0.5 * sum2, -n3 / 3.0, det4(n));
    for _ in 0..64 {
        let x2 = x * x;
        let p = (x2 + c2) * x2 + c1 * x + c0;
        let dp = (4.0 * x2 + 2.0 * c2) * x + c1;
        if !(dp.abs() > 1e-300) {
            break;
        }
        let step = p / dp;
        x -= step;
        if !(step.abs() > 1e-15 * scale) {
            break;
        }
    }
    let mut a = *n;
    for (i, row) in a.iter_mut().enumerate() {
        row[i] -= x;
    }
    // Columns of the adjugate: cofactors of a's rows; the longest is the eigenvector.
    let mut best = ([0.0; 4], 0.0);
    for col in 0..4 {
        let mut v = [0.0; 4];
        for (row, out) in v.iter_mut().enumerate() {
            let sign = if (row + col) % 2 == 0 { 1.0 } else { -1.0 };
            *out = sign * minor3(&a, col, row);
        }
        let len2: f64 = v.iter().map(|c| c * c).sum();
        if len2 > best.1 {
            best = (v, len2);
        }
    }
    // Adjugate entries scale as the cube of the eigenvalues; a column far below that has lost
    // its digits to cancellation.
    if !(best.1.sqrt() > 1e-7 * scale * scale * scale) {
        return None;
    }
    Some(best.0)
}

/// The determinant of `a` without row `skip_row` and column `skip_col`.
fn minor3(a: &[[f64; 4]; 4], skip_row: usize, skip_col: usize) -> f64 {
    let mut m = [[0.0; 3]; 3];
    for (r, i) in (0..4).filter(|&i| i != skip_row).enumerate() {
        for (c, j) in (0..4).filter(|&j| j != skip_col).enumerate() {
            m[r][c] = a[i][j];
        }
    }
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// The determinant of a 4x4 matrix, by cofactors of its first row.
fn det4(a: &[[f64; 4]; 4]) -> f64 {
    (0..4).map(|j| if j % 2 == 0 { 1.0 } else { -1.0 } * a[0][j] * minor3(a, 0, j)).sum()
}

/// The weighted rigid transform carrying `a_i` onto `b_i` (weights `w_i >= 0`) in the least
/// squares sense; the identity when the weights sum to nothing.
pub fn fit_rigid(points: impl Iterator<Item = (DVec3, DVec3, f64)> + Clone) -> Rigid {
    let (mut sw, mut ca, mut cb) = (0.0, DVec3::ZERO, DVec3::ZERO);
    for (a, b, w) in points.clone() {
        sw += w;
        ca += w * a;
        cb += w * b;
    }
    if !(sw > 1e-300) {
        return Rigid::IDENTITY;
    }
    let (ca, cb) = (ca / sw, cb / sw);
    let mut s = DMat3::ZERO;
    for (a, b, w) in points {
        s += outer(w * (a - ca), b - cb);
    }
    let r = rotation_from_covariance(s);
    Rigid { r, t: cb - r * ca }
}

/// `a b^T`: column c is `a * b[c]`.
#[inline]
pub fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Eigenvalues and eigenvectors (as the columns of the returned matrix) of the symmetric `a`,
/// by cyclic Jacobi sweeps (Golub and Van Loan, "Matrix Computations", section 8.5). `a` is
/// overwritten.
fn jacobi4(a: &mut [[f64; 4]; 4]) -> ([f64; 4], [[f64; 4]; 4]) {
    let mut v = [[0.0; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let scale: f64 = a.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    // Quadratic convergence: a handful of sweeps reach rounding; 32 is a bound, not a target.
    for _ in 0..32 {
        let off: f64 = (0..4).flat_map(|p| (p + 1..4).map(move |q| (p, q))).map(|(p, q)| a[p][q] * a[p][q]).sum();
        if !(off.sqrt() > 1e-15 * scale) {
            break;
        }
        for p in 0..4 {
            for q in p + 1..4 {
                let apq = a[p][q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..4 {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for k in 0..4 {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for row in v.iter_mut() {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2], a[3][3]], v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_rotation_and_translation() {
        let truth = Rigid {
            r: DMat3::from_quat(DQuat::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 2.3)),
            t: DVec3::new(0.3, -4.0, 7.0),
        };
        let a: Vec<DVec3> = (0..9).map(|i| DVec3::new((i as f64).sin() * 3.0, (i * i) as f64 * 0.1, (i as f64 * 0.7).cos())).collect();
        let fit = fit_rigid(a.iter().map(|&p| (p, truth.apply(p), 1.0)));
        assert!((fit.r - truth.r).abs().to_cols_array().iter().all(|&x| x < 1e-9), "{:?}", fit.r);
        assert!((fit.t - truth.t).length() < 1e-9);
        assert!((fit.r.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn degenerate_sets_give_rotations() {
        // One point, and collinear points: any rotation about the line fits; it must be proper.
        for pts in [vec![DVec3::ONE], vec![DVec3::ZERO, DVec3::X, 2.0 * DVec3::X], vec![]] {
            let fit = fit_rigid(pts.iter().map(|&p| (p, p + DVec3::Y, 1.0)));
            assert!((fit.r.determinant() - 1.0).abs() < 1e-9 || pts.is_empty());
            for p in &pts {
                assert!((fit.apply(*p) - (*p + DVec3::Y)).length() < 1e-9);
            }
        }
        assert_eq!(fit_rigid(std::iter::once((DVec3::X, DVec3::Y, 0.0))), Rigid::IDENTITY);
    }

    #[test]
    fn the_characteristic_polynomial_agrees_with_jacobi() {
        // Covariances of varied shapes (generic, near-planar, near-collinear, a reflection's):
        // the fast eigenvector gives Jacobi's rotation, or declines.
        let mut declined = 0;
        for i in 0..500 {
            let x = |k: u32| ((i * 7 + k * 13) as f64 * 0.618034).fract() - 0.5;
            let mut s = DMat3::from_cols_array(&std::array::from_fn(|k| x(k as u32)));
            match i % 5 {
                1 => s.z_axis *= 1e-6,
                2 => s = DMat3::from_cols(s.x_axis, s.x_axis * 0.5, s.x_axis * 1e-9),
                3 => s = -s,
                _ => {}
            }
            let r = rotation_from_covariance(s);
            assert!((r.determinant() - 1.0).abs() < 1e-9, "{i}");
            let e = |x: usize, y: usize| s.col(y)[x];
            let mut n = [
                [e(0, 0) + e(1, 1) + e(2, 2), e(1, 2) - e(2, 1), e(2, 0) - e(0, 2), e(0, 1) - e(1, 0)],
                [e(1, 2) - e(2, 1), e(0, 0) - e(1, 1) - e(2, 2), e(0, 1) + e(1, 0), e(2, 0) + e(0, 2)],
                [e(2, 0) - e(0, 2), e(0, 1) + e(1, 0), -e(0, 0) + e(1, 1) - e(2, 2), e(1, 2) + e(2, 1)],
                [e(0, 1) - e(1, 0), e(2, 0) + e(0, 2), e(1, 2) + e(2, 1), -e(0, 0) - e(1, 1) + e(2, 2)],
            ];
            if largest_eigenvector(&n).is_none() {
                declined += 1;
                continue;
            }
            let (values, vectors) = jacobi4(&mut n);
            let best = (0..4).fold(0, |b, k| if values[k] > values[b] { k } else { b });
            let mut sorted = values;
            sorted.sort_by(f64::total_cmp);
            if sorted[3] - sorted[2] < 1e-6 * sorted[3].abs().max(1e-12) {
                continue; // a nearly repeated eigenvalue: any rotation of its plane fits
            }
            let q = DQuat::from_xyzw(vectors[1][best], vectors[2][best], vectors[3][best], vectors[0][best]).normalize();
            let j = DMat3::from_quat(q);
            assert!((r - j).abs().to_cols_array().iter().all(|&d| d < 1e-7), "{i}: {r:?} vs {j:?}");
        }
        assert!(declined < 150, "{declined}");
    }
}
