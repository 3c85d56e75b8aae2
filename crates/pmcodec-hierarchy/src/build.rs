//! Building the multilevel mesh (Kircher & Garland section 3): one QEM edge-collapse run
//! (QSlim, Garland & Heckbert 1997) from M0 toward a single vertex per component, snapshotted
//! when the number of live vertices reaches each level's size.
//!
//! Only pairs joined by a mesh edge are contracted, so every cluster is a connected set of fine
//! vertices by construction. The run tracks vertex adjacency only (not faces): the clustering
//! is all the hierarchy keeps, and each level's faces are derived from M0 through the parent
//! maps afterwards, as the paper prescribes.

use crate::Hierarchy;
use crate::quadric::Quadric;
use crate::topology::FineTopology;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Options for [`build`].
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// Each level has about 1/b of the vertices of the one below (2..=16).
    pub branching: u32,
    /// Stop adding levels once the next one would have fewer vertices than this.
    pub min_coarsest: u32,
    /// Explicit level sizes below |M0| (strictly decreasing), overriding `branching`: used to
    /// put a level at exactly the vertex count an evaluation asks for.
    pub level_sizes: Option<Vec<u32>>,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions { branching: 4, min_coarsest: 8, level_sizes: None }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BuildError {
    #[error("branching factor {0} is outside 2..=16")]
    Branching(u32),
    #[error("{0} quadrics for {1} vertices")]
    QuadricCount(usize, u32),
    #[error("level sizes must decrease strictly from the {fine} input vertices and stay above 0: {sizes:?}")]
    LevelSizes { fine: u32, sizes: Vec<u32> },
    #[error("the mesh has no vertices")]
    Empty,
}

impl BuildOptions {
    /// The sizes of levels 1.. for a mesh of `fine` vertices.
    pub fn targets(&self, fine: u32) -> Result<Vec<u32>, BuildError> {
        if let Some(sizes) = &self.level_sizes {
            let mut prev = fine;
            for &s in sizes {
                if s == 0 || s >= prev {
                    return Err(BuildError::LevelSizes { fine, sizes: sizes.clone() });
                }
                prev = s;
            }
            return Ok(sizes.clone());
        }
        if !(2..=16).contains(&self.branching) {
            return Err(BuildError::Branching(self.branching));
        }
        let mut out = Vec::new();
        let mut k = 1;
        loop {
            let size = (fine as f64 / (self.branching as f64).powi(k)).round() as u32;
            let prev = out.last().copied().unwrap_or(fine);
            if size < self.min_coarsest.max(1) || size >= prev {
                break;
            }
            out.push(size);
            k += 1;
        }
        Ok(out)
    }
}

/// Level sizes `V, a*b^j, ..., a, a/b, ...` that put one level at exactly `anchor` vertices.
pub fn anchored_sizes(fine: u32, anchor: u32, branching: u32, min_coarsest: u32) -> Vec<u32> {
    let b = branching.max(2) as u64;
    let mut above = Vec::new();
    let mut s = anchor as u64 * b;
    while s < fine as u64 {
        above.push(s as u32);
        s *= b;
    }
    above.reverse();
    let mut out = above;
    if anchor < fine {
        out.push(anchor);
    }
    let mut s = anchor as u64 / b;
    while s >= min_coarsest.max(1) as u64 {
        out.push(s as u32);
        s /= b;
    }
    out
}

#[derive(Clone, Copy)]
struct Candidate {
    cost: f64,
    u: u32,
    v: u32,
    stamp_u: u32,
    stamp_v: u32,
}

impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Candidate {
    // BinaryHeap is a max-heap: reverse so the cheapest contraction comes out first; ties broken
    // by vertex ids so the build is deterministic.
    fn cmp(&self, o: &Self) -> Ordering {
        o.cost.total_cmp(&self.cost).then_with(|| o.u.cmp(&self.u)).then_with(|| o.v.cmp(&self.v))
    }
}

#[inline]
fn contraction_cost(a: &Quadric, b: &Quadric) -> f64 {
    let mut q = *a;
    q += b;
    q.eval(q.optimal()).max(0.0)
}

