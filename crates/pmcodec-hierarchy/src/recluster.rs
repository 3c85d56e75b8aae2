//! Per-frame reclustering (Kircher & Garland section 4 and 5): as the surface deforms, swaps
//! move level-k nodes between neighbouring clusters of level k+1 so that the hierarchy H_f fits
//! frame f. The swaps of one frame turn H_{f-1} into H_f and are what the stream carries.
//!
//! Per frame: fine quadrics from the frame's positions, node quadrics summed up the hierarchy,
//! positions re-solved; then, coarse to fine, passes of valid beneficial swaps, best first, an
//! independent set per pass, until none is left or a cap is reached.

use crate::Hierarchy;
use crate::levels::{LevelAdjacency, LevelScratch, level_adjacency_with};
use crate::nodes::NodeState;
use crate::quadric::{Quadric, QuadricOptions, vertex_quadrics};
use crate::topology::FineTopology;
use glam::Vec3;

/// One swap (section 4.1): level-`level` node `v` moves from cluster `from` to cluster `to`
/// (both level `level + 1` nodes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Swap {
    /// The level of the node that moves.
    pub level: u32,
    /// The node that moves (level-local id).
    pub v: u32,
    /// Its old parent (level `level + 1` local id).
    pub from: u32,
    /// Its new parent (level `level + 1` local id).
    pub to: u32,
}

/// Options for reclustering.
#[derive(Clone, Debug, PartialEq)]
pub struct ReclusterOptions {
    /// Growth exponent of the QEM across levels in the hierarchical weights (equation 2).
    pub beta: f64,
    /// At most this many swaps per frame (over all levels).
    pub max_swaps_per_frame: u32,
    /// At most this many independent-set passes per level per frame.
    pub max_passes: u32,
    /// A swap must improve the estimate by at least this fraction of the node's current error,
    /// so that rounding noise never drives swaps back and forth.
    pub min_relative_benefit: f64,
    /// Rank swaps by the exact change of error (both clusters re-solved) instead of the
    /// conservative estimate of equation 1, which never sees a swap whose gain comes only from
    /// the re-solved positions.
    pub exact_benefit: bool,
    /// Also require the homeomorphism rule of section 4.2 (conservatively: see `homeomorphic`).
    pub homeomorphism: bool,
    /// Quadrics of each frame (boundary weight).
    pub quadric: QuadricOptions,
}

impl Default for ReclusterOptions {
    fn default() -> Self {
        // Defaults measured on horse-gallop (800 vertices, 1,600-triangle coherence budget; see
        // the README's figures): the paper's beta = 1.9127 (our own regression of the QEM growth
        // gives 1.87 on the horse) spreads each swap's benefit over all coarser levels; beta = 4
        // weighs the next level most and gave lower RMS at every level we measured (200, 800 and
        // 3,200 vertices). Exact benefits find swaps equation 1 misses. The hysteresis of 1.0
        // (a swap must gain at least the moving node's current error) keeps playback coherent
        // (3% of shown triangles change per frame instead of 22%) for about 7% more RMS.
        ReclusterOptions {
            beta: 4.0,
            max_swaps_per_frame: u32::MAX,
            max_passes: 16,
            min_relative_benefit: 1.0,
            homeomorphism: false,
            exact_benefit: true,
            quadric: QuadricOptions::default(),
        }
    }
}

/// Counters of one frame's reclustering.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Swaps made.
    pub swaps: u32,
    /// Independent-set passes run, over all levels.
    pub passes: u32,
    /// Candidate swaps evaluated.
    pub candidates: u64,
    /// Candidates rejected because they would break a cluster or the homeomorphism rule.
    pub rejected_invalid: u64,
}

