//! Cuts carried from frame to frame: a cut made for one frame's hierarchy is repaired after
//! reclustering and brought back to its budget with as few changes as possible, as a player
//! at a fixed budget does, so that the coherence measured in [`crate::changed_share`] is what
//! a viewer would see.

use pmcodec_hierarchy::CutTarget;
use pmcodec_hierarchy::cut::{self, ByError, ChildIndex, Cut};
use pmcodec_hierarchy::{DegenerateSets, Hierarchy, NONE, NodeState};
use std::collections::BinaryHeap;

/// Makes `cut` closed upward again after the hierarchy changed under it (a swap can hang an
/// expanded node under an unexpanded one): such nodes are collapsed with their subtrees (which
/// never raises the triangle count; expanding the new parent instead changed about twice as
/// many shown triangles per frame on the horse gallop). Then recounts triangles and vertices.
pub fn repair(h: &Hierarchy, d: &DegenerateSets, children: &ChildIndex, cut: &mut Cut) {
    // Coarse to fine: an expanded node under an unexpanded parent either pulls its unexpanded
    // ancestors open or is collapsed with its subtree, whichever changes fewer triangles.
    let mut stack = Vec::new();
    for k in (0..h.top()).rev() {
        for v in 0..h.level_sizes[k] {
            let g = h.offsets[k] + v;
            let p = h.offsets[k + 1] + h.parent[k][v as usize];
            if !cut.expanded[g as usize] || cut.expanded[p as usize] {
                continue;
            }
            let mut open_cost = 0;
            let mut x = p;
            while x != NONE && !cut.expanded[x as usize] {
                open_cost += d.size(x);
                x = h.parent_global(x);
            }
            let mut collapse_cost = 0;
            stack.clear();
            stack.push(g);
            while let Some(y) = stack.pop() {
                if cut.expanded[y as usize] {
                    collapse_cost += d.size(y);
                    stack.extend_from_slice(children.of(y));
                }
            }
            if open_cost < collapse_cost {
                let mut x = p;
                while x != NONE && !cut.expanded[x as usize] {
                    cut.expanded[x as usize] = true;
                    x = h.parent_global(x);
                }
            } else {
                stack.clear();
                stack.push(g);
                while let Some(y) = stack.pop() {
                    if cut.expanded[y as usize] {
                        cut.expanded[y as usize] = false;
                        stack.extend_from_slice(children.of(y));
                    }
                }
            }
        }
    }
    cut.triangles = d.never.len() as u32;
    cut.vertices = h.level_sizes[h.top()];
    for g in 0..h.node_count() as u32 {
        if cut.expanded[g as usize] {
            cut.triangles += d.size(g);
            cut.vertices += children.of(g).len() as u32 - 1;
        }
    }
}

/// Brings an existing cut to a triangle or vertex budget with as few changes as it can, so
/// that playback at a fixed budget stays temporally coherent: while over budget, the expanded
/// node of least error whose children are all unexpanded is collapsed; then, like [`cut::select`],
/// the cut node of greatest error that still fits is expanded until none fits. Other targets
/// fall back to [`cut::select`].
pub fn rebalance(h: &Hierarchy, d: &DegenerateSets, children: &ChildIndex, nodes: &NodeState, cut: &mut Cut, target: CutTarget) {
    repair(h, d, children, cut);
    let cost = |g: u32| -> u32 {
        match target {
            CutTarget::Triangles(_) => d.size(g),
            _ => children.of(g).len() as u32 - 1,
        }
    };
    let (budget, used): (u32, fn(&Cut) -> u32) = match target {
        CutTarget::Triangles(n) => (n, |c| c.triangles),
        CutTarget::Vertices(n) => (n, |c| c.vertices),
        _ => {
            *cut = crate::select_cut(h, d, children, nodes, target);
            return;
        }
    };
    let n0 = h.level_sizes[0];
    let is_leaf = |cut: &Cut, g: u32| cut.expanded[g as usize] && children.of(g).iter().all(|&c| !cut.expanded[c as usize]);
    if used(cut) > budget {
        // Least error first (BinaryHeap is a max-heap: negate).
        let mut heap: BinaryHeap<ByError> =
            (n0..h.node_count() as u32).filter(|&g| is_leaf(cut, g)).map(|g| ByError(-nodes.error(g), g)).collect();
        while used(cut) > budget {
            let Some(ByError(_, g)) = heap.pop() else { break };
            if !is_leaf(cut, g) {
                continue;
            }
            cut.expanded[g as usize] = false;
            cut.triangles -= d.size(g);
            cut.vertices -= children.of(g).len() as u32 - 1;
            let p = h.parent_global(g);
            if p != NONE && is_leaf(cut, p) {
                heap.push(ByError(-nodes.error(p), p));
            }
        }
    }
    // Expand: the cut nodes (unexpanded, parent expanded or top) by decreasing error.
    let mut heap: BinaryHeap<ByError> = (n0..h.node_count() as u32)
        .filter(|&g| {
            let p = h.parent_global(g);
            !cut.expanded[g as usize] && (p == NONE || cut.expanded[p as usize])
        })
        .map(|g| ByError(nodes.error(g), g))
        .collect();
    while let Some(ByError(_, g)) = heap.pop() {
        if used(cut) + cost(g) > budget {
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
