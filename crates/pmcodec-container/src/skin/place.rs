//! Where the encoder stores a coarse node of a band that skinning predicts: at the prediction
//! itself (a zero residual) wherever that costs the node's cluster little more error than its
//! per-frame quadric-optimal point does.
//!
//! Why: a coarse node sits at the optimal point of its cluster's quadric (Garland and Heckbert,
//! "Surface simplification using quadric error metrics", 1997; Kircher and Garland,
//! "Progressive multiresolution meshes for deforming surfaces", 2005), a point that moves with
//! the cluster's shape from frame to frame and not as one point carried by the skeleton, so
//! skinning predicts it to tens of quanta at best (Fox: a median 22 to 78 quanta per band) and
//! the coarse bands took three quarters of the position bytes. Houle and Poulin
//! ("Simplification and real-time smooth transitions of articulated meshes", 2001) instead make
//! the coarse vertex a bind-space point that the skeleton carries: its position in every frame
//! *is* its skinned position. Here it is where that costs little, judged by the cluster's own
//! quadric `Q` of the frame: the skinned position `x_s` is taken when
//!
//! * `Q(x_s) - Q(x_t) <= error * Q(x_t) + area * (cells * g)^2`: the cluster's mean squared
//!   distance from its faces' planes grows by at most the fraction `error` of its own, or by what
//!   a displacement of `cells` grid steps `g` of the band's coarse grid along a face normal adds
//!   (storing on that grid already costs up to 0.85 steps), and
//! * `|x_s - x_t|^2 <= reach^2 * area + (cells * g)^2`: the quadric does not see sliding along a
//!   flat cluster, so the node stays within a fraction `reach` of the cluster's size (the square
//!   root of its area) of the optimal point, and the coarse triangles keep their shape.
//!
//! Elsewhere the node is stored on the band's grid near the optimal point, as in bands that
//! skinning does not predict. Decoders are unchanged: they add the zero residual to the same
//! integer prediction.

use glam::DVec3;
use pmcodec_hierarchy::Quadric;

/// How far from its quadric-optimal point a coarse node of a skinned band may be stored at its
/// skinned position (see the module's comment).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkinnedCoarse {
    /// Allowed growth of the cluster's squared quadric error, as a fraction of it.
    pub error: f64,
    /// Allowed displacement along a face normal, in steps of the band's coarse grid.
    pub cells: f64,
    /// Allowed displacement in any direction, as a fraction of the square root of the
    /// cluster's area.
    pub reach: f64,
    /// The skeleton's level of detail: at each coarse level, palette entries are merged into
    /// the kept entry that moves their points most alike while a merge moves the level's nodes
    /// by at most this fraction of the level's mean cluster radius (`skin::skeleton`); a coarse
    /// node's weights on merged entries go to the entry that took them. 0 keeps every entry at
    /// every level.
    pub joints: f64,
}

/// The default keeps cuts as close to the input as before (`pmcodec eval --pmc` on the horse
/// with a fitted skin at 800 vertices: mean RMS 0.0825% -> 0.0829% of the diagonal) for 4.4%
/// fewer position bytes there; `{ error: 0.25, cells: 1.0, reach: 0.25 }` saves 9.4% for 3.7%
/// more RMS error (`examples/skinned_coarse.rs`). Its skeleton levels (`joints: 0.25`) cut what
/// a client at 10% of the triangles reads of the fitted horse from 39.7% to 24.1% of a full
/// client's bytes, of RobotExpressive (every clip) from 59.9% to 48.1%, of Fox from 70.5% to
/// 62.5%, with cuts as close to the input (`pmcodec eval --pmc`: within 0.5% of the RMS error
/// without them) for files 0.2% (horse: fewer influences in the Bind chunks pay for most of
/// the coarse position bytes), 5.7% (Robot) and 8.5% (Fox: a Joints chunk per band and frame
/// where there was one per frame) larger (`examples/skinned.rs`). Larger values merge more
/// for more coarse position bytes (0.5, measured before a coarse node chose the entry each of
/// its merged ones goes to: horse 23.8%, Robot 48.0%, Fox 61.2%, files 2-11% larger).
impl Default for SkinnedCoarse {
    fn default() -> Self {
        SkinnedCoarse { error: 0.1, cells: 0.5, reach: 0.25, joints: 0.25 }
    }
}

/// One frame's coarse-node quadrics with what turns quanta into the quadrics' units.
pub(crate) struct CoarseQuadrics<'a> {
    /// The quadrics of nodes `first..`, by global id.
    pub quadrics: &'a [Quadric],
    pub first: usize,
    /// The quantization grid's origin and step.
    pub lo: DVec3,
    pub step: f64,
    pub tolerance: SkinnedCoarse,
}