/// The reclustering state: the current hierarchy and its node quadrics and positions.
pub struct Reclusterer {
    h: Hierarchy,
    nodes: NodeState,
    opts: ReclusterOptions,
    topo: FineTopology,
    triangles: Vec<[u32; 3]>,
    /// (|M_{j+1}| / |M_j|)^beta for each level j: the factor between consecutive weights.
    weight_step: Vec<f64>,
    fine_q: Vec<Quadric>,
    /// E_g = Q_g(x_g) of every node (unclamped, as the exact benefit reads it), kept in step
    /// with `nodes` by `fit` and `apply`: the "before" half of every exact benefit term.
    errors: Vec<f64>,
    /// The exact benefit's terms that depend only on the moving node (see [`GainMemo`]).
    memo: GainMemo,
    adjacency: Vec<LevelAdjacency>,
    /// Whether `adjacency` is that of the current hierarchy: built by a frame, and no swap
    /// ([`Self::apply`]) since. Frames without swaps (a skinned sequence reclustered every few
    /// frames, or never) reuse it, and frames with no swap budget need none: building it was
    /// 14% of the encode of the 34,102-vertex character of scripts/benchmarks.py, whose
    /// hierarchy never changes.
    adjacency_fresh: bool,
    level_scratch: LevelScratch,
    // Scratch, kept to avoid allocation per frame.
    locked: Vec<bool>,
    dirty: Vec<bool>,
    dirty_list: Vec<u32>,
    candidates: Vec<(f64, u32, u32)>,
    anc: Vec<u32>,
    set: Vec<u32>,
    stack: Vec<u32>,
    seen: Vec<bool>,
}

impl Reclusterer {
    /// Starts from H_0 (`h`, built for the sequence's first frame or poses).
    pub fn new(h: Hierarchy, topo: FineTopology, triangles: Vec<[u32; 3]>, opts: ReclusterOptions) -> Self {
        let weight_step = (0..h.levels())
            .map(|j| if j + 1 < h.levels() { (h.level_sizes[j + 1] as f64 / h.level_sizes[j] as f64).powf(opts.beta) } else { 0.0 })
            .collect();
        Reclusterer {
            h,
            nodes: NodeState::default(),
            opts,
            topo,
            triangles,
            weight_step,
            fine_q: Vec::new(),
            errors: Vec::new(),
            memo: GainMemo::default(),
            adjacency: Vec::new(),
            adjacency_fresh: false,
            level_scratch: LevelScratch::default(),
            locked: Vec::new(),
            dirty: Vec::new(),
            dirty_list: Vec::new(),
            candidates: Vec::new(),
            anc: Vec::new(),
            set: Vec::new(),
            stack: Vec::new(),
            seen: Vec::new(),
        }
    }

    /// The current hierarchy.
    pub fn hierarchy(&self) -> &Hierarchy {
        &self.h
    }

    /// Every node's quadric and position for the frame last fitted (level 0 is that frame's
    /// input).
    pub fn nodes(&self) -> &NodeState {
        &self.nodes
    }

    /// The options reclustering runs with.
    pub fn options(&self) -> &ReclusterOptions {
        &self.opts
    }

    /// The options, to change between frames (an encoder reclustering only some frames sets
    /// the swap budget of the others to 0).
    pub fn options_mut(&mut self) -> &mut ReclusterOptions {
        &mut self.opts
    }

    /// The fine mesh's topology.
    pub fn topology(&self) -> &FineTopology {
        &self.topo
    }

    /// The fine mesh's triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Computes this frame's quadrics and node positions on the current hierarchy without
    /// changing it (what "first-frame static" uses, and the state before reclustering).
    pub fn fit(&mut self, positions: &[Vec3]) {
        vertex_quadrics(positions, &self.triangles, &self.topo.boundary, &self.opts.quadric, &mut self.fine_q);
        self.nodes.recompute(&self.h, &self.fine_q, positions);
        let (q, x) = (&self.nodes.quadrics, &self.nodes.positions);
        self.errors.clear();
        self.errors.extend(q.iter().zip(x).map(|(q, &x)| q.eval_f32(x)));
    }

