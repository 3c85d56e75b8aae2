//! Greedy cuts by node error, the cuts measurement compares methods at (Kircher & Garland,
//! *Progressive Multiresolution Meshes for Deforming Surfaces*, 2005, section 5.1: a cut is
//! refined where the error is largest until the budget is met). Players and the server do not
//! use it: they read cuts off the split order ([`pmcodec_hierarchy::split_order`]).

use pmcodec_hierarchy::cut::{self, ByError, ChildIndex, Cut};
use pmcodec_hierarchy::{CutTarget, DegenerateSets, Hierarchy, NodeState};
use std::collections::BinaryHeap;

/// Chooses a cut for `target` using this frame's node errors. A [`CutTarget::MaxError`] is
/// compared with each node's error distance ([`NodeState::error_distance`]); a diagonal fraction
/// is of this frame's input vertices' bounding box.
pub fn select_cut(h: &Hierarchy, d: &DegenerateSets, children: &ChildIndex, nodes: &NodeState, target: CutTarget) -> Cut {
    let mut cut = cut::coarsest(h, d);
    let top = h.top();
    let n0 = h.level_sizes[0];
    match target {
        CutTarget::Level(level) => {
            let level = level.min(top);
            for g in h.offsets[level + 1]..h.offsets[top + 1] {
                cut.expanded[g as usize] = true;
                cut.triangles += d.size(g);
            }
            cut.vertices = h.level_sizes[level];
        }
        CutTarget::MaxError(distance) => {
            let fine = nodes.positions.get(..n0 as usize).and_then(pmcodec_mesh::bounds_of);
            let tol = distance.in_model_units(fine.map_or(0.0, |(lo, hi)| (hi - lo).length() as f64));
            let mut stack: Vec<u32> = (h.offsets[top]..h.offsets[top + 1]).collect();
            while let Some(g) = stack.pop() {
                if g >= n0 && nodes.error_distance(g) > tol {
                    cut::expand(&mut cut, d, children, g);
                    stack.extend_from_slice(children.of(g));
                }
            }
        }
        CutTarget::Triangles(budget) => greedy(&mut cut, h, d, children, nodes, |c, g| c.triangles + d.size(g) <= budget),
        CutTarget::Vertices(budget) => {
            greedy(&mut cut, h, d, children, nodes, |c, g| c.vertices + children.of(g).len() as u32 - 1 <= budget)
        }
    }
    cut
}

/// Expands the highest-error cut node that still fits, until none does.
fn greedy(cut: &mut Cut, h: &Hierarchy, d: &DegenerateSets, children: &ChildIndex, nodes: &NodeState, fits: impl Fn(&Cut, u32) -> bool) {
    let top = h.top();
    let n0 = h.level_sizes[0];
    let mut heap: BinaryHeap<ByError> =
        (h.offsets[top]..h.offsets[top + 1]).filter(|&g| g >= n0).map(|g| ByError(nodes.error(g), g)).collect();
    while let Some(ByError(_, g)) = heap.pop() {
        if !fits(cut, g) {
            continue;
        }
        cut::expand(cut, d, children, g);
        for &c in children.of(g) {
            if c >= n0 {
                heap.push(ByError(nodes.error(c), c));
            }
        }
    }
}
