//! The quadric error metric (Garland & Heckbert 1997), as used by Kircher & Garland section 3:
//! every fine vertex carries the area-weighted sum of the plane quadrics of its faces, a node's
//! quadric is the sum over its cluster, and a node sits at the argmin of its quadric.
//!
//! Beside the 10 quadric coefficients a [`Quadric`] carries the cluster's vertex count and
//! position sum. They are additive like the quadric itself, so `Q_a = sum Q_u` keeps them
//! right through every merge and swap, and they give the centroid that ill-conditioned solves are
//! pulled toward (a flat or cylindrical cluster has a line or plane of minimisers; picking the
//! point nearest the centroid keeps the node from sliding along it from frame to frame).

use glam::{DVec3, Vec3};
use std::ops::{AddAssign, SubAssign};

/// Symmetric quadric `Q(x) = x'Ax + 2b'x + c` plus the cluster moments described above.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Quadric {
    /// Upper triangle of A: a00 a01 a02 a11 a12 a22.
    pub a: [f64; 6],
    /// The linear term b.
    pub b: [f64; 3],
    /// The constant term c.
    pub c: f64,
    /// Total area weight (area of the faces that contributed, divided among their corners).
    pub area: f64,
    /// Number of fine vertices in the cluster and the sum of their positions.
    pub count: f64,
    /// Sum of the cluster's fine vertex positions (its centroid times `count`).
    pub sum: [f64; 3],
}

/// Relative strength of the pull toward the centroid: lambda = REG * trace(A) / 3. Small enough
/// to move a well-conditioned solution by a negligible amount, large enough to fix the
/// directions whose eigenvalues are a thousand times below the average.
pub const REGULARISATION: f64 = 1e-3;

impl Quadric {
    /// The quadric of the plane `n.x + d = 0` (n unit length) scaled by `weight`.
    #[inline]
    pub fn plane(n: DVec3, d: f64, weight: f64) -> Self {
        Quadric {
            a: [weight * n.x * n.x, weight * n.x * n.y, weight * n.x * n.z, weight * n.y * n.y, weight * n.y * n.z, weight * n.z * n.z],
            b: [weight * d * n.x, weight * d * n.y, weight * d * n.z],
            c: weight * d * d,
            area: weight,
            count: 0.0,
            sum: [0.0; 3],
        }
    }

    /// Quadric error at `x`. Never negative in exact arithmetic; rounding can make it slightly so,
    /// and callers that rank by it clamp.
    #[inline]
    pub fn eval(&self, x: DVec3) -> f64 {
        let [a00, a01, a02, a11, a12, a22] = self.a;
        let ax = DVec3::new(a00 * x.x + a01 * x.y + a02 * x.z, a01 * x.x + a11 * x.y + a12 * x.z, a02 * x.x + a12 * x.y + a22 * x.z);
        x.dot(ax) + 2.0 * x.dot(DVec3::from_array(self.b)) + self.c
    }

    /// Q(x) at a single-precision point.
    #[inline]
    pub fn eval_f32(&self, x: Vec3) -> f64 {
        self.eval(x.as_dvec3())
    }

    /// Centroid of the cluster's fine vertices (origin for an empty quadric).
    #[inline]
    pub fn centroid(&self) -> DVec3 {
        if self.count > 0.0 { DVec3::from_array(self.sum) / self.count } else { DVec3::ZERO }
    }

    /// Adds one fine vertex's position to the cluster moments.
    #[inline]
    pub fn add_point(&mut self, p: Vec3) {
        self.count += 1.0;
        self.sum[0] += p.x as f64;
        self.sum[1] += p.y as f64;
        self.sum[2] += p.z as f64;
    }

    /// `argmin_x Q(x) + lambda |x - centroid|^2` with lambda = [`REGULARISATION`] * tr(A)/3.
    /// Solved by Cramer's rule on the regularised, symmetric positive definite system
    /// `(A + lambda I) x = lambda m - b`.
    // Always inlined: reclustering's exact benefit solves a cluster for every candidate swap,
    // and the call (the quadric spilled to memory and read back) was a fifth of its cost.
    #[inline(always)]
    pub fn optimal(&self) -> DVec3 {
        let m = self.centroid();
        let [a00, a01, a02, a11, a12, a22] = self.a;
        let trace = a00 + a11 + a22;
        if !(trace > 0.0) || !trace.is_finite() {
            return m;
        }
        let lambda = REGULARISATION * trace / 3.0;
        let (d0, d1, d2) = (a00 + lambda, a11 + lambda, a22 + lambda);
        let r = lambda * m - DVec3::from_array(self.b);
        // Cofactors of the symmetric matrix [[d0 a01 a02][a01 d1 a12][a02 a12 d2]].
        let c00 = d1 * d2 - a12 * a12;
        let c01 = a02 * a12 - a01 * d2;
        let c02 = a01 * a12 - a02 * d1;
        let det = d0 * c00 + a01 * c01 + a02 * c02;
        if !(det.abs() > 1e-300) {
            return m;
        }
        let c11 = d0 * d2 - a02 * a02;
        let c12 = a01 * a02 - d0 * a12;
        let c22 = d0 * d1 - a01 * a01;
        let inv = 1.0 / det;
        let x = DVec3::new(
            (c00 * r.x + c01 * r.y + c02 * r.z) * inv,
            (c01 * r.x + c11 * r.y + c12 * r.z) * inv,
            (c02 * r.x + c12 * r.y + c22 * r.z) * inv,
        );
        if x.is_finite() { x } else { m }
    }

