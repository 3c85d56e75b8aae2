//! Cuts through the hierarchy and the triangle meshes they show.
//!
//! A cut is stored as the set of *expanded* nodes: nodes whose children are shown instead of
//! themselves. It is closed upward (a node's parent is expanded whenever it is), and the cut
//! nodes are the unexpanded nodes whose parent is expanded, plus the unexpanded top-level
//! nodes. By the degenerate-set rule (see [`crate::DegenerateSets`]) the shown triangles are the
//! never-degenerating ones plus D_a of every expanded node a.

use crate::Hierarchy;
use crate::degenerate::DegenerateSets;
use crate::hierarchy::NONE;
use crate::rows::compressed_rows;
use glam::Vec3;
use pmcodec_mesh::TriMesh;
use std::cmp::Ordering;

/// A cut: the expanded flags of all nodes (global ids) and the counts they give.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Cut {
    /// Whether each node (global id) is expanded: its children are shown instead of it.
    pub expanded: Vec<bool>,
    /// Triangles the cut shows.
    pub triangles: u32,
    /// Cut nodes, the vertices of the mesh the cut shows.
    pub vertices: u32,
}

/// Children of every node (global ids) in compressed rows.
#[derive(Clone, Debug, Default)]
pub struct ChildIndex {
    /// `children[offsets[g]..offsets[g + 1]]` are node `g`'s children.
    pub offsets: Vec<u32>,
    /// Every node's children (global ids), row by row.
    pub children: Vec<u32>,
}

impl ChildIndex {
    /// The children of every node of `h`.
    pub fn new(h: &Hierarchy) -> Self {
        // Every node below the top, as (global parent, global child).
        let edges = || {
            (0..h.levels().saturating_sub(1))
                .flat_map(move |k| h.parent[k].iter().enumerate().map(move |(v, &p)| (h.offsets[k + 1] + p, h.offsets[k] + v as u32)))
        };
        let (offsets, children) = compressed_rows(h.node_count(), edges);
        ChildIndex { offsets, children }
    }

    /// The children of node `g` (global ids).
    #[inline]
    pub fn of(&self, g: u32) -> &[u32] {
        &self.children[self.offsets[g as usize] as usize..self.offsets[g as usize + 1] as usize]
    }
}

/// A heap item ordered by error, ties to the smaller node id (so cuts are deterministic).
#[derive(PartialEq, Clone, Copy, Debug)]
pub struct ByError(pub f64, pub u32);
impl Eq for ByError {}
impl PartialOrd for ByError {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for ByError {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0).then_with(|| o.1.cmp(&self.1))
    }
}

/// The coarsest cut: nothing expanded.
pub fn coarsest(h: &Hierarchy, d: &DegenerateSets) -> Cut {
    Cut { expanded: vec![false; h.node_count()], triangles: d.never.len() as u32, vertices: h.level_sizes[h.top()] }
}

/// Expands cut node `g`, keeping the cut's counts.
#[inline]
pub fn expand(cut: &mut Cut, d: &DegenerateSets, children: &ChildIndex, g: u32) {
    cut.expanded[g as usize] = true;
    cut.triangles += d.size(g);
    cut.vertices += children.of(g).len() as u32 - 1;
}

/// For every node, the cut node that stands for it (itself, or its cut ancestor), or [`NONE`]
/// for expanded nodes.
pub fn cut_nodes(h: &Hierarchy, cut: &Cut) -> Vec<u32> {
    cut_nodes_from(h, &cut.expanded, 0)
}

/// [`cut_nodes`] from expanded flags, for the nodes at `min_level` and above (others NONE).
pub fn cut_nodes_from(h: &Hierarchy, expanded: &[bool], min_level: usize) -> Vec<u32> {
    let mut rep = vec![NONE; h.node_count()];
    for k in (min_level..h.levels()).rev() {
        for v in 0..h.level_sizes[k] {
            let g = h.offsets[k] + v;
            let above = if k == h.top() { NONE } else { rep[(h.offsets[k + 1] + h.parent[k][v as usize]) as usize] };
            rep[g as usize] = if above != NONE {
                above
            } else if expanded[g as usize] {
                NONE
            } else {
                g
            };
        }
    }
    rep
}

/// Fine triangles a cut shows, ascending.
pub fn shown_triangles(d: &DegenerateSets, cut: &Cut) -> Vec<u32> {
    let mut out: Vec<u32> =
        d.node_of.iter().enumerate().filter(|&(_, &g)| g == NONE || cut.expanded[g as usize]).map(|(t, _)| t as u32).collect();
    out.sort_unstable();
    out
}

/// The indexed triangle mesh a cut shows, with node positions from `positions` (global ids).
/// Also returns, for each output vertex, the global id of its node.
pub fn extract(h: &Hierarchy, d: &DegenerateSets, fine_triangles: &[[u32; 3]], cut: &Cut, positions: &[Vec3]) -> (TriMesh, Vec<u32>) {
    let rep = cut_nodes(h, cut);
    let mut index_of = vec![NONE; h.node_count()];
    let mut nodes = Vec::new();
    let mut mesh = TriMesh::default();
    for (t, &g) in d.node_of.iter().enumerate() {
        if g != NONE && !cut.expanded[g as usize] {
            continue;
        }
        let tri = fine_triangles[t].map(|v| {
            let c = rep[v as usize];
            if index_of[c as usize] == NONE {
                index_of[c as usize] = nodes.len() as u32;
                nodes.push(c);
                mesh.positions.push(positions[c as usize]);
            }
            index_of[c as usize]
        });
        mesh.triangles.push(tri);
    }
    (mesh, nodes)
}