    /// Adapts the hierarchy to a new frame; appends the swaps performed, in order, to `swaps`.
    pub fn frame(&mut self, positions: &[Vec3], swaps: &mut Vec<Swap>) -> FrameStats {
        self.fit(positions);
        let mut stats = FrameStats::default();
        let mut budget = self.opts.max_swaps_per_frame;
        if budget == 0 || self.h.levels() < 2 {
            return stats;
        }
        let mut adjacency = std::mem::take(&mut self.adjacency);
        if !self.adjacency_fresh {
            level_adjacency_with(&self.h, &self.topo, &mut adjacency, &mut self.level_scratch);
            self.adjacency_fresh = true;
        }
        for k in (0..self.h.levels() - 1).rev() {
            if budget == 0 {
                break;
            }
            self.improve_level(k, &adjacency[k], swaps, &mut stats, &mut budget);
        }
        self.adjacency = adjacency;
        debug_assert!(self.h.check(&self.topo).is_ok(), "reclustering broke a cluster: {:?}", self.h.check(&self.topo));
        stats
    }

    /// Passes of best-first independent sets of valid beneficial swaps at level k.
    fn improve_level(&mut self, k: usize, adj: &LevelAdjacency, swaps: &mut Vec<Swap>, stats: &mut FrameStats, budget: &mut u32) {
        let n = self.h.level_sizes[k] as usize;
        self.locked.clear();
        self.locked.resize(n, false);
        self.dirty.clear();
        self.dirty.resize(n, true);
        self.dirty_list.clear();
        self.dirty_list.extend(0..n as u32);
        for _pass in 0..self.opts.max_passes {
            stats.passes += 1;
            // 1. Candidates: for each dirty node, its best beneficial move to a neighbouring cluster.
            self.candidates.clear();
            for i in 0..self.dirty_list.len() {
                let v = self.dirty_list[i];
                self.dirty[v as usize] = false;
                let a = self.h.parent[k][v as usize];
                let mut best = (0.0, a);
                // Every candidate move of v shares v's quadric and the clusters it leaves.
                self.memo.clear();
                for &w in adj.row(v) {
                    let b = self.h.parent[k][w as usize];
                    if b == a || b == best.1 {
                        continue;
                    }
                    stats.candidates += 1;
                    let gain = self.gain(k, v, a, b);
                    if gain > best.0 {
                        best = (gain, b);
                    }
                }
                if best.1 != a && best.0 > self.threshold(k, v, a) {
                    self.candidates.push((best.0, v, best.1));
                }
            }
            if self.candidates.is_empty() {
                break;
            }
            self.candidates.sort_unstable_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
            // 2. An independent set, best first: a swap locks its node and its neighbours, so
            // no validity test in this pass reads a neighbourhood another swap has changed.
            self.dirty_list.clear();
            let mut done = 0u32;
            let cands = std::mem::take(&mut self.candidates);
            for &(_, v, b) in &cands {
                if *budget == 0 {
                    break;
                }
                if self.locked[v as usize] {
                    continue;
                }
                let a = self.h.parent[k][v as usize];
                // Earlier swaps in this pass moved node positions: re-estimate.
                self.memo.clear();
                if self.gain(k, v, a, b) <= self.threshold(k, v, a) {
                    continue;
                }
                if !self.valid(k, adj, v, a, b) {
                    stats.rejected_invalid += 1;
                    continue;
                }
                self.apply(k, v, a, b);
                swaps.push(Swap { level: k as u32, v, from: a, to: b });
                done += 1;
                *budget -= 1;
                self.locked[v as usize] = true;
                self.mark_dirty(v);
                for &w in adj.row(v) {
                    self.locked[w as usize] = true;
                    self.mark_dirty(w);
                    // Neighbours of neighbours see moved cluster positions too.
                    for &x in adj.row(w) {
                        self.mark_dirty(x);
                    }
                }
            }
            self.candidates = cands;
            stats.swaps += done;
            if done == 0 || *budget == 0 {
                break;
            }
            for l in self.locked.iter_mut() {
                *l = false;
            }
        }
    }

    #[inline]
    fn mark_dirty(&mut self, v: u32) {
        if !self.dirty[v as usize] {
            self.dirty[v as usize] = true;
            self.dirty_list.push(v);
        }
    }

    /// The smallest benefit worth a swap.
    #[inline]
    fn threshold(&self, k: usize, v: u32, a: u32) -> f64 {
        let qv = &self.nodes.quadrics[(self.h.offsets[k] + v) as usize];
        let xa = self.nodes.positions[(self.h.offsets[k + 1] + a) as usize];
        self.opts.min_relative_benefit * qv.eval_f32(xa).max(0.0)
    }

