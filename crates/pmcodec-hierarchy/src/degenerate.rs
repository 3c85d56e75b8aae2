//! Degenerate sets (Kircher & Garland section 5.1; DESIGN.md point 4).
//!
//! A fine triangle degenerates at the lowest level j where the ancestors of its three corners
//! are no longer distinct; it then belongs to D_a of the level-j node a into which two (or all)
//! of its corners merged. The pair of corners that merge first is unique: if two pairs merged at
//! once, all three did. For a cut, triangle t is shown iff its degeneration node is expanded
//! (lies strictly above the cut); a triangle that never degenerates is always shown. So
//! expanding cut node a adds exactly |D_a| triangles.

use crate::Hierarchy;
use crate::hierarchy::NONE;
use crate::rows::compressed_rows;

/// Degeneration node of every fine triangle, and the sets D_a grouped by node.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DegenerateSets {
    /// Global id of the node each fine triangle degenerates at, or [`NONE`].
    pub node_of: Vec<u32>,
    /// `triangles[offsets[g]..offsets[g + 1]]` is D_g (ascending triangle ids).
    pub offsets: Vec<u32>,
    /// Every set's triangles, row by row (see `offsets`).
    pub triangles: Vec<u32>,
    /// Triangles that never degenerate (shown by every cut).
    pub never: Vec<u32>,
}

/// Degeneration node of one triangle, walking up the parent maps.
#[inline]
pub fn degeneration_node(h: &Hierarchy, tri: [u32; 3]) -> u32 {
    let [mut x, mut y, mut z] = tri;
    for k in 0..h.levels() - 1 {
        let p = &h.parent[k];
        x = p[x as usize];
        y = p[y as usize];
        z = p[z as usize];
        if x == y || x == z {
            return h.offsets[k + 1] + x;
        }
        if y == z {
            return h.offsets[k + 1] + y;
        }
    }
    NONE
}

/// Degeneration nodes of all triangles into `out`.
pub fn degeneration_nodes(h: &Hierarchy, triangles: &[[u32; 3]], out: &mut Vec<u32>) {
    out.clear();
    out.extend(triangles.iter().map(|&t| degeneration_node(h, t)));
}

impl DegenerateSets {
    /// The degenerate sets of `triangles` (the fine mesh's) in `h`.
    pub fn new(h: &Hierarchy, triangles: &[[u32; 3]]) -> Self {
        let mut node_of = Vec::new();
        degeneration_nodes(h, triangles, &mut node_of);
        Self::from_nodes(h.node_count(), node_of)
    }

    /// Groups per-triangle degeneration nodes into sets.
    pub fn from_nodes(node_count: usize, node_of: Vec<u32>) -> Self {
        let never: Vec<u32> = (0..node_of.len() as u32).filter(|&t| node_of[t as usize] == NONE).collect();
        let (offsets, triangles) =
            compressed_rows(node_count, || node_of.iter().enumerate().filter(|(_, g)| **g != NONE).map(|(t, &g)| (g, t as u32)));
        DegenerateSets { node_of, offsets, triangles, never }
    }

    /// D_g.
    #[inline]
    pub fn set(&self, g: u32) -> &[u32] {
        &self.triangles[self.offsets[g as usize] as usize..self.offsets[g as usize + 1] as usize]
    }

    /// |D_g|: the triangles expanding node `g` shows.
    #[inline]
    pub fn size(&self, g: u32) -> u32 {
        self.offsets[g as usize + 1] - self.offsets[g as usize]
    }
}
