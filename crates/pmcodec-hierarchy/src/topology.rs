//! Connectivity of the fine mesh M0 that every frame shares: its unique edges, its vertex
//! adjacency (compressed rows) and its boundary edges. Built once per sequence.

use crate::levels::LevelAdjacency;

/// Edges and adjacency of M0.
#[derive(Clone, Debug, Default)]
pub struct FineTopology {
    /// Vertices of M0.
    pub vertex_count: u32,
    /// Unique undirected edges `(a, b)` with `a < b`, sorted.
    pub edges: Vec<[u32; 2]>,
    /// `adjacency[adj_offsets[v]..adj_offsets[v + 1]]` are v's neighbours, ascending.
    pub adj_offsets: Vec<u32>,
    /// Every vertex's neighbours, row by row (see `adj_offsets`).
    pub adjacency: Vec<u32>,
    /// Edges used by exactly one triangle, as `(v0, v1, triangle)` with v0 -> v1 in that
    /// triangle's winding.
    pub boundary: Vec<(u32, u32, u32)>,
    /// The triangles themselves (level triangle counts are read from them while building).
    pub triangles: Vec<[u32; 3]>,
}

impl FineTopology {
    /// `triangles` must index below `vertex_count` (checked by `Sequence::validate`).
    pub fn new(vertex_count: u32, triangles: &[[u32; 3]]) -> Self {
        // Every directed half-edge keyed by its undirected edge; sorting groups the copies.
        let mut half: Vec<(u64, u32, u32, u32)> = Vec::with_capacity(triangles.len() * 3);
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
                half.push((key, a, b, t as u32));
            }
        }
        half.sort_unstable_by_key(|h| h.0);
        let mut edges = Vec::with_capacity(half.len() / 2 + 1);
        let mut boundary = Vec::new();
        let mut i = 0;
        while i < half.len() {
            let mut j = i + 1;
            while j < half.len() && half[j].0 == half[i].0 {
                j += 1;
            }
            let (key, a, b, t) = half[i];
            edges.push([(key >> 32) as u32, key as u32]);
            if j - i == 1 {
                boundary.push((a, b, t));
            }
            i = j;
        }
        let LevelAdjacency { offsets: adj_offsets, adjacency } = LevelAdjacency::from_pairs(vertex_count as usize, &edges);
        FineTopology { vertex_count, edges, adj_offsets, adjacency, boundary, triangles: triangles.to_vec() }
    }

    /// The neighbours of vertex `v`, ascending.
    #[inline]
    pub fn neighbours(&self, v: u32) -> &[u32] {
        &self.adjacency[self.adj_offsets[v as usize] as usize..self.adj_offsets[v as usize + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_has_five_edges_four_on_boundary() {
        let t = FineTopology::new(4, &[[0, 1, 2], [0, 2, 3]]);
        assert_eq!(t.edges, vec![[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]);
        assert_eq!(t.boundary.len(), 4);
        assert_eq!(t.neighbours(0), &[1, 2, 3]);
        assert_eq!(t.neighbours(1), &[0, 2]);
    }
}