    /// Hierarchical benefit of moving level-k node v from a to b: equation 1 at each coarser
    /// level where the ancestors differ, weighted by equation 2 (w_{k+1} = 1).
    #[inline]
    pub fn benefit(&self, k: usize, v: u32, a: u32, b: u32) -> f64 {
        let h = &self.h;
        let qv = &self.nodes.quadrics[(h.offsets[k] + v) as usize];
        let (mut x, mut y) = (a, b);
        let mut w = 1.0;
        let mut sum = 0.0;
        let mut j = k + 1;
        while x != y {
            let pa = self.nodes.positions[(h.offsets[j] + x) as usize];
            let pb = self.nodes.positions[(h.offsets[j] + y) as usize];
            sum += w * if self.opts.exact_benefit {
                // Re-solve both clusters as they would be after the swap.
                let (qa, qb) = (&self.nodes.quadrics[(h.offsets[j] + x) as usize], &self.nodes.quadrics[(h.offsets[j] + y) as usize]);
                let before = qa.eval_f32(pa) + qb.eval_f32(pb);
                before - without(qa, qv) - with(qb, qv)
            } else {
                qv.eval_f32(pa) - qv.eval_f32(pb)
            };
            if j == h.top() {
                break;
            }
            w *= self.weight_step[j];
            x = h.parent[j][x as usize];
            y = h.parent[j][y as usize];
            j += 1;
        }
        sum
    }

    /// [`Reclusterer::benefit`], the same value to the bit, from what `memo` and `errors`
    /// already hold. Of an exact term `(E_A + E_B) - E'_A - E'_B` at level j, E'_A (A_j
    /// re-solved without v) depends only on v and A_j, the ancestors of v's own parent, so it
    /// is solved once per moving node, not once per neighbouring cluster; E'_B is solved once
    /// per distinct B_j (several neighbours of v share a cluster, and their clusters share
    /// ancestors); E_A and E_B are read from `errors`. `memo` must be cleared whenever v or the
    /// node state changes.
    fn gain(&mut self, k: usize, v: u32, a: u32, b: u32) -> f64 {
        if !self.opts.exact_benefit {
            return self.benefit(k, v, a, b);
        }
        let Reclusterer { h, nodes, errors, memo, weight_step, .. } = self;
        let qv = &nodes.quadrics[(h.offsets[k] + v) as usize];
        let (mut x, mut y) = (a, b);
        let mut w = 1.0;
        let mut sum = 0.0;
        let mut j = k + 1;
        while x != y {
            let (gx, gy) = ((h.offsets[j] + x) as usize, (h.offsets[j] + y) as usize);
            // x runs up the one chain of a's ancestors whatever b is: level j's entry is A_j's.
            let i = j - (k + 1);
            let left = match memo.a_side.get(i) {
                Some(&e) => e,
                None => {
                    let e = without(&nodes.quadrics[gx], qv);
                    memo.a_side.push(e);
                    e
                }
            };
            let joined = match memo.b_side.iter().find(|m| m.0 == gy as u32) {
                Some(m) => m.1,
                None => {
                    let e = with(&nodes.quadrics[gy], qv);
                    memo.b_side.push((gy as u32, e));
                    e
                }
            };
            // The operations and their order are `benefit`'s, so the sum is bit-identical.
            sum += w * (errors[gx] + errors[gy] - left - joined);
            if j == h.top() {
                break;
            }
            w *= weight_step[j];
            x = h.parent[j][x as usize];
            y = h.parent[j][y as usize];
            j += 1;
        }
        sum
    }

