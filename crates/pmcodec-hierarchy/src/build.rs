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
use glam::DVec3;

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
    /// Levels 1.. holding at least these fractions of M0's triangles first (decreasing, in
    /// (0, 1)), then every `branching` times smaller in vertices: so that levels fall on the
    /// triangle budgets clients ask for (a client at a budget reads the bands down to the
    /// coarsest level that holds it). Empty: levels 1/b, 1/b^2, ... of |M0|.
    pub anchors: Vec<f64>,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions { branching: 4, min_coarsest: 8, level_sizes: None, anchors: Vec::new() }
    }
}

/// Options or input a hierarchy cannot be built from.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BuildError {
    /// The branching factor is outside 2..=16.
    #[error("branching factor {0} is outside 2..=16")]
    Branching(u32),
    /// The quadrics do not match the vertices one to one.
    #[error("{0} quadrics for {1} vertices")]
    QuadricCount(usize, u32),
    /// Explicit level sizes that do not decrease strictly from the input's vertex count.
    #[error("level sizes must decrease strictly from the {fine} input vertices and stay above 0: {sizes:?}")]
    LevelSizes {
        /// The input's vertex count.
        fine: u32,
        /// The level sizes asked for.
        sizes: Vec<u32>,
    },
    /// A mesh without vertices.
    #[error("the mesh has no vertices")]
    Empty,
    /// A level anchor that is not a decreasing fraction in (0, 1).
    #[error("level anchor {0}: anchors are decreasing fractions of the input vertices, between 0 and 1")]
    Anchor(f64),
}

impl BuildOptions {
    /// The vertex sizes of levels 1.. for a mesh of `fine` vertices, when no anchor is set
    /// (explicit `level_sizes`, or every `branching` times smaller). Anchored levels are sized
    /// by triangles instead: see [`BuildOptions::anchor_triangles`].
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
        Ok(self.branch_sizes(fine))
    }

    /// Vertex sizes `from / b, from / b^2, ...` down to `min_coarsest`.
    pub fn branch_sizes(&self, from: u32) -> Vec<u32> {
        let mut out: Vec<u32> = Vec::new();
        let b = self.branching.clamp(2, 16) as f64;
        let mut k = 1;
        loop {
            let size = (from as f64 / b.powi(k)).round() as u32;
            let prev = out.last().copied().unwrap_or(from);
            if size < self.min_coarsest.max(1) || size >= prev {
                break;
            }
            out.push(size);
            k += 1;
        }
        out
    }

    /// The triangle counts the anchored levels keep at least, for a mesh of `fine`
    /// triangles: `ceil(anchor * fine)` each, while that stays at or above `min_coarsest`.
    pub fn anchor_triangles(&self, fine: u32) -> Result<Vec<u32>, BuildError> {
        if !(2..=16).contains(&self.branching) {
            return Err(BuildError::Branching(self.branching));
        }
        let mut out: Vec<u32> = Vec::new();
        let mut prev = 1.0;
        for &f in &self.anchors {
            if !(f > 0.0 && f < prev) {
                return Err(BuildError::Anchor(f));
            }
            prev = f;
            let size = (fine as f64 * f).ceil() as u32;
            if size < self.min_coarsest.max(1) {
                break;
            }
            out.push(size);
        }
        Ok(out)
    }
}

