//! Exact closest point on a triangle, by the Voronoi regions of its vertices, edges and face.
//!
//! The arithmetic is done in `f64` on the `f32` input: every difference of two `f32` values is
//! then (practically always) exact, and thin triangles keep an accurate normal. That costs
//! little (the work is scalar either way) and lets the distance statistics be trusted down to
//! the precision of the input itself.

use glam::{DVec3, Vec3};

/// A face whose squared sine of the angle at its first corner is below this is treated as a
/// segment. Below it the normal is dominated by rounding (relative error about 1e-16 / sin);
/// above it the error of calling the face a segment is at most `sin * edge length`. At 1e-14
/// (sin 1e-7) both errors are below the `f32` precision the input was given in.
const SLIVER_SIN2: f64 = 1e-14;

/// The point of triangle `t` closest to `p`. Degenerate triangles (repeated corners, collinear
/// corners) are handled: their closest point is the closest point of their segments.
pub fn closest_point(p: DVec3, t: [DVec3; 3]) -> DVec3 {
    closest_point_within(p, t, f64::INFINITY).unwrap_or(p)
}

/// [`closest_point`], or `None` as soon as it is clear the point is not closer than
/// `sqrt(bound2)`: the distance to the triangle's plane is a lower bound that costs one dot
/// product more than the degeneracy test needs anyway, and most candidates a BVH hands over
/// fail it.
#[inline]
fn closest_point_within(p: DVec3, t: [DVec3; 3], bound2: f64) -> Option<DVec3> {
    let [a, b, c] = t;
    let ab = b - a;
    let ac = c - a;

    // Degenerate first: the region tests below assume three distinct, non-collinear corners
    // (with a == b, for instance, the empty edge ab passes its own region test for any p).
    // The cross product is accurate exactly when the angle at a is not tiny, which is what the
    // test measures; it covers repeated corners too (a zero edge makes the right side zero).
    let n = ab.cross(ac);
    let n2 = n.length_squared();
    if !(n2 > SLIVER_SIN2 * ab.length_squared() * ac.length_squared()) {
        return Some(closest_on_segments(p, a, b, c));
    }
    // Early out on the plane distance. The margin keeps rounding from rejecting a triangle
    // whose full computation below would come out (by an ulp) just under the bound, so a
    // search with this test finds exactly what one without it does.
    let ap = p - a;
    let height = ap.dot(n);
    if height * height > bound2 * n2 * (1.0 + 1e-9) {
        return None;
    }

    // Vertex region of a: p is behind a along both edges leaving it.
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return Some(a);
    }
    // Vertex region of b: p is past b along ab, and behind b along bc (d4 - d3 = bc . bp).
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return Some(b);
    }
    // Vertex region of c: past c along ac, and not towards b along cb (d5 - d6 = cb . cp).
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return Some(c);
    }

    // Edge regions. Each `v*` is (a multiple of) the barycentric coordinate of the opposite
    // corner, so its sign says on which side of that edge p's projection falls; the two other
    // tests say the projection falls between the edge's endpoints. The corners are distinct
    // here, so the divisions are by positive numbers (`ratio` clamps rounding all the same).
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return Some(a + ab * ratio(d1, d1 - d3));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return Some(a + ac * ratio(d2, d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 >= d3 && d5 >= d6 {
        return Some(b + (c - b) * ratio(d4 - d3, (d4 - d3) + (d5 - d6)));
    }

    // Face region. Project along the normal instead of through the barycentrics (vb, vc over
    // va + vb + vc): same point, but the projection keeps its accuracy on thin triangles,
    // whose barycentric denominators lose digits quadratically in the angle.
    Some(p - n * (height / n2))
}

/// Closest point of a zero-area triangle: it is the union of its three segments (all of which
/// may be points).
fn closest_on_segments(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let mut best = closest_on_segment(p, a, b);
    for q in [closest_on_segment(p, b, c), closest_on_segment(p, c, a)] {
        if (q - p).length_squared() < (best - p).length_squared() {
            best = q;
        }
    }
    best
}

/// `num / den` for a parameter known to lie in [0, 1]; 0 when the segment has no length.
#[inline]
fn ratio(num: f64, den: f64) -> f64 {
    if den > 0.0 { (num / den).clamp(0.0, 1.0) } else { 0.0 }
}

/// The point of segment [a, b] closest to `p` (a itself when a == b).
pub fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    a + ab * ratio((p - a).dot(ab), ab.length_squared())
}

