//! Per-level connectivity of the multilevel mesh (section 3): level k's mesh edges are the fine
//! edges whose ends have distinct level-k ancestors. Derived bottom-up, level k from level
//! k-1 through the parent map, as the paper constructs each level's connectivity.

use crate::Hierarchy;
use crate::rows::compressed_rows;
use crate::topology::FineTopology;

/// Vertex adjacency of one level in compressed rows (rows sorted ascending).
#[derive(Clone, Debug, Default)]
pub struct LevelAdjacency {
    /// `adjacency[offsets[v]..offsets[v + 1]]` are vertex `v`'s neighbours.
    pub offsets: Vec<u32>,
    /// Every vertex's neighbours (level-local ids), row by row, ascending.
    pub adjacency: Vec<u32>,
}

impl LevelAdjacency {
    /// The neighbours of vertex `v`, ascending.
    #[inline]
    pub fn row(&self, v: u32) -> &[u32] {
        &self.adjacency[self.offsets[v as usize] as usize..self.offsets[v as usize + 1] as usize]
    }

    /// Whether `u` and `w` share an edge at this level.
    #[inline]
    pub fn adjacent(&self, u: u32, w: u32) -> bool {
        self.row(u).binary_search(&w).is_ok()
    }

    /// Rows from unique undirected pairs `(a, b)`, a < b.
    pub fn from_pairs(n: usize, pairs: &[[u32; 2]]) -> Self {
        let (offsets, mut adjacency) = compressed_rows(n, || pairs.iter().flat_map(|p| [(p[0], p[1]), (p[1], p[0])]));
        for v in 0..n {
            adjacency[offsets[v] as usize..offsets[v + 1] as usize].sort_unstable();
        }
        LevelAdjacency { offsets, adjacency }
    }

    /// Unique pairs `(a, b)`, a < b, of this adjacency.
    pub fn pairs(&self) -> impl Iterator<Item = [u32; 2]> + '_ {
        (0..self.offsets.len().saturating_sub(1) as u32)
            .flat_map(move |v| self.row(v).iter().filter(move |&&w| w > v).map(move |&w| [v, w]))
    }
}

/// Adjacency of every level of `h`, built bottom-up.
pub fn level_adjacency(h: &Hierarchy, topo: &FineTopology, out: &mut Vec<LevelAdjacency>) {
    out.clear();
    out.push(LevelAdjacency { offsets: topo.adj_offsets.clone(), adjacency: topo.adjacency.clone() });
    let mut keys: Vec<u64> = Vec::new();
    let mut pairs: Vec<[u32; 2]> = Vec::new();
    for k in 0..h.levels() - 1 {
        let parent = &h.parent[k];
        keys.clear();
        for [a, b] in out[k].pairs() {
            let (pa, pb) = (parent[a as usize], parent[b as usize]);
            if pa != pb {
                keys.push(((pa.min(pb) as u64) << 32) | pa.max(pb) as u64);
            }
        }
        keys.sort_unstable();
        keys.dedup();
        pairs.clear();
        pairs.extend(keys.iter().map(|&k| [(k >> 32) as u32, k as u32]));
        let next = LevelAdjacency::from_pairs(h.level_sizes[k + 1] as usize, &pairs);
        out.push(next);
    }
}