/// Level sizes `V, a*b^j, ..., a, a/b, ...` that put one level at exactly `anchor` vertices.
pub fn anchored_sizes(fine: u32, anchor: u32, branching: u32, min_coarsest: u32) -> Vec<u32> {
    let b = branching.max(2) as u64;
    let mut above = Vec::new();
    let mut s = anchor as u64 * b;
    // An anchor of 0 would never grow: its size list is left to `build` to refuse.
    while s > 0 && s < fine as u64 {
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

#[inline]
fn contraction_cost(a: &Quadric, b: &Quadric) -> f32 {
    let mut q = *a;
    q += b;
    q.eval(q.optimal()).max(0.0) as f32
}

/// At most this fraction of the live vertices is contracted per pass: small enough that a pass
/// stays close to the one-at-a-time greedy order of QSlim, large enough that few passes are
/// needed (the same batching meshoptimizer's simplifier uses).
const PASS_FRACTION: u32 = 6;

/// What the build stops at for one level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stop {
    /// This many live vertices.
    Vertices(u32),
    /// As few vertices as keep at least this many triangles (a level anchor).
    Triangles(u32),
}

/// Below this many triangles above a triangle target, contractions are made one at a time,
/// each checked to remove no more triangles than the target allows.
const EXACT_GAP: u32 = 24;

/// The state of the contraction run (see [`build`]).
struct Run<'a> {
    topo: &'a FineTopology,
    q: Vec<Quadric>,
    alive: Vec<bool>,
    /// `merged_into[u]` = the vertex u was contracted into; roots are live vertices.
    merged_into: Vec<u32>,
    /// Current edges between live vertices, (a, b) with a < b, and their contraction costs.
    edges: Vec<[u32; 2]>,
    cost: Vec<f32>,
    live: u32,
    touched: Vec<bool>,
    order: Vec<u32>,
    scratch: Vec<f32>,
    /// Both ends of every contraction of the pass, to clear their flags afterwards.
    changed: Vec<u32>,
    keys: Vec<(u64, u32)>,
    /// Per live vertex: its position (the optimum of its quadric), whether its cluster holds a
    /// boundary vertex, and the fine triangles around it that may still be live (see
    /// [`Run::valid`]): every live triangle with a corner in the cluster is listed (a contraction
    /// joins the two lists and drops the triangles it kills), and dead ones may linger.
    pos: Vec<DVec3>,
    border: Vec<bool>,
    around: Vec<Vec<u32>>,
    /// Each fine triangle's normal (unnormalised): a level's triangle must face the same way.
    fine_normal: Vec<DVec3>,
    /// Fine triangles whose corners lie in three different live clusters (the current level's
    /// mesh), kept as contractions remove them rather than counted over the mesh each pass.
    live_triangles: u32,
}