/// Builds the multilevel mesh from the fine-vertex quadrics that define "error" for the base
/// hierarchy (frame 0's, or summed over frames: see [`crate::base`]).
pub fn build(topo: &FineTopology, quadrics: &[Quadric], opts: &BuildOptions) -> Result<Hierarchy, BuildError> {
    let n = topo.vertex_count;
    if n == 0 {
        return Err(BuildError::Empty);
    }
    if quadrics.len() != n as usize {
        return Err(BuildError::QuadricCount(quadrics.len(), n));
    }
    let targets = opts.targets(n)?;
    let branching = opts.branching;

    let mut q: Vec<Quadric> = quadrics.to_vec();
    let mut adj: Vec<Vec<u32>> = (0..n).map(|v| topo.neighbours(v).to_vec()).collect();
    let mut alive = vec![true; n as usize];
    let mut stamp = vec![0u32; n as usize];
    // `merged_into[u]` = the vertex u was contracted into; roots are live vertices.
    let mut merged_into: Vec<u32> = (0..n).collect();

    let mut heap = BinaryHeap::with_capacity(topo.edges.len() * 2);
    for e in &topo.edges {
        let (u, v) = (e[0], e[1]);
        let cost = contraction_cost(&q[u as usize], &q[v as usize]);
        heap.push(Candidate { cost, u, v, stamp_u: 0, stamp_v: 0 });
    }

    let mut parents: Vec<Vec<u32>> = Vec::with_capacity(targets.len());
    // Live representatives of the previous level's nodes, in node order.
    let mut prev_reps: Vec<u32> = (0..n).collect();
    let mut live = n;
    let mut level_index = vec![u32::MAX; n as usize];
    let mut snapshot = |merged_into: &mut Vec<u32>, alive: &[bool], prev_reps: &mut Vec<u32>, parents: &mut Vec<Vec<u32>>| {
        let mut reps = Vec::new();
        for (v, &a) in alive.iter().enumerate() {
            if a {
                level_index[v] = reps.len() as u32;
                reps.push(v as u32);
            }
        }
        let parent: Vec<u32> =
            prev_reps.iter().map(|&r| level_index[crate::hierarchy::find(merged_into, r) as usize]).collect();
        parents.push(parent);
        *prev_reps = reps;
    };

    let mut next_target = 0usize;
    while next_target < targets.len() {
        if live <= targets[next_target] {
            snapshot(&mut merged_into, &alive, &mut prev_reps, &mut parents);
            next_target += 1;
            continue;
        }
        let Some(c) = heap.pop() else {
            // Nothing left to contract (one vertex per connected component): the last level is
            // as coarse as the mesh allows.
            if (live as usize) < prev_reps.len() {
                snapshot(&mut merged_into, &alive, &mut prev_reps, &mut parents);
            }
            break;
        };
        let (u, v) = (c.u as usize, c.v as usize);
        if !alive[u] || !alive[v] || stamp[u] != c.stamp_u || stamp[v] != c.stamp_v {
            continue; // stale: one end changed since this cost was computed
        }
        // Keep the end with more neighbours so fewer lists are rewritten.
        let (keep, gone) = if adj[u].len() >= adj[v].len() { (u, v) } else { (v, u) };
        let qg = q[gone];
        q[keep] += &qg;
        alive[gone] = false;
        merged_into[gone] = keep as u32;
        stamp[keep] += 1;
        live -= 1;
        let gone_adj = std::mem::take(&mut adj[gone]);
        for &w in &gone_adj {
            let w = w as usize;
            if w == keep {
                continue;
            }
            let list = &mut adj[w];
            let has_keep = list.contains(&(keep as u32));
            if let Some(i) = list.iter().position(|&x| x as usize == gone) {
                if has_keep {
                    list.swap_remove(i);
                } else {
                    list[i] = keep as u32;
                }
            }
            if !adj[keep].contains(&(w as u32)) {
                adj[keep].push(w as u32);
            }
        }
        if let Some(i) = adj[keep].iter().position(|&x| x as usize == gone) {
            adj[keep].swap_remove(i);
        }
        let sk = stamp[keep];
        for &w in &adj[keep] {
            let cost = contraction_cost(&q[keep], &q[w as usize]);
            heap.push(Candidate { cost, u: keep as u32, v: w, stamp_u: sk, stamp_v: stamp[w as usize] });
        }
    }

    Ok(Hierarchy::from_parents(branching, n, parents))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_shrink_by_branching() {
        let o = BuildOptions::default();
        assert_eq!(o.targets(8431).unwrap(), vec![2108, 527, 132, 33, 8]);
        assert!(BuildOptions { branching: 1, ..o.clone() }.targets(100).is_err());
        assert!(BuildOptions { level_sizes: Some(vec![50, 50]), ..o }.targets(100).is_err());
    }

    #[test]
    fn anchored() {
        assert_eq!(anchored_sizes(8431, 800, 4, 8), vec![3200, 800, 200, 50, 12]);
    }
}
