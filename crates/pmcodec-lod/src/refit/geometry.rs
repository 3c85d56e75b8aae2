//! Geometry of the refit: the ICP metric, barycentric samples of the LOD surface, flips.

use super::*;

/// `(1 - share) n n' + share I`: point-to-plane (Chen & Medioni 1992) along the face normal
/// `n`, blended with point-to-point; point-to-point alone when `n` is zero.
pub(super) fn metric(n: DVec3, share: f64) -> DMat3 {
    if n == DVec3::ZERO {
        return DMat3::IDENTITY;
    }
    let nn = DMat3::from_cols(n * n.x, n * n.y, n * n.z);
    nn * (1.0 - share) + DMat3::IDENTITY * share
}

/// Barycentric sample points `(triangle, b)`: `count` spread by `areas`
/// ([`pmcodec_eval::area_samples`], the sampler the error measure uses), plus every corner once
/// (the error measure samples the vertices too).
pub(super) fn sample_bary(triangles: &[[u32; 3]], areas: &[f64], count: usize, seed: u64) -> Vec<(u32, [f64; 3])> {
    let mut out = Vec::with_capacity(count + triangles.len() * 3);
    out.extend(pmcodec_eval::area_samples(areas, count, seed).into_iter().map(|(t, u, v)| (t, [1.0 - u - v, u, v])));
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

/// Whether a triangle with a normal before (`before`) points the other way `after`.
pub(super) fn flipped(before: [DVec3; 3], after: [DVec3; 3]) -> bool {
    let n0 = (before[1] - before[0]).cross(before[2] - before[0]);
    let n1 = (after[1] - after[0]).cross(after[2] - after[0]);
    n0.length_squared() > 0.0 && !(n0.dot(n1) > 0.0)
}

pub(super) fn area(p: [Vec3; 3]) -> f64 {
    pmcodec_eval::triangle_area(p.map(|x| x.as_dvec3()))
}

/// Barycentric coordinates of `q` (a point of the triangle) in `t`, clamped to the triangle.
pub(super) fn barycentric(q: DVec3, t: [DVec3; 3]) -> [f64; 3] {
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
