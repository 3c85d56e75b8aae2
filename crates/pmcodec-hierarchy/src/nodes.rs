//! Per-frame node state: every node's quadric (the sum over its cluster, section 3), its
//! optimal position and its error, for one frame's fine positions.

use crate::Hierarchy;
use crate::quadric::Quadric;
use glam::Vec3;

/// Quadrics, positions and errors of all nodes (indexed by global id) for one frame.
#[derive(Clone, Debug, Default)]
pub struct NodeState {
    /// Every node's quadric: the sum of its cluster's fine quadrics.
    pub quadrics: Vec<Quadric>,
    /// Every node's position: the input's at level 0, the quadric-optimal one above.
    pub positions: Vec<Vec3>,
}

impl NodeState {
    /// Sums fine quadrics up the hierarchy and solves every coarse node's position. Level-0
    /// nodes sit at their own input positions.
    pub fn compute(h: &Hierarchy, fine_quadrics: &[Quadric], fine_positions: &[Vec3]) -> Self {
        let mut s = NodeState::default();
        s.recompute(h, fine_quadrics, fine_positions);
        s
    }

    /// As [`NodeState::compute`], reusing this state's allocations.
    pub fn recompute(&mut self, h: &Hierarchy, fine_quadrics: &[Quadric], fine_positions: &[Vec3]) {
        let total = h.node_count();
        self.quadrics.clear();
        self.quadrics.resize(total, Quadric::default());
        self.positions.clear();
        self.positions.resize(total, Vec3::ZERO);
        let n0 = h.level_sizes[0] as usize;
        self.quadrics[..n0].copy_from_slice(fine_quadrics);
        self.positions[..n0].copy_from_slice(fine_positions);
        for k in 0..h.levels() - 1 {
            let (lo, hi) = (h.offsets[k] as usize, h.offsets[k + 1] as usize);
            let (below, above) = self.quadrics.split_at_mut(hi);
            for (v, &p) in h.parent[k].iter().enumerate() {
                above[p as usize] += &below[lo + v];
            }
        }
        for g in n0..total {
            self.positions[g] = self.quadrics[g].optimal().as_vec3();
        }
    }

    /// Re-solves one node's position from its quadric.
    #[inline]
    pub fn resolve(&mut self, g: u32) {
        self.positions[g as usize] = self.quadrics[g as usize].optimal().as_vec3();
    }

    /// Quadric error E_a = Q_a(x_a) of a node (section 3).
    #[inline]
    pub fn error(&self, g: u32) -> f64 {
        self.quadrics[g as usize].eval_f32(self.positions[g as usize]).max(0.0)
    }

    /// Per level, the root of the area-weighted mean squared distance from the level's
    /// clusters' faces to their nodes: sqrt(sum E_a / sum area_a) over the level's nodes (0 at
    /// level 0, whose nodes are the input). A level's own simplification error as one length,
    /// e.g. for choosing how coarse a grid its positions can be stored on without it showing.
    pub fn level_rms_errors(&self, h: &Hierarchy) -> Vec<f64> {
        (0..h.levels())
            .map(|k| {
                let (mut e, mut area) = (0.0, 0.0);
                for g in h.offsets[k]..h.offsets[k + 1] {
                    e += self.error(g);
                    area += self.quadrics[g as usize].area;
                }
                if k > 0 && area > 0.0 { (e / area).sqrt() } else { 0.0 }
            })
            .collect()
    }

    /// Error as a distance: the root of the area-weighted mean squared distance from the
    /// cluster's faces to the node, sqrt(E_a / area_a). Comparable across nodes and to a
    /// length tolerance.
    #[inline]
    pub fn error_distance(&self, g: u32) -> f64 {
        let q = &self.quadrics[g as usize];
        if q.area > 0.0 { (self.error(g) / q.area).sqrt() } else { 0.0 }
    }
}
