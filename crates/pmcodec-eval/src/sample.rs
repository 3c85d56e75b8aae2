//! Deterministic area-uniform sampling of a triangle mesh's surface.

use crate::rng::SplitMix64;
use glam::{DVec3, Vec3};
use pmcodec_mesh::TriMesh;

/// `count` points uniformly distributed by area over the mesh's triangles, followed by every
/// vertex that a triangle uses (in index order; unused vertices are not on the surface).
///
/// The area samples are stratified: sample `k` is uniform within the `k`-th of `count` equal
/// slices of the cumulative area. Every point is still area-uniform, the number landing on each
/// triangle is within one of its expected share (so the estimate has less variance than with
/// independent draws), and the points come out in the mesh's triangle order, which is spatially
/// coherent in real meshes and makes consecutive closest-point queries touch the same BVH nodes.
///
/// A mesh of zero total area yields only its vertices. The caller has validated the mesh
/// (indices in range, finite coordinates).
pub(crate) fn sample_surface(mesh: &TriMesh, count: usize, seed: u64) -> Vec<Vec3> {
    let corners = |t: &[u32; 3]| t.map(|i| mesh.positions[i as usize].as_dvec3());
    // Cumulative areas in f64: a sum over many small triangles in f32 would drift.
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0f64;
    for t in &mesh.triangles {
        let [a, b, c] = corners(t);
        total += 0.5 * (b - a).cross(c - a).length();
        cumulative.push(total);
    }

    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    let vertices = used.iter().filter(|&&u| u).count();

    let area_samples = if total > 0.0 && total.is_finite() { count } else { 0 };
    let mut out = Vec::with_capacity(area_samples + vertices);
    let mut rng = SplitMix64::new(seed);
    let last = mesh.triangles.len().saturating_sub(1);
    let mut tri = 0usize;
    for k in 0..area_samples {
        let r = (k as f64 + rng.unit()) / area_samples as f64 * total;
        // The targets increase with k, so the triangle cursor only moves forward. Zero-area
        // triangles have an empty slice and are stepped over.
        while tri < last && cumulative[tri] <= r {
            tri += 1;
        }
        let [a, b, c] = corners(&mesh.triangles[tri]);
        // Uniform on the triangle: a uniform point of the unit square, folded onto the lower
        // half along the diagonal (the fold is measure-preserving).
        let (mut u, mut v) = (rng.unit(), rng.unit());
        if u + v > 1.0 {
            u = 1.0 - u;
            v = 1.0 - v;
        }
        let p: DVec3 = a + (b - a) * u + (c - a) * v;
        out.push(p.as_vec3());
    }
    out.extend(mesh.positions.iter().zip(&used).filter(|&(_, &u)| u).map(|(p, _)| *p));
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