    /// Scales the quadric part (not the moments): per-vertex importance weights.
    pub fn scale(&mut self, s: f64) {
        for v in &mut self.a {
            *v *= s;
        }
        for v in &mut self.b {
            *v *= s;
        }
        self.c *= s;
        self.area *= s;
    }
}

impl AddAssign<&Quadric> for Quadric {
    #[inline]
    fn add_assign(&mut self, o: &Quadric) {
        for i in 0..6 {
            self.a[i] += o.a[i];
        }
        for i in 0..3 {
            self.b[i] += o.b[i];
            self.sum[i] += o.sum[i];
        }
        self.c += o.c;
        self.area += o.area;
        self.count += o.count;
    }
}

impl SubAssign<&Quadric> for Quadric {
    #[inline]
    fn sub_assign(&mut self, o: &Quadric) {
        for i in 0..6 {
            self.a[i] -= o.a[i];
        }
        for i in 0..3 {
            self.b[i] -= o.b[i];
            self.sum[i] -= o.sum[i];
        }
        self.c -= o.c;
        self.area -= o.area;
        self.count -= o.count;
    }
}

/// How the fine-vertex quadrics of one frame are made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadricOptions {
    /// Weight of the perpendicular constraint plane through each boundary edge, relative to the
    /// squared edge length (Garland & Heckbert section 5: boundaries are kept by such planes).
    pub boundary_weight: f64,
}

impl Default for QuadricOptions {
    fn default() -> Self {
        QuadricOptions { boundary_weight: 2.0 }
    }
}

/// Fine-vertex quadrics of one frame: each triangle's plane quadric weighted by a third of its
/// area goes to each corner; each boundary edge (an edge of exactly one triangle) adds its
/// perpendicular constraint plane to both ends. `boundary` lists boundary edges as
/// `(v0, v1, triangle)`; see [`crate::topology::FineTopology`].
pub fn vertex_quadrics(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    boundary: &[(u32, u32, u32)],
    opts: &QuadricOptions,
    out: &mut Vec<Quadric>,
) {
    out.clear();
    out.resize(positions.len(), Quadric::default());
    for (q, p) in out.iter_mut().zip(positions) {
        q.add_point(*p);
    }
    for tri in triangles {
        let [p0, p1, p2] = tri.map(|i| positions[i as usize].as_dvec3());
        let n = (p1 - p0).cross(p2 - p0);
        let len = n.length();
        if !(len > 0.0) {
            continue; // zero-area triangle: no plane, no weight
        }
        let n = n / len;
        let area = 0.5 * len;
        let plane = Quadric::plane(n, -n.dot(p0), area / 3.0);
        for &i in tri {
            out[i as usize] += &plane;
        }
    }
    if opts.boundary_weight > 0.0 {
        for &(v0, v1, t) in boundary {
            let tri = triangles[t as usize];
            let [p0, p1, p2] = tri.map(|i| positions[i as usize].as_dvec3());
            let face_n = (p1 - p0).cross(p2 - p0);
            let (a, b) = (positions[v0 as usize].as_dvec3(), positions[v1 as usize].as_dvec3());
            let e = b - a;
            let n = e.cross(face_n);
            let len = n.length();
            if !(len > 0.0) {
                continue;
            }
            let n = n / len;
            let mut plane = Quadric::plane(n, -n.dot(a), opts.boundary_weight * e.length_squared());
            // Constraint planes shape the error, but are not surface: keep area the faces' own.
            plane.area = 0.0;
            out[v0 as usize] += &plane;
            out[v1 as usize] += &plane;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_error_is_squared_distance() {
        let q = Quadric::plane(DVec3::Z, -1.0, 1.0);
        assert!((q.eval(DVec3::new(3.0, 4.0, 3.0)) - 4.0).abs() < 1e-12);
    }

    #[test]
    fn three_planes_meet_at_corner() {
        let mut q = Quadric::plane(DVec3::X, -1.0, 1.0);
        q += &Quadric::plane(DVec3::Y, -2.0, 1.0);
        q += &Quadric::plane(DVec3::Z, -3.0, 1.0);
        q.add_point(Vec3::ZERO);
        let x = q.optimal();
        // The regularisation pulls by about 1e-3 relative toward the centroid (the origin).
        assert!((x - DVec3::new(1.0, 2.0, 3.0)).length() < 1e-2, "{x}");
    }

    #[test]
    fn flat_cluster_lands_on_plane_at_centroid() {
        let mut q = Quadric::plane(DVec3::Z, -5.0, 2.0);
        for p in [Vec3::new(0.0, 0.0, 5.0), Vec3::new(2.0, 0.0, 5.0), Vec3::new(0.0, 4.0, 5.0)] {
            q.add_point(p);
        }
        let x = q.optimal();
        assert!((x - DVec3::new(2.0 / 3.0, 4.0 / 3.0, 5.0)).length() < 1e-3, "{x}");
    }

    #[test]
    fn add_then_sub_is_identity() {
        let mut a = Quadric::plane(DVec3::new(0.6, 0.8, 0.0), 0.3, 2.0);
        a.add_point(Vec3::ONE);
        let b = Quadric::plane(DVec3::Z, 1.0, 0.5);
        let mut c = a;
        c += &b;
        c -= &b;
        for i in 0..6 {
            assert!((c.a[i] - a.a[i]).abs() < 1e-12);
        }
        assert_eq!(c.count, a.count);
    }

    #[test]
    fn empty_quadric_returns_centroid() {
        let mut q = Quadric::default();
        q.add_point(Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(q.optimal(), DVec3::new(1.0, 2.0, 3.0));
    }
}