impl<'a> CoarseQuadrics<'a> {
    /// The quadrics of nodes `first..` for positions quantized at `step` from `lo`.
    pub fn new(quadrics: &'a [Quadric], first: usize, (lo, step): (glam::Vec3, f32), tolerance: SkinnedCoarse) -> Self {
        CoarseQuadrics { quadrics, first, lo: lo.as_dvec3(), step: step as f64, tolerance }
    }

    /// Whether node `g`, whose optimal point is `t` (in quanta), may be stored at its skinned
    /// prediction `p` (in quanta) on a band whose grid step is `2^shift` quanta.
    pub fn accepts(&self, g: usize, t: [f64; 3], p: [i32; 3], shift: u32) -> bool {
        let Some(q) = g.checked_sub(self.first).and_then(|k| self.quadrics.get(k)) else { return false };
        let world = |x: [f64; 3]| self.lo + DVec3::from_array(x) * self.step;
        let (xt, xs) = (world(t), world(p.map(f64::from)));
        let grid = self.tolerance.cells * (1u64 << shift.min(30)) as f64 * self.step;
        let area = if q.area.is_finite() { q.area.max(0.0) } else { 0.0 };
        let (qt, qs) = (q.eval(xt).max(0.0), q.eval(xs).max(0.0));
        let error_ok = qs - qt <= self.tolerance.error * qt + area * grid * grid;
        let reach = self.tolerance.reach;
        let reach_ok = xs.distance_squared(xt) <= reach * reach * area + grid * grid;
        // NaN anywhere fails both comparisons: the node is stored as elsewhere.
        error_ok && reach_ok
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A flat square cluster of side 8 in the plane z = 2 (quanta of 1 from the origin) with a
    /// plane quadric of its area, its optimal point at (4, 4, 2).
    fn flat() -> Quadric {
        let mut q = Quadric::plane(DVec3::Z, -2.0, 64.0);
        for p in [[0.0, 0.0], [8.0, 0.0], [0.0, 8.0], [8.0, 8.0]] {
            q.add_point(Vec3::new(p[0], p[1], 2.0));
        }
        q
    }

    #[test]
    fn skinned_positions_are_taken_within_the_clusters_error_only() {
        let quadrics = [flat()];
        let tolerance = SkinnedCoarse { error: 0.25, cells: 1.0, reach: 0.25, joints: 0.0 };
        let c = CoarseQuadrics { quadrics: &quadrics, first: 5, lo: DVec3::ZERO, step: 1.0, tolerance };
        let t = [4.0, 4.0, 2.0];
        // Along the plane: free up to a quarter of the cluster's size (8) and a grid step.
        assert!(c.accepts(5, t, [5, 4, 2], 0));
        assert!(c.accepts(5, t, [6, 5, 2], 0), "sqrt(5) <= sqrt(4 + 1)");
        assert!(!c.accepts(5, t, [7, 4, 2], 0), "3 > sqrt(5)");
        // Off the plane: one grid step (the cluster has no error of its own to scale).
        assert!(c.accepts(5, t, [4, 4, 3], 0));
        assert!(!c.accepts(5, t, [4, 4, 4], 0));
        assert!(c.accepts(5, t, [4, 4, 4], 1), "a grid of 2 quanta allows 2");
        // Nodes without a quadric (input vertices, out of range) are never relaxed.
        assert!(!c.accepts(4, t, [4, 4, 2], 0));
        assert!(!c.accepts(6, t, [4, 4, 2], 0));
        // A cluster with an error of its own (a second plane at z = 4) allows a quarter more.
        let mut bent = flat();
        bent += &Quadric::plane(DVec3::Z, -4.0, 64.0);
        let quadrics = [bent];
        let strict = SkinnedCoarse { error: 0.25, cells: 0.0, reach: 10.0, joints: 0.0 };
        let c = CoarseQuadrics { quadrics: &quadrics, first: 0, lo: DVec3::ZERO, step: 1.0, tolerance: strict };
        // Q at z = 3 is 128 (1 from each plane); at 3 + d it is 128 + 128 d^2: d^2 <= 0.25.
        let t = [4.0, 4.0, 3.0];
        assert!(c.accepts(0, t, [4, 4, 3], 0));
        let c = CoarseQuadrics { lo: DVec3::new(0.0, 0.0, 0.5), ..c };
        assert!(c.accepts(0, [4.0, 4.0, 2.5], [4, 4, 3], 0), "d = 0.5 is the limit");
        let c = CoarseQuadrics { lo: DVec3::new(0.0, 0.0, 0.6), ..c };
        assert!(!c.accepts(0, [4.0, 4.0, 2.4], [4, 4, 3], 0), "d = 0.6 is beyond it");
    }
}