impl<'a> Run<'a> {
    fn new(topo: &'a FineTopology, quadrics: &[Quadric]) -> Self {
        let n = topo.vertex_count;
        let q: Vec<Quadric> = quadrics.to_vec();
        let edges: Vec<[u32; 2]> = topo.edges.clone();
        let cost = edges.iter().map(|e| contraction_cost(&q[e[0] as usize], &q[e[1] as usize])).collect();
        let mut around = vec![Vec::new(); n as usize];
        for (t, tri) in topo.triangles.iter().enumerate() {
            for &v in tri {
                around[v as usize].push(t as u32);
            }
        }
        let mut border = vec![false; n as usize];
        for &(a, b, _) in &topo.boundary {
            border[a as usize] = true;
            border[b as usize] = true;
        }
        let pos: Vec<DVec3> = q.iter().map(Quadric::centroid).collect();
        let fine_normal = topo
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| pos[v as usize]);
                (b - a).cross(c - a)
            })
            .collect();
        let live_triangles = topo.triangles.iter().filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]).count() as u32;
        Run {
            live_triangles,
            fine_normal,
            pos,
            border,
            around,
            topo,
            q,
            alive: vec![true; n as usize],
            merged_into: (0..n).collect(),
            edges,
            cost,
            live: n,
            touched: vec![false; n as usize],
            order: Vec::new(),
            scratch: Vec::new(),
            changed: Vec::new(),
            keys: Vec::new(),
        }
    }

    /// Live triangles that contracting live vertices `u` and `v` would remove: those around
    /// `u` whose corners lie in three clusters, two of them `u` and `v`. Every live triangle
    /// touching `u`'s cluster is in `around[u]` (see [`Run::around`]), so this is the count a
    /// scan of every fine triangle gives, in the time of one neighbourhood.
    fn removed_by(&mut self, u: u32, v: u32) -> u32 {
        let mut n = 0;
        for i in 0..self.around[u as usize].len() {
            let t = self.around[u as usize][i];
            let r = self.topo.triangles[t as usize].map(|x| crate::hierarchy::find(&mut self.merged_into, x));
            let live = r[0] != r[1] && r[1] != r[2] && r[0] != r[2];
            n += u32::from(live && r.contains(&u) && r.contains(&v));
        }
        n
    }

    /// One pass toward `stop`; returns the contractions made (0: nothing more can be done).
    fn step(&mut self, stop: Stop) -> u32 {
        let fraction = (self.live / PASS_FRACTION).max(1);
        match stop {
            Stop::Vertices(target) => {
                if self.live <= target {
                    return 0;
                }
                self.checked_pass((self.live - target).min(fraction), None)
            }
            Stop::Triangles(target) => {
                let gap = self.live_triangles.saturating_sub(target);
                if gap == 0 {
                    0
                } else if gap < EXACT_GAP {
                    self.checked_pass(1, Some(gap))
                } else {
                    // A contraction removes the (usually two) triangles on its edge; an
                    // eighth of the gap per pass keeps far from overshooting.
                    self.checked_pass((gap / 8).clamp(1, fraction), None)
                }
            }
        }
    }

    /// A pass of valid contractions only; where none is left, one without the check, so that
    /// every level reaches its size.
    fn checked_pass(&mut self, limit: u32, max_removed: Option<u32>) -> u32 {
        match self.pass(limit, max_removed, true) {
            0 => self.pass(limit, max_removed, false),
            done => done,
        }
    }

    /// Whether contracting live vertices `u` and `v` to `p` is valid (Garland & Heckbert 1997,
    /// section 3.2's consistency check, and their boundary rule as meshoptimizer applies it):
    /// no surrounding triangle turns over, and two boundary clusters join only across a
    /// boundary edge (one triangle between them), so a boundary is never pinched to a point
    /// across the surface. Triangles that turned over at a coarse level were drawn folded;
    /// boundaries pinched across holes opened new holes.
    fn valid(&mut self, u: u32, v: u32, p: DVec3) -> bool {
        let mut shared = 0;
        for x in [u, v] {
            for i in 0..self.around[x as usize].len() {
                let t = self.around[x as usize][i];
                let r = self.topo.triangles[t as usize].map(|c| crate::hierarchy::find(&mut self.merged_into, c));
                if r[0] == r[1] || r[1] == r[2] || r[0] == r[2] {
                    continue;
                }
                if r.contains(&u) && r.contains(&v) {
                    shared += u32::from(x == u);
                    continue;
                }
                let [a, b, c] = r.map(|y| self.pos[y as usize]);
                let before = (b - a).cross(c - a);
                let [a2, b2, c2] = r.map(|y| if y == x { p } else { self.pos[y as usize] });
                let after = (b2 - a2).cross(c2 - a2);
                // Against the triangle as it is now and as it was in the input: small turns
                // add up over many contractions.
                if !(after.dot(before) > 0.0 && after.dot(self.fine_normal[t as usize]) > 0.0) {
                    return false;
                }
            }
        }
        !(self.border[u as usize] && self.border[v as usize] && shared != 1)
    }

    /// Contracts up to `limit` of the cheapest edges, an independent set; with `max_removed`,
    /// only a contraction removing at most that many live triangles.
    ///
    /// Contractions are made in passes: each pass takes the cheapest current edges in cost
    /// order and contracts every one whose ends are both untouched in this pass, up to the
    /// limit; then only the edges around contracted vertices are re-keyed, de-duplicated and
    /// re-costed. This touches memory in order and avoids a priority queue of stale entries,
    /// which on a 270k-triangle mesh was eight times slower.
    fn pass(&mut self, limit: u32, max_removed: Option<u32>, check: bool) -> u32 {
        // The cheapest `3 * limit` edges are enough candidates for `limit` contractions in
        // all but degenerate cases; a short pass just means another pass.
        let k = (3 * limit as usize).min(self.edges.len());
        self.scratch.clear();
        self.scratch.extend_from_slice(&self.cost);
        let threshold = if k < self.scratch.len() { *self.scratch.select_nth_unstable_by(k, f32::total_cmp).1 } else { f32::INFINITY };
        self.order.clear();
        self.order.extend((0..self.edges.len() as u32).filter(|&i| self.cost[i as usize] <= threshold));
        let cost = &self.cost;
        self.order.sort_unstable_by(|&x, &y| cost[x as usize].total_cmp(&cost[y as usize]).then(x.cmp(&y)));
        let mut done = 0;
        self.changed.clear();
        for j in 0..self.order.len() {
            if done == limit {
                break;
            }
            let [u, v] = self.edges[self.order[j] as usize];
            if self.touched[u as usize] || self.touched[v as usize] {
                continue;
            }
            let removed = self.removed_by(u, v);
            if max_removed.is_some_and(|m| removed > m) {
                continue;
            }
            let mut merged = self.q[u as usize];
            merged += &self.q[v as usize];
            let p = merged.optimal();
            if check && !self.valid(u, v, p) {
                // Out of the way until its neighbourhood changes (re-keying re-costs it).
                self.cost[self.order[j] as usize] = f32::MAX;
                continue;
            }
            self.live_triangles -= removed;
            self.q[u as usize] = merged;
            self.pos[u as usize] = p;
            self.border[u as usize] |= self.border[v as usize];
            self.merged_into[v as usize] = u;
            let moved = std::mem::take(&mut self.around[v as usize]);
            self.around[u as usize].extend(moved);
            let mut list = std::mem::take(&mut self.around[u as usize]);
            list.retain(|&t| {
                let r = self.topo.triangles[t as usize].map(|c| crate::hierarchy::find(&mut self.merged_into, c));
                r[0] != r[1] && r[1] != r[2] && r[0] != r[2]
            });
            self.around[u as usize] = list;
            self.alive[v as usize] = false;
            self.touched[u as usize] = true;
            self.touched[v as usize] = true;
            self.changed.push(u);
            self.changed.push(v);
            done += 1;
        }
        self.live -= done;
        self.rekey();
        for &u in &self.changed {
            self.touched[u as usize] = false;
        }
        done
    }

    /// Re-keys the edges that touch a contracted pair; keeps the others in place.
    fn rekey(&mut self) {
        self.keys.clear();
        let mut w = 0;
        for i in 0..self.edges.len() {
            let [a, b] = self.edges[i];
            if self.touched[a as usize] || self.touched[b as usize] {
                let (a, b) = (self.merged_into[a as usize], self.merged_into[b as usize]);
                if a != b {
                    self.keys.push((((a.min(b) as u64) << 32) | a.max(b) as u64, i as u32));
                }
            } else {
                self.edges[w] = self.edges[i];
                self.cost[w] = self.cost[i];
                w += 1;
            }
        }
        self.edges.truncate(w);
        self.cost.truncate(w);
        self.keys.sort_unstable();
        self.keys.dedup_by_key(|k| k.0);
        for &(key, _) in &self.keys {
            let (a, b) = ((key >> 32) as u32, key as u32);
            self.edges.push([a, b]);
            self.cost.push(contraction_cost(&self.q[a as usize], &self.q[b as usize]));
        }
    }
}