    /// Validity (section 4.2, at level k and every coarser level where the ancestors of a and b
    /// differ): after v leaves, the ancestor A_j of a must keep some of v's neighbours, and those
    /// neighbours must be connected to one another without passing through v. Checking the
    /// neighbours' connection through edges among themselves is local and conservative: it
    /// never accepts a swap that disconnects a cluster (any path through v can be rerouted
    /// through them), though it may reject one that would not.
    pub fn valid(&mut self, k: usize, adj: &LevelAdjacency, v: u32, a: u32, b: u32) -> bool {
        let h = &self.h;
        let nbrs = adj.row(v);
        self.anc.clear();
        self.anc.extend(nbrs.iter().map(|&w| h.parent[k][w as usize]));
        let (mut x, mut y) = (a, b);
        let mut j = k + 1;
        while x != y {
            // S_j: v's neighbours whose level-j ancestor is A_j = x.
            self.set.clear();
            for (i, &c) in self.anc.iter().enumerate() {
                if c == x {
                    self.set.push(i as u32);
                }
            }
            if self.set.is_empty() || !connected_among(nbrs, &self.set, adj, &mut self.stack, &mut self.seen) {
                return false;
            }
            if j == h.top() {
                break;
            }
            x = h.parent[j][x as usize];
            y = h.parent[j][y as usize];
            for c in self.anc.iter_mut() {
                *c = h.parent[j][*c as usize];
            }
            j += 1;
        }
        if self.opts.homeomorphism && !self.homeomorphic(k, adj, v, b) {
            return false;
        }
        true
    }

    /// Section 4.2's optional rule, applied conservatively: for every cluster c that v touches
    /// (other than b), v's contact with c must continue an existing contact between C_b and c,
    /// i.e. some neighbour of v in C_b is adjacent to some neighbour of v in C_c. Otherwise the
    /// swap could open a second, separate boundary between C_b and c, and the approximation
    /// would stop being homeomorphic to the one before.
    fn homeomorphic(&self, k: usize, adj: &LevelAdjacency, v: u32, b: u32) -> bool {
        let parent = &self.h.parent[k];
        let nbrs = adj.row(v);
        for &w in nbrs {
            let c = parent[w as usize];
            if c == b {
                continue;
            }
            let touches =
                nbrs.iter().any(|&u| parent[u as usize] == b && nbrs.iter().any(|&z| parent[z as usize] == c && adj.adjacent(u, z)));
            if !touches {
                return false;
            }
        }
        true
    }

    /// Performs swap (v, a, b) at level k: reparents v and moves its quadric from every
    /// ancestor of a to the matching ancestor of b (Q_a -= Q_v, Q_b += Q_v), re-solving them.
    pub fn apply(&mut self, k: usize, v: u32, a: u32, b: u32) {
        self.adjacency_fresh = false;
        let h = &mut self.h;
        h.parent[k][v as usize] = b;
        let qv = self.nodes.quadrics[(h.offsets[k] + v) as usize];
        let (mut x, mut y) = (a, b);
        let mut j = k + 1;
        while x != y {
            let (gx, gy) = (h.offsets[j] + x, h.offsets[j] + y);
            self.nodes.quadrics[gx as usize] -= &qv;
            self.nodes.quadrics[gy as usize] += &qv;
            self.nodes.resolve(gx);
            self.nodes.resolve(gy);
            for g in [gx as usize, gy as usize] {
                self.errors[g] = self.nodes.quadrics[g].eval_f32(self.nodes.positions[g]);
            }
            if j == h.top() {
                break;
            }
            x = h.parent[j][x as usize];
            y = h.parent[j][y as usize];
            j += 1;
        }
    }
}

/// The exact benefit's memo for one moving node v (see [`Reclusterer::gain`]).
#[derive(Debug, Default)]
struct GainMemo {
    /// E'_{A_j}, the error of v's parent's level-j ancestor re-solved without v, for
    /// j = k+1, k+2, ... in order, as far as some candidate has needed.
    a_side: Vec<f64>,
    /// (global id of B, E'_B): a cluster v could join, or its ancestor, re-solved with v.
    b_side: Vec<(u32, f64)>,
}

impl GainMemo {
    fn clear(&mut self) {
        self.a_side.clear();
        self.b_side.clear();
    }
}

/// The error of cluster `q` re-solved after `v` leaves it.
#[inline]
fn without(q: &Quadric, v: &Quadric) -> f64 {
    let mut q = *q;
    q -= v;
    q.eval(q.optimal())
}