/// Squared distance from `p` to triangle `t`, in `f64`.
#[inline]
pub fn distance2(p: Vec3, t: &[Vec3; 3]) -> f64 {
    distance2_below(p, t, f64::INFINITY)
}

/// Squared distance from `p` to triangle `t` when it is below `bound2`; otherwise some value
/// at least `bound2` (possibly infinity). For searches that only care about a closer triangle.
#[inline]
pub fn distance2_below(p: Vec3, t: &[Vec3; 3], bound2: f64) -> f64 {
    let q = p.as_dvec3();
    match closest_point_within(q, t.map(Vec3::as_dvec3), bound2) {
        Some(c) => (c - q).length_squared(),
        None => f64::INFINITY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d2(p: [f64; 3], t: [[f64; 3]; 3]) -> f64 {
        let p = DVec3::from_array(p);
        (closest_point(p, t.map(DVec3::from_array)) - p).length_squared()
    }

    const T: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn every_region_of_a_right_triangle() {
        let cases = [
            ([0.2, 0.2, 1.0], 1.0),   // face, above
            ([0.2, 0.2, -2.0], 4.0),  // face, below
            ([-1.0, -1.0, 0.0], 2.0), // vertex a
            ([2.0, -1.0, 0.0], 2.0),  // vertex b
            ([-1.0, 2.0, 0.0], 2.0),  // vertex c
            ([0.5, -1.0, 0.0], 1.0),  // edge ab
            ([-1.0, 0.5, 1.0], 2.0),  // edge ca
            ([1.0, 1.0, 0.0], 0.5),   // edge bc
            ([0.25, 0.25, 0.0], 0.0), // inside
            ([1.0, 0.0, 0.0], 0.0),   // on a corner
        ];
        for (p, want) in cases {
            assert!((d2(p, T) - want).abs() < 1e-12, "{p:?}: {} vs {want}", d2(p, T));
        }
    }

    #[test]
    fn degenerate_triangles_are_their_segments() {
        // Collinear, with the middle corner last: the hull is the segment from 0 to 2.
        let line = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        assert!((d2([1.5, 1.0, 0.0], line) - 1.0).abs() < 1e-12);
        assert!((d2([3.0, 0.0, 0.0], line) - 1.0).abs() < 1e-12);
        assert!((d2([-1.0, 0.0, 1.0], line) - 2.0).abs() < 1e-12);
        // Two corners equal: a segment.
        let seg = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        assert!((d2([1.0, 1.0, 0.0], seg) - 1.0).abs() < 1e-12);
        assert!((d2([0.0, 3.0, 0.0], seg) - 1.0).abs() < 1e-12);
        // All corners equal: a point.
        let point = [[1.0, 1.0, 1.0]; 3];
        assert!((d2([1.0, 1.0, 3.0], point) - 4.0).abs() < 1e-12);
        for p in [[0.5, 0.5, 0.5], [1.0, 1.0, 1.0], [-3.0, 0.0, 9.0]] {
            for t in [line, seg, point] {
                assert!(d2(p, t).is_finite());
            }
        }
    }

    #[test]
    fn a_sliver_keeps_its_plane_distance() {
        // 1000 long, 1e-3 wide: barycentrics would lose digits here, the normal does not.
        let t = [[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [500.0, 1e-3, 0.0]];
        let got = d2([400.0, 1e-4, 0.25], t);
        assert!((got - 0.0625).abs() < 1e-12, "{got}");
    }
}