/// Builds the multilevel mesh from the fine-vertex quadrics that define "error" for the base
/// hierarchy (frame 0's, or summed over frames: see [`crate::base`]).
///
/// Level anchors bind triangles: an anchored level is the coarsest state of the run that
/// still shows at least its share of the input's triangles (on a model of many small parts
/// the vertex share falls far slower than the triangle share, and a level sized by vertices
/// left a "25%" client short of its budget, reading the finest band). Levels after the last
/// anchor are `branching` times smaller in vertices each.
pub fn build(topo: &FineTopology, quadrics: &[Quadric], opts: &BuildOptions) -> Result<Hierarchy, BuildError> {
    let n = topo.vertex_count;
    if n == 0 {
        return Err(BuildError::Empty);
    }
    if quadrics.len() != n as usize {
        return Err(BuildError::QuadricCount(quadrics.len(), n));
    }
    let mut stops: Vec<Stop> = if opts.level_sizes.is_some() || opts.anchors.is_empty() {
        opts.targets(n)?.into_iter().map(Stop::Vertices).collect()
    } else {
        opts.anchor_triangles(topo.triangles.len() as u32)?.into_iter().map(Stop::Triangles).collect()
    };
    let branch_after_anchors = opts.level_sizes.is_none() && !opts.anchors.is_empty();
    let mut run = Run::new(topo, quadrics);
    let mut parents: Vec<Vec<u32>> = Vec::with_capacity(stops.len() + 8);
    let mut prev_reps: Vec<u32> = (0..n).collect();
    let mut level_index = vec![u32::MAX; n as usize];
    let mut i = 0;
    while i < stops.len() {
        let stop = stops[i];
        i += 1;
        while run.step(stop) > 0 {}
        if branch_after_anchors && i == stops.len() && matches!(stop, Stop::Triangles(_)) {
            stops.extend(opts.branch_sizes(run.live).into_iter().map(Stop::Vertices));
        }
        if (run.live as usize) >= prev_reps.len() {
            if matches!(stop, Stop::Triangles(_)) && !run.edges.is_empty() {
                // An anchor no contraction fits under (it is at or above this level's own
                // count): the next target decides.
                continue;
            }
            // Nothing left to contract (one vertex per connected component): the last level is
            // as coarse as the mesh allows.
            break;
        }
        let mut reps = Vec::with_capacity(run.live as usize);
        for (v, &a) in run.alive.iter().enumerate() {
            if a {
                level_index[v] = reps.len() as u32;
                reps.push(v as u32);
            }
        }
        let parent: Vec<u32> = prev_reps.iter().map(|&r| level_index[crate::hierarchy::find(&mut run.merged_into, r) as usize]).collect();
        parents.push(parent);
        prev_reps = reps;
        if let Stop::Vertices(t) = stop
            && run.live > t
        {
            break;
        }
    }
    Ok(Hierarchy::from_parents(opts.branching, n, parents))
}