/// The error of cluster `q` re-solved after `v` joins it.
#[inline]
fn with(q: &Quadric, v: &Quadric) -> f64 {
    let mut q = *q;
    q += v;
    q.eval(q.optimal())
}

/// Whether the neighbours `nbrs[set[..]]` form one connected group using edges among
/// themselves.
fn connected_among(nbrs: &[u32], set: &[u32], adj: &LevelAdjacency, stack: &mut Vec<u32>, seen: &mut Vec<bool>) -> bool {
    if set.len() <= 1 {
        return true;
    }
    seen.clear();
    seen.resize(set.len(), false);
    stack.clear();
    stack.push(0);
    seen[0] = true;
    let mut reached = 1;
    while let Some(i) = stack.pop() {
        let u = nbrs[set[i as usize] as usize];
        for (j, &s) in set.iter().enumerate() {
            if !seen[j] && adj.adjacent(u, nbrs[s as usize]) {
                seen[j] = true;
                reached += 1;
                stack.push(j as u32);
            }
        }
    }
    reached == set.len()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::{BuildOptions, build};
    use pmcodec_mesh::Sequence;

    /// Every candidate's memoised gain against the reference `benefit`, to the bit, and the
    /// kept node errors against fresh ones: before and after each frame's swaps (which update
    /// both through `apply`).
    fn check_sequence(seq: &Sequence, exact: bool) -> u32 {
        let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
        let mut q = Vec::new();
        vertex_quadrics(&seq.frames[0], &seq.triangles, &topo.boundary, &QuadricOptions::default(), &mut q);
        let h = build(&topo, &q, &BuildOptions { min_coarsest: 4, ..Default::default() }).unwrap();
        assert!(h.levels() >= 3, "levels {:?}", h.level_sizes);
        let opts = ReclusterOptions { exact_benefit: exact, min_relative_benefit: 0.1, ..Default::default() };
        let mut rc = Reclusterer::new(h, topo, seq.triangles.clone(), opts);
        let (mut swaps, mut adjacency, mut compared) = (Vec::new(), Vec::new(), 0u64);
        let mut check = |rc: &mut Reclusterer| {
            for (g, e) in rc.errors.iter().enumerate() {
                assert_eq!(e.to_bits(), rc.nodes.quadrics[g].eval_f32(rc.nodes.positions[g]).to_bits(), "node {g}");
            }
            crate::levels::level_adjacency_with(&rc.h, &rc.topo, &mut adjacency, &mut Default::default());
            for (k, adj) in adjacency.iter().enumerate().take(rc.h.levels() - 1) {
                for v in 0..rc.h.level_sizes[k] {
                    let a = rc.h.parent[k][v as usize];
                    rc.memo.clear();
                    for &w in adj.row(v) {
                        let b = rc.h.parent[k][w as usize];
                        if b != a {
                            let (got, want) = (rc.gain(k, v, a, b), rc.benefit(k, v, a, b));
                            assert_eq!(got.to_bits(), want.to_bits(), "level {k} node {v} from {a} to {b}: {got} vs {want}");
                            compared += 1;
                        }
                    }
                }
            }
        };
        for frame in &seq.frames {
            rc.fit(frame);
            check(&mut rc);
            rc.frame(frame, &mut swaps);
            check(&mut rc);
        }
        assert!(compared > 1000, "only {compared} candidates compared");
        swaps.len() as u32
    }

    #[test]
    fn memoised_gain_is_the_benefit_closed_tube() {
        let swaps = check_sequence(&pmcodec_mesh::samples::twisting_tube(16, 24, 6), true);
        assert!(swaps > 0, "no swaps: apply's error updates went untested");
    }

    #[test]
    fn memoised_gain_is_the_benefit_open_cloth() {
        let swaps = check_sequence(&pmcodec_mesh::samples::waving_cloth(20, 16, 5), true);
        assert!(swaps > 0, "no swaps: apply's error updates went untested");
    }

    #[test]
    fn estimate_path_unchanged() {
        check_sequence(&pmcodec_mesh::samples::waving_cloth(12, 10, 3), false);
    }
}
