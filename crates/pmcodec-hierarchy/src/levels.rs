//! Per-level connectivity of the multilevel mesh (section 3): level k's mesh edges are the fine
//! edges whose ends have distinct level-k ancestors. Derived bottom-up, level k from level
//! k-1 through the parent map, as the paper constructs each level's connectivity.

use crate::Hierarchy;
use crate::rows::compressed_rows_into;
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
        let mut out = LevelAdjacency::default();
        out.fill_from_pairs(n, pairs, &mut Vec::new());
        out
    }

    /// [`LevelAdjacency::from_pairs`] into this adjacency's allocations (`fill` is scratch):
    /// reclustering rebuilds every level's rows each frame.
    pub fn fill_from_pairs(&mut self, n: usize, pairs: &[[u32; 2]], fill: &mut Vec<u32>) {
        let (offsets, adjacency) = (&mut self.offsets, &mut self.adjacency);
        compressed_rows_into(n, || pairs.iter().flat_map(|p| [(p[0], p[1]), (p[1], p[0])]), offsets, adjacency, fill);
        for v in 0..n {
            adjacency[offsets[v] as usize..offsets[v + 1] as usize].sort_unstable();
        }
    }

    /// Unique pairs `(a, b)`, a < b, of this adjacency.
    pub fn pairs(&self) -> impl Iterator<Item = [u32; 2]> + '_ {
        (0..self.offsets.len().saturating_sub(1) as u32)
            .flat_map(move |v| self.row(v).iter().filter(move |&&w| w > v).map(move |&w| [v, w]))
    }
}

/// What [`level_adjacency_with`] sorts and fills through, kept between frames.
#[derive(Debug, Default)]
pub struct LevelScratch {
    keys: Vec<u64>,
    pairs: Vec<[u32; 2]>,
    fill: Vec<u32>,
}

/// Adjacency of every level of `h`, built bottom-up, into `out`'s allocations, with the scratch
/// kept by the caller: no allocation once every level has been as large as it gets
/// (reclustering calls this every frame).
pub fn level_adjacency_with(h: &Hierarchy, topo: &FineTopology, out: &mut Vec<LevelAdjacency>, s: &mut LevelScratch) {
    out.resize_with(h.levels(), LevelAdjacency::default);
    out[0].offsets.clone_from(&topo.adj_offsets);
    out[0].adjacency.clone_from(&topo.adjacency);
    for k in 0..h.levels() - 1 {
        let parent = &h.parent[k];
        s.keys.clear();
        for [a, b] in out[k].pairs() {
            let (pa, pb) = (parent[a as usize], parent[b as usize]);
            if pa != pb {
                s.keys.push(((pa.min(pb) as u64) << 32) | pa.max(pb) as u64);
            }
        }
        s.keys.sort_unstable();
        s.keys.dedup();
        s.pairs.clear();
        s.pairs.extend(s.keys.iter().map(|&k| [(k >> 32) as u32, k as u32]));
        out[k + 1].fill_from_pairs(h.level_sizes[k + 1] as usize, &s.pairs, &mut s.fill);
    }
}
