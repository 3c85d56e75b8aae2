//! The progressive representation (section 5): the base hierarchy, then per frame the swaps and
//! degenerate-set deltas that turn H_{f-1} into H_f. [`Encoder`] produces it; [`Replay`]
//! plays it back and keeps a cut's shown triangles up to date from the deltas alone (section
//! 5.1), without re-deriving them.
//!
//! Convention: frame 0 has a delta too (reclustering the built base to fit frame 0), so the
//! hierarchy of frame f is always the base plus the deltas of frames 0..=f.

use crate::Hierarchy;
use crate::degenerate::degeneration_nodes;
use crate::hierarchy::NONE;
use crate::recluster::{FrameStats, ReclusterOptions, Reclusterer, Swap};
use crate::topology::FineTopology;
use glam::Vec3;

/// What turns H_{f-1} into H_f.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameDelta {
    /// Swaps in the order they were made (coarse levels first).
    pub swaps: Vec<Swap>,
    /// `(triangle, node)`: the triangle's degeneration node in H_f (global id, or [`NONE`]),
    /// for every triangle whose node changed, ascending by triangle.
    pub degenerate: Vec<(u32, u32)>,
}

/// Produces frame deltas by reclustering.
pub struct Encoder {
    pub recluster: Reclusterer,
    node_of: Vec<u32>,
    scratch: Vec<u32>,
}

impl Encoder {
    pub fn new(base: Hierarchy, topo: FineTopology, triangles: Vec<[u32; 3]>, opts: ReclusterOptions) -> Self {
        let mut node_of = Vec::new();
        degeneration_nodes(&base, &triangles, &mut node_of);
        Encoder { recluster: Reclusterer::new(base, topo, triangles, opts), node_of, scratch: Vec::new() }
    }

    /// The current hierarchy H_f.
    pub fn hierarchy(&self) -> &Hierarchy {
        &self.recluster.h
    }

    /// Degeneration node of every triangle in H_f.
    pub fn degeneration(&self) -> &[u32] {
        &self.node_of
    }

    /// Reclusters for the next frame and returns its delta.
    pub fn encode_frame(&mut self, positions: &[Vec3]) -> (FrameDelta, FrameStats) {
        let mut delta = FrameDelta::default();
        let stats = self.recluster.frame(positions, &mut delta.swaps);
        degeneration_nodes(&self.recluster.h, self.recluster.triangles(), &mut self.scratch);
        for (t, (old, new)) in self.node_of.iter_mut().zip(&self.scratch).enumerate() {
            if old != new {
                delta.degenerate.push((t as u32, *new));
                *old = *new;
            }
        }
        (delta, stats)
    }
}

/// A delta that does not fit the hierarchy it is applied to.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum DeltaError {
    #[error("swap {index}: level {level} has no node {v} or no cluster {to} above it")]
    SwapOutOfRange { index: usize, level: u32, v: u32, to: u32 },
    #[error("swap {index}: node {v} of level {level} is in cluster {actual}, not {from}")]
    SwapMismatch { index: usize, level: u32, v: u32, from: u32, actual: u32 },
    #[error("swap {index}: cluster {from} of level {} would be left empty", level + 1)]
    EmptyCluster { index: usize, level: u32, from: u32 },
    #[error("degenerate-set delta {index}: triangle {triangle} or node {node} out of range")]
    DegenerateOutOfRange { index: usize, triangle: u32, node: u32 },
}

/// Plays back a progressive representation and maintains one cut through it.
///
/// The cut is the set of expanded nodes, closed upward. The shown triangles are kept as a dense
/// list (ready to become an index buffer) with each triangle's slot, so showing and hiding are
/// O(1). A degenerate-set delta `(t, node)` shows or hides t according to whether its new node
/// is expanded; a swap that hangs an expanded node under an unexpanded one collapses that node's
/// subtree so the cut stays closed (section 5.1 leaves the policy open; collapsing never raises
/// the triangle count).
#[derive(Clone, Debug)]
pub struct Replay {
    pub h: Hierarchy,
    node_of: Vec<u32>,
    /// D sets per node (global id), unordered, and each triangle's slot in its set.
    sets: Vec<Vec<u32>>,
    slot_in_set: Vec<u32>,
    children: Vec<Vec<u32>>,
    expanded: Vec<bool>,
    shown: Vec<u32>,
    slot_in_shown: Vec<u32>,
}

impl Replay {
    /// Starts at the base hierarchy with the coarsest cut.
    pub fn new(base: Hierarchy, triangles: &[[u32; 3]]) -> Self {
        let mut node_of = Vec::new();
        degeneration_nodes(&base, triangles, &mut node_of);
        let total = base.node_count();
        let mut sets = vec![Vec::new(); total];
        let mut slot_in_set = vec![NONE; triangles.len()];
        for (t, &g) in node_of.iter().enumerate() {
            if g != NONE {
                slot_in_set[t] = sets[g as usize].len() as u32;
                sets[g as usize].push(t as u32);
            }
        }
        let mut children = vec![Vec::new(); total];
        for k in 0..base.levels() - 1 {
            for (v, &p) in base.parent[k].iter().enumerate() {
                children[(base.offsets[k + 1] + p) as usize].push(base.offsets[k] + v as u32);
            }
        }
        let mut r = Replay {
            h: base,
            node_of,
            sets,
            slot_in_set,
            children,
            expanded: vec![false; total],
            shown: Vec::new(),
            slot_in_shown: vec![NONE; triangles.len()],
        };
        for t in 0..triangles.len() {
            if r.node_of[t] == NONE {
                r.show(t as u32);
            }
        }
        r
    }

