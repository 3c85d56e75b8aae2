//! Deterministic area-uniform sampling of a triangle mesh's surface.

use crate::rng::SplitMix64;
use glam::{DVec3, Vec3};
use pmcodec_mesh::TriMesh;

/// `count` points uniformly distributed by area over the mesh's triangles ([`area_samples`]),
/// followed by every vertex that a triangle uses (in index order; unused vertices are not on
/// the surface). A mesh of zero total area yields only its vertices. The caller has validated
/// the mesh (indices in range, finite coordinates).
pub(crate) fn sample_surface(mesh: &TriMesh, count: usize, seed: u64) -> Vec<Vec3> {
    let corners = |t: &[u32; 3]| t.map(|i| mesh.positions[i as usize].as_dvec3());
    let areas: Vec<f64> = mesh.triangles.iter().map(|t| triangle_area(corners(t))).collect();
    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    let samples = area_samples(&areas, count, seed);
    let mut out = Vec::with_capacity(samples.len() + used.iter().filter(|&&u| u).count());
    for (t, u, v) in samples {
        let [a, b, c] = corners(&mesh.triangles[t as usize]);
        let p: DVec3 = a + (b - a) * u + (c - a) * v;
        out.push(p.as_vec3());
    }
    out.extend(mesh.positions.iter().zip(&used).filter(|&(_, &u)| u).map(|(p, _)| *p));
    out
}

/// Area of a triangle, in f64 (sums over many small triangles in f32 would drift).
pub fn triangle_area([a, b, c]: [DVec3; 3]) -> f64 {
    0.5 * (b - a).cross(c - a).length()
}

/// `count` points uniformly distributed by area over triangles of the given `areas`, as
/// `(triangle, u, v)`: the point `a + (b - a) u + (c - a) v` of triangle `(a, b, c)`, i.e.
/// barycentric `(1 - u - v, u, v)`. The workspace's one area sampler (the distance measure and
/// `pmcodec-lod`'s refit both draw from it).
///
/// The samples are stratified: sample `k` is uniform within the `k`-th of `count` equal slices
/// of the cumulative area. Every point is still area-uniform, the number landing on each
/// triangle is within one of its expected share (so an estimate has less variance than with
/// independent draws), and the points come out in triangle order, which is spatially coherent
/// in real meshes and makes consecutive closest-point queries touch the same BVH nodes. No
/// samples when the total area is zero or not finite.
pub fn area_samples(areas: &[f64], count: usize, seed: u64) -> Vec<(u32, f64, f64)> {
    let mut cumulative = Vec::with_capacity(areas.len());
    let mut total = 0.0f64;
    for &a in areas {
        total += a;
        cumulative.push(total);
    }
    let count = if total > 0.0 && total.is_finite() { count } else { 0 };
    let mut out = Vec::with_capacity(count);
    let mut rng = SplitMix64::new(seed);
    let last = areas.len().saturating_sub(1);
    let mut tri = 0usize;
    for k in 0..count {
        let r = (k as f64 + rng.unit()) / count as f64 * total;
        // The targets increase with k, so the triangle cursor only moves forward. Zero-area
        // triangles have an empty slice and are stepped over.
        while tri < last && cumulative[tri] <= r {
            tri += 1;
        }
        // Uniform on the triangle: a uniform point of the unit square, folded onto the lower
        // half along the diagonal (the fold is measure-preserving).
        let (mut u, mut v) = (rng.unit(), rng.unit());
        if u + v > 1.0 {
            u = 1.0 - u;
            v = 1.0 - v;
        }
        out.push((tri as u32, u, v));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_follow_area() {
        // Two triangles, the second with three times the area of the first.
        let m = TriMesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(10.0, 0.0, 0.0),
                Vec3::new(13.0, 0.0, 0.0),
                Vec3::new(10.0, 1.0, 0.0),
                Vec3::splat(99.0), // unused: not a sample
            ],
            triangles: vec![[0, 1, 2], [3, 4, 5]],
        };
        let s = sample_surface(&m, 4000, 1);
        assert_eq!(s.len(), 4000 + 6);
        let on_second = s[..4000].iter().filter(|p| p.x >= 10.0).count();
        assert!((2999..=3001).contains(&on_second), "{on_second}");
        assert!(!s.contains(&Vec3::splat(99.0)));
        assert!(s[..1000].iter().all(|p| p.x + p.y <= 1.0 + 1e-6 && p.z == 0.0));
    }

    #[test]
    fn zero_area_gives_vertices_only() {
        let m = TriMesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], triangles: vec![[0, 1, 2]] };
        assert_eq!(sample_surface(&m, 100, 3), m.positions);
    }
}