/// Builds the hierarchy with one level at exactly `vertices` nodes; returns it and that level.
pub fn anchored_build(
    topo: &FineTopology,
    quadrics: &[crate::Quadric],
    vertices: u32,
    branching: u32,
) -> Result<(Hierarchy, usize), BuildError> {
    let b = if branching == 0 { 4 } else { branching };
    let sizes = anchored_sizes(topo.vertex_count, vertices, b, 8);
    let h = build(topo, quadrics, &BuildOptions { branching: b, level_sizes: Some(sizes.clone()), ..Default::default() })?;
    let level = h.level_sizes.iter().position(|&s| s == vertices).unwrap_or(0);
    Ok((h, level))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_shrink_by_branching() {
        let o = BuildOptions::default();
        assert_eq!(o.targets(8431).unwrap(), vec![2108, 527, 132, 33, 8]);
        assert!(BuildOptions { branching: 1, ..o.clone() }.targets(100).is_err());
        assert!(BuildOptions { level_sizes: Some(vec![50, 50]), ..o.clone() }.targets(100).is_err());
        // Anchored: at least 25% and 10% of the triangles, stopping below min_coarsest.
        let a = BuildOptions { anchors: vec![0.25, 0.1], ..o.clone() };
        assert_eq!(a.anchor_triangles(16843).unwrap(), vec![4211, 1685]);
        assert_eq!(a.anchor_triangles(40).unwrap(), vec![10]);
        assert_eq!(a.branch_sizes(843), vec![211, 53, 13]);
        assert!(BuildOptions { anchors: vec![0.1, 0.25], ..o.clone() }.anchor_triangles(1000).is_err());
        assert!(BuildOptions { anchors: vec![1.5], ..o.clone() }.anchor_triangles(1000).is_err());
    }

    #[test]
    fn anchored() {
        assert_eq!(anchored_sizes(8431, 800, 4, 8), vec![3200, 800, 200, 50, 12]);
    }
}