    /// Degeneration node of every triangle in the current hierarchy.
    pub fn degeneration(&self) -> &[u32] {
        &self.node_of
    }

    /// The shown fine triangles (unordered).
    pub fn shown(&self) -> &[u32] {
        &self.shown
    }

    pub fn expanded(&self) -> &[bool] {
        &self.expanded
    }

    pub fn degenerate_set(&self, g: u32) -> &[u32] {
        &self.sets[g as usize]
    }

    pub fn children_of(&self, g: u32) -> &[u32] {
        &self.children[g as usize]
    }

    #[inline]
    fn show(&mut self, t: u32) {
        if self.slot_in_shown[t as usize] == NONE {
            self.slot_in_shown[t as usize] = self.shown.len() as u32;
            self.shown.push(t);
        }
    }

    #[inline]
    fn hide(&mut self, t: u32) {
        let slot = self.slot_in_shown[t as usize];
        if slot != NONE {
            self.shown.swap_remove(slot as usize);
            if let Some(&moved) = self.shown.get(slot as usize) {
                self.slot_in_shown[moved as usize] = slot;
            }
            self.slot_in_shown[t as usize] = NONE;
        }
    }

    /// Expands node g (and, to keep the cut closed, its unexpanded ancestors).
    pub fn expand(&mut self, g: u32) {
        let mut x = g;
        while x != NONE && !self.expanded[x as usize] && x >= self.h.level_sizes[0] {
            self.expanded[x as usize] = true;
            for i in 0..self.sets[x as usize].len() {
                let t = self.sets[x as usize][i];
                self.show(t);
            }
            x = self.h.parent_global(x);
        }
    }

    /// Collapses node g and every expanded node below it.
    pub fn collapse(&mut self, g: u32) {
        let mut stack = vec![g];
        while let Some(x) = stack.pop() {
            if !self.expanded[x as usize] {
                continue;
            }
            self.expanded[x as usize] = false;
            for i in 0..self.sets[x as usize].len() {
                let t = self.sets[x as usize][i];
                self.hide(t);
            }
            stack.extend_from_slice(&self.children[x as usize]);
        }
    }

    /// Replaces the cut by `expanded` (must be closed upward).
    pub fn set_cut(&mut self, expanded: &[bool]) {
        for g in 0..self.expanded.len().min(expanded.len()) {
            if self.expanded[g] != expanded[g] {
                self.expanded[g] = expanded[g];
                for i in 0..self.sets[g].len() {
                    let t = self.sets[g][i];
                    if expanded[g] { self.show(t) } else { self.hide(t) }
                }
            }
        }
    }

    /// Applies one frame's delta, updating the hierarchy, the degenerate sets and the shown
    /// triangles. On error nothing after the failing element is applied; the replay should then
    /// be discarded (the stream is corrupt).
    pub fn apply(&mut self, delta: &FrameDelta) -> Result<(), DeltaError> {
        let levels = self.h.levels();
        for (index, s) in delta.swaps.iter().enumerate() {
            let k = s.level as usize;
            if k + 1 >= levels
                || s.v >= self.h.level_sizes[k]
                || s.to >= self.h.level_sizes[k + 1]
                || s.from >= self.h.level_sizes[k + 1]
            {
                return Err(DeltaError::SwapOutOfRange { index, level: s.level, v: s.v, to: s.to });
            }
            let actual = self.h.parent[k][s.v as usize];
            if actual != s.from {
                return Err(DeltaError::SwapMismatch { index, level: s.level, v: s.v, from: s.from, actual });
            }
            let (gv, ga, gb) = (self.h.offsets[k] + s.v, self.h.offsets[k + 1] + s.from, self.h.offsets[k + 1] + s.to);
            if self.children[ga as usize].len() <= 1 && ga != gb {
                return Err(DeltaError::EmptyCluster { index, level: s.level, from: s.from });
            }
            self.h.parent[k][s.v as usize] = s.to;
            if let Some(i) = self.children[ga as usize].iter().position(|&c| c == gv) {
                self.children[ga as usize].swap_remove(i);
            }
            self.children[gb as usize].push(gv);
            if self.expanded[gv as usize] && !self.expanded[gb as usize] {
                self.collapse(gv);
            }
        }
        let total = self.expanded.len() as u32;
        for (index, &(t, g)) in delta.degenerate.iter().enumerate() {
            if t as usize >= self.node_of.len() || (g != NONE && g >= total) {
                return Err(DeltaError::DegenerateOutOfRange { index, triangle: t, node: g });
            }
            let old = self.node_of[t as usize];
            if old == g {
                continue;
            }
            if old != NONE {
                let set = &mut self.sets[old as usize];
                let slot = self.slot_in_set[t as usize] as usize;
                set.swap_remove(slot);
                if let Some(&moved) = set.get(slot) {
                    self.slot_in_set[moved as usize] = slot as u32;
                }
            }
            if g != NONE {
                self.slot_in_set[t as usize] = self.sets[g as usize].len() as u32;
                self.sets[g as usize].push(t);
            } else {
                self.slot_in_set[t as usize] = NONE;
            }
            self.node_of[t as usize] = g;
            if g == NONE || self.expanded[g as usize] { self.show(t) } else { self.hide(t) }
        }
        Ok(())
    }
}
