//! The multilevel mesh of Kircher & Garland section 3, stored as flat parent maps.
//!
//! Level 0 is the input mesh M0 (node `v` of level 0 is input vertex `v`); level k+1's nodes are
//! the contraction clusters of level k. A node is named by `(level, index)` or by a *global id*
//! `offsets[level] + index`, which flat per-node arrays (quadrics, positions, degenerate sets,
//! cut flags) are indexed by. Node counts per level never change after the build: swaps move
//! children between clusters but never empty one (section 7: clusters do not evaporate).

use crate::rows::compressed_rows;
use crate::topology::FineTopology;

/// The multilevel hierarchy: the parent maps between consecutive levels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Hierarchy {
    /// Branching factor the levels were sized with.
    pub branching: u32,
    /// `level_sizes[k]` = |M_k|.
    pub level_sizes: Vec<u32>,
    /// Global id of node 0 of each level, plus the total node count at the end.
    pub offsets: Vec<u32>,
    /// `parent[k][v]` is the level-(k+1) parent of level-k node v, for k < levels - 1.
    pub parent: Vec<Vec<u32>>,
}

/// Sentinel for "no node".
pub const NONE: u32 = u32::MAX;

impl Hierarchy {
    /// Assembles a hierarchy from its parent maps (level 0 has `fine_count` nodes).
    pub fn from_parents(branching: u32, fine_count: u32, parent: Vec<Vec<u32>>) -> Self {
        let mut level_sizes = vec![fine_count];
        for p in &parent {
            let next = p.iter().copied().max().map_or(0, |m| m + 1);
            level_sizes.push(next);
        }
        let mut offsets = vec![0u32];
        for s in &level_sizes {
            offsets.push(offsets.last().copied().unwrap_or(0) + s);
        }
        Hierarchy { branching, level_sizes, offsets, parent }
    }

    /// Number of levels including M0.
    #[inline]
    pub fn levels(&self) -> usize {
        self.level_sizes.len()
    }

    /// Index of the coarsest level.
    #[inline]
    pub fn top(&self) -> usize {
        self.level_sizes.len() - 1
    }

    /// Total number of nodes over all levels.
    #[inline]
    pub fn node_count(&self) -> usize {
        *self.offsets.last().unwrap_or(&0) as usize
    }

    /// Global id of node `v` of level `level`.
    #[inline]
    pub fn global(&self, level: usize, v: u32) -> u32 {
        self.offsets[level] + v
    }

    /// `(level, index)` of a global id.
    #[inline]
    pub fn local(&self, g: u32) -> (usize, u32) {
        // offsets is ascending; the level is the last offset <= g.
        let k = self.offsets.partition_point(|&o| o <= g) - 1;
        (k, g - self.offsets[k])
    }

    /// Parent of a global node, or [`NONE`] at the top level.
    #[inline]
    pub fn parent_global(&self, g: u32) -> u32 {
        let (k, v) = self.local(g);
        if k + 1 < self.levels() { self.offsets[k + 1] + self.parent[k][v as usize] } else { NONE }
    }

    /// For every level, the ancestor of every fine vertex: `out[k][v]`.
    pub fn all_ancestors(&self) -> Vec<Vec<u32>> {
        let mut out = Vec::with_capacity(self.levels());
        out.push((0..self.level_sizes[0]).collect::<Vec<u32>>());
        for k in 0..self.levels() - 1 {
            let prev = &out[k];
            let next: Vec<u32> = prev.iter().map(|&a| self.parent[k][a as usize]).collect();
            out.push(next);
        }
        out
    }

    /// Children of every level-(k+1) node in compressed rows: `(offsets, children)`.
    pub fn children(&self, k: usize) -> (Vec<u32>, Vec<u32>) {
        compressed_rows(self.level_sizes[k + 1] as usize, || self.parent[k].iter().enumerate().map(|(v, &p)| (p, v as u32)))
    }

    /// Checks the structural invariants: parent maps of the right lengths pointing into the next
    /// level, no empty cluster, and every cluster at every level a connected set of fine vertices
    /// in M0 (section 4.2's validity rule guarantees it; this verifies it).
    pub fn check(&self, topo: &FineTopology) -> Result<(), String> {
        if self.level_sizes.first() != Some(&topo.vertex_count) {
            return Err(format!("level 0 has {:?} nodes, the mesh {}", self.level_sizes.first(), topo.vertex_count));
        }
        for k in 0..self.levels() - 1 {
            if self.parent[k].len() != self.level_sizes[k] as usize {
                return Err(format!("parent map {k} has {} entries for {} nodes", self.parent[k].len(), self.level_sizes[k]));
            }
            let mut used = vec![false; self.level_sizes[k + 1] as usize];
            for (v, &p) in self.parent[k].iter().enumerate() {
                let Some(slot) = used.get_mut(p as usize) else {
                    return Err(format!("level {k} node {v} has parent {p}, beyond level {}", k + 1));
                };
                *slot = true;
            }
            if let Some(a) = used.iter().position(|u| !u) {
                return Err(format!("level {} node {a} has no children", k + 1));
            }
        }
        // Connectivity: union-find over fine edges whose ends share the level-k ancestor; each
        // node must end with exactly one component.
        let n = topo.vertex_count as usize;
        let mut uf: Vec<u32> = Vec::with_capacity(n);
        let anc = self.all_ancestors();
        for (k, anc_k) in anc.iter().enumerate().skip(1) {
            uf.clear();
            uf.extend(0..n as u32);
            for e in &topo.edges {
                if anc_k[e[0] as usize] == anc_k[e[1] as usize] {
                    union(&mut uf, e[0], e[1]);
                }
            }
            let mut root_of_node = vec![NONE; self.level_sizes[k] as usize];
            for v in 0..n as u32 {
                let r = find(&mut uf, v);
                let a = anc_k[v as usize] as usize;
                if root_of_node[a] == NONE {
                    root_of_node[a] = r;
                } else if root_of_node[a] != r {
                    return Err(format!("level {k} node {a} is not connected (fine vertex {v} is cut off)"));
                }
            }
        }
        Ok(())
    }
}

pub(crate) fn find(uf: &mut [u32], mut x: u32) -> u32 {
    while uf[x as usize] != x {
        let up = uf[uf[x as usize] as usize];
        uf[x as usize] = up; // path halving
        x = up;
    }
    x
}

pub(crate) fn union(uf: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(uf, a), find(uf, b));
    if ra != rb {
        uf[ra.max(rb) as usize] = ra.min(rb);
    }
}
