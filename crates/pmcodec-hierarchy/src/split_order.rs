//! A frame's split order: the greedy refinement of the cut by split priority (Kircher & Garland
//! section 5.1's cut, grown from the coarsest one), recorded once so that the cut for any
//! triangle budget, vertex budget or error bound is a *prefix* of it.
//!
//! Split priorities are monotone (a node's is at least each child's, see
//! [`Replay::node_errors`]), so popping the frontier by priority visits nodes in non-increasing
//! priority: "every node above an error bound" is a prefix, and so is "as many splits as fit a
//! budget". The order grows lazily (a server asked for 500 triangles never orders the fine
//! levels), and a mesh for a prefix is read off in time proportional to the mesh: a triangle
//! appears with its degeneration node's split and never leaves, so the shown triangles are a
//! prefix of the triangles in order of appearance, and a corner's cut node is found by walking
//! up from it while the parent is not split.
//!
//! The order is a pure function of the hierarchy, the degenerate sets and the priorities:
//! ties go to the smaller node id and each split's triangles are taken in ascending order, so
//! two decoders at the same frame produce byte-identical meshes whatever their history.
//!
//! Two kinds of step ([`Steps`]): *whole splits* (a step splits node P, all its children
//! appear at once: what error bounds and, by default, budgets take) and *partial splits* (a
//! step reveals one child c of a revealed node P: what budgets take as an option,
//! proto/container.md "Partial splits", so a budget between two levels is a true partial
//! simplification). A partial cut is the set of revealed nodes, closed under parents (the top
//! level always revealed); a level-L vertex stands for its deepest revealed ancestor, and a
//! revealed node is drawn while a child of it is unrevealed, for those children. When a
//! reveal leaves P one unrevealed child, that child is revealed in the same step: P would
//! stand for that child's cluster alone, and the child's own decoded position is exact there
//! (one vertex more per step, none when the child was P's only one). A triangle of D_P shows
//! once at most one of the children of P holding its corners is unrevealed (before that two
//! of its corners stand for the same node); it never leaves, so shown triangles are still a
//! prefix of the order of appearance. Whole splits are the special case where every child of
//! P is revealed in one step.

use crate::NONE;
use crate::cut::ByError;
use crate::progressive::Replay;
use crate::target::CutTarget;
use glam::Vec3;
use pmcodec_mesh::TriMesh;
use std::collections::BinaryHeap;

/// What one step of a [`SplitOrder`] does (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Steps {
    /// A step splits a node: all its children appear; priorities are per split node
    /// ([`Replay::node_errors`]).
    #[default]
    WholeSplits,
    /// A step reveals one child of a revealed node (two when only one would be left);
    /// priorities are per revealed node ([`Replay::reveal_benefits_into`]).
    PartialSplits,
    /// Whole splits level-major: every splittable node of a level before any node of the
    /// finer level below it (within a level by priority, ties the smaller id), so every
    /// level's cut is a prefix and a budget at a level's count gets that level (issue #15).
    LevelSplits,
}

/// The split order of one frame (see the module docs). Built from a [`Replay`] and that
/// frame's priorities; it must be rebuilt when the replay moves to another frame.
#[derive(Clone, Debug, Default)]
pub struct SplitOrder {
    /// Whole or partial splits.
    steps: Steps,
    /// Frontier of the greedy refinement not yet ordered.
    heap: BinaryHeap<ByError>,
    /// Level-major whole splits: the finer level's candidates, held until the heap (the
    /// current level's) is empty.
    pending: Vec<ByError>,
    /// Position in the order of each split node (whole splits) or of each revealed node
    /// (partial splits), global ids; NONE while not (yet) ordered.
    rank: Vec<u32>,
    /// Per node (global id): its parent (global id) and the step that reveals the node (its
    /// parent's split, with whole splits), NONE for a top node or a step not (yet) ordered. A corner's walk up to its cut node reads one pair
    /// per level from this one array, instead of a per-level parent map and the rank array:
    /// the walk is a chain of dependent loads, and a server holding many frames' states
    /// mostly misses the caches on each of them.
    up: Vec<[u32; 2]>,
    /// The split nodes in order, and the priority of each (non-increasing for monotone
    /// priorities).
    order: Vec<u32>,
    priority: Vec<f64>,
    /// Shown triangles and cut nodes after the first i splits (one entry more than splits).
    shown_after: Vec<u32>,
    nodes_after: Vec<u32>,
    /// Triangles in order of appearance: those shown at the coarsest cut, then each split's.
    appearing: Vec<u32>,
    /// Their level-L corners, in the same order (read sequentially by `mesh`).
    appearing_corners: Vec<[u32; 3]>,
    /// Whether each triangle is in `appearing` (partial splits show a D set piecewise).
    appeared: Vec<bool>,
    /// Scratch of `mesh`: output index of each node, and of each level-L corner (a corner is
    /// walked up once per mesh however many triangles share it); NONE between calls.
    index: Vec<u32>,
    corner_index: Vec<u32>,
}

impl SplitOrder {
    /// The order's start: the coarsest cut (nothing split) of `replay`'s current frame, with
    /// whole splits by split priorities `errors`.
    pub fn new(replay: &Replay, errors: &[f64]) -> SplitOrder {
        let mut order = SplitOrder::default();
        order.reset(replay, errors);
        order
    }

    /// Starts the order again for `replay`'s current frame (whole splits), keeping the memory
    /// (a player that cuts every frame allocates nothing once its buffers have grown).
    pub fn reset(&mut self, replay: &Replay, errors: &[f64]) {
        self.reset_steps(replay, errors, Steps::WholeSplits);
    }

    /// Starts the order again for `replay`'s current frame with `steps`: `priorities` are per
    /// split node (whole splits) or per revealed node (partial splits).
    pub fn reset_steps(&mut self, replay: &Replay, priorities: &[f64], steps: Steps) {
        let errors = priorities;
        self.steps = steps;
        let h = &replay.h;
        let top = h.top();
        let nodes = h.node_count();
        let corners = replay.corners();
        self.appearing.clear();
        self.appearing_corners.clear();
        for (t, &g) in replay.degeneration().iter().enumerate() {
            if g == NONE {
                self.appearing.push(t as u32);
                self.appearing_corners.push(corners.get(t).copied().unwrap_or([NONE; 3]));
            }
        }
        self.appeared.clear();
        self.appeared.resize(corners.len(), false);
        self.heap.clear();
        self.pending.clear();
        let priority = |g: u32| ByError(errors.get(g as usize).copied().unwrap_or(0.0), g);
        let tops = (h.offsets[top]..h.offsets[top + 1]).filter(|&g| replay.expandable(g));
        match steps {
            Steps::WholeSplits | Steps::LevelSplits => self.heap.extend(tops.map(priority)),
            // The top level is always revealed: its children are the first candidates.
            Steps::PartialSplits => {
                for g in tops {
                    self.heap.extend(replay.children_of(g).iter().map(|&c| priority(c)));
                }
            }
        }
        // The parent maps change from frame to frame, so `up` is rebuilt over every node
        // anyway: ranks are too, in the same pass over memory.
        self.rank.clear();
        self.rank.resize(nodes, NONE);
        self.order.clear();
        self.priority.clear();
        self.up.clear();
        self.up.resize(nodes, [NONE; 2]);
        for level in replay.min_level..top {
            let (base, above) = (h.offsets[level] as usize, h.offsets[level + 1]);
            for (v, &p) in h.parent[level].iter().enumerate() {
                if let Some(up) = self.up.get_mut(base + v) {
                    up[0] = above + p;
                }
            }
        }
        self.shown_after.clear();
        self.shown_after.push(self.appearing.len() as u32);
        self.nodes_after.clear();
        self.nodes_after.push(h.level_sizes[top]);
        // Between calls of `mesh` the scratch holds NONE everywhere; only sizes can change.
        self.index.resize(nodes + 1, NONE);
        self.corner_index.resize(h.level_sizes[replay.min_level] as usize, NONE);
    }

    /// Steps (splits or reveals) ordered so far.
    pub fn len(&self) -> usize {
        self.priority.len()
    }

    /// Whether no split is recorded yet.
    pub fn is_empty(&self) -> bool {
        self.priority.is_empty()
    }

    /// The step that splits node `g` (whole splits) or reveals it (partial splits), if it has
    /// been ordered.
    pub fn rank(&self, g: u32) -> Option<u32> {
        self.rank.get(g as usize).copied().filter(|&r| r != NONE)
    }

    /// Orders one more step (false when every step is ordered).
    fn grow(&mut self, replay: &Replay, errors: &[f64]) -> bool {
        match self.steps {
            Steps::WholeSplits | Steps::LevelSplits => self.grow_split(replay, errors),
            Steps::PartialSplits => self.grow_reveal(replay, errors),
        }
    }

    /// Orders one more partial split: the candidate child with the highest priority is
    /// revealed (with P's last unrevealed child when only that one would be left), and the
    /// triangles of D_P that now have at most one corner in an unrevealed child appear.
    fn grow_reveal(&mut self, replay: &Replay, benefits: &[f64]) -> bool {
        // Candidates a step revealed as a last child are still in the heap: skipped here.
        let (priority, c) = loop {
            match self.heap.pop() {
                None => return false,
                Some(ByError(b, c)) if self.rank.get(c as usize) == Some(&NONE) => break (b, c),
                Some(_) => {}
            }
        };
        let i = self.priority.len() as u32;
        let p = self.up.get(c as usize).map_or(NONE, |u| u[0]);
        self.order.push(c);
        self.priority.push(priority);
        let mut revealed = [c, NONE];
        let mut left = replay.children_of(p).iter().filter(|&&x| x != c && self.rank.get(x as usize) == Some(&NONE));
        if let (Some(&last), None) = (left.next(), left.next()) {
            revealed[1] = last;
        }
        for &x in revealed.iter().filter(|&&x| x != NONE) {
            if let Some(r) = self.rank.get_mut(x as usize) {
                *r = i;
            }
            if let Some(up) = self.up.get_mut(x as usize) {
                up[1] = i;
            }
            if replay.expandable(x) {
                self.heap.extend(replay.children_of(x).iter().map(|&y| ByError(benefits.get(y as usize).copied().unwrap_or(0.0), y)));
            }
        }
        // Whether P is no longer drawn (every child of it revealed after this step).
        let done = !replay.children_of(p).iter().any(|&x| self.rank.get(x as usize) == Some(&NONE));
        let start = self.appearing.len();
        let levels = replay.h.levels();
        let base = replay.h.offsets[replay.min_level];
        let corners = replay.corners();
        for &t in replay.degenerate_set(p) {
            if self.appeared.get(t as usize) != Some(&false) {
                continue;
            }
            let Some(&c3) = corners.get(t as usize) else { continue };
            // Corners under P lie in distinct children (two in one child would meet below P).
            let hidden = c3
                .iter()
                .filter(|&&v| child_under(&self.up, base + v, p, levels).is_some_and(|x| self.rank.get(x as usize) == Some(&NONE)))
                .count();
            if hidden <= 1 {
                self.appeared[t as usize] = true;
                self.appearing.push(t);
            }
        }
        self.appearing[start..].sort_unstable();
        for i in start..self.appearing.len() {
            let t = self.appearing[i] as usize;
            self.appearing_corners.push(corners.get(t).copied().unwrap_or([NONE; 3]));
        }
        let (shown, cut) = (self.shown_after[i as usize], self.nodes_after[i as usize]);
        let added = if revealed[1] == NONE { 1 } else { 2 };
        self.shown_after.push(shown + (self.appearing.len() - start) as u32);
        self.nodes_after.push(cut + added - u32::from(done));
        true
    }

    /// Orders one more whole split (false when every splittable node is ordered).
    fn grow_split(&mut self, replay: &Replay, errors: &[f64]) -> bool {
        // Level-major: a level's candidates are all in `pending` once the coarser level is
        // exhausted (its nodes' children are all of that level).
        if self.heap.is_empty() {
            self.heap.extend(self.pending.drain(..));
        }
        let Some(ByError(priority, g)) = self.heap.pop() else { return false };
        let i = self.priority.len() as u32;
        self.rank[g as usize] = i;
        self.order.push(g);
        self.priority.push(priority);
        let set = replay.degenerate_set(g);
        let start = self.appearing.len();
        self.appearing.extend_from_slice(set);
        // D sets are kept unordered by the replay; ascending order makes the mesh canonical.
        self.appearing[start..].sort_unstable();
        let corners = replay.corners();
        for i in start..self.appearing.len() {
            let t = self.appearing[i] as usize;
            self.appearing_corners.push(corners.get(t).copied().unwrap_or([NONE; 3]));
        }
        let children = replay.children_of(g);
        for &c in children {
            if let Some(up) = self.up.get_mut(c as usize) {
                up[1] = i;
            }
        }
        let (shown, cut) = (self.shown_after[i as usize], self.nodes_after[i as usize]);
        self.shown_after.push(shown + set.len() as u32);
        self.nodes_after.push(cut + (children.len() as u32).saturating_sub(1));
        let level_major = self.steps == Steps::LevelSplits;
        for &c in children {
            if replay.expandable(c) {
                let e = ByError(errors.get(c as usize).copied().unwrap_or(0.0), c);
                if level_major { self.pending.push(e) } else { self.heap.push(e) }
            }
        }
        true
    }

    /// The length of the prefix `target` selects, ordering more splits as needed: the longest
    /// prefix within a triangle or vertex budget, or every split whose priority exceeds a
    /// [`CutTarget::MaxError`] (a diagonal fraction is of `diagonal`). `Err(level)` for a
    /// [`CutTarget::Level`], which is a cut of the replay ([`Replay::select_level`]), not a
    /// prefix.
    pub fn prefix(&mut self, replay: &Replay, errors: &[f64], target: CutTarget, diagonal: f64) -> Result<usize, usize> {
        enum Bound {
            Triangles(u32),
            Vertices(u32),
            Priority(f64),
        }
        let bound = match target {
            CutTarget::Triangles(n) => Bound::Triangles(n),
            CutTarget::Vertices(n) => Bound::Vertices(n),
            CutTarget::MaxError(d) => Bound::Priority(d.in_model_units(diagonal)),
            CutTarget::Level(l) => return Err(l),
        };
        // The prefix is known once the order reaches past it (or ends): grow until the next
        // split would break the target.
        let fits = |o: &SplitOrder, i: usize| match bound {
            Bound::Triangles(n) => o.shown_after[i + 1] <= n,
            Bound::Vertices(n) => o.nodes_after[i + 1] <= n,
            Bound::Priority(e) => o.priority[i] > e,
        };
        // Budgets: the counts after each split never decrease, so the first split that breaks
        // the budget within the order grown so far is found by bisection (a warm frame answers
        // every budget without rescanning its order). Error bounds scan: their monotonicity
        // rests on the caller's priorities.
        let mut k = match bound {
            Bound::Triangles(n) => self.shown_after[1..].partition_point(|&x| x <= n),
            Bound::Vertices(n) => self.nodes_after[1..].partition_point(|&x| x <= n),
            Bound::Priority(_) => 0,
        };
        loop {
            if k == self.priority.len() && !self.grow(replay, errors) {
                return Ok(k);
            }
            if !fits(self, k) {
                return Ok(k);
            }
            k += 1;
        }
    }

    /// Triangles shown after the first `k` splits.
    pub fn shown(&self, k: usize) -> &[u32] {
        let k = k.min(self.priority.len());
        &self.appearing[..self.shown_after[k] as usize]
    }

    /// The cut node standing for level-L node `v` (local id) after the first `k` splits: its
    /// highest ancestor whose parent is split, or its top-level ancestor.
    #[inline]
    pub fn cut_node_of(&self, replay: &Replay, v: u32, k: usize) -> u32 {
        cut_node_of(&self.up, replay, v, k)
    }

    /// The mesh after the first `k` splits: triangles in order of appearance (coarse first),
    /// vertices in order of first use, positions from `positions` (global ids).
    pub fn mesh(&mut self, replay: &Replay, positions: &[Vec3], k: usize) -> TriMesh {
        let mut mesh = TriMesh::default();
        self.mesh_into(replay, positions, k, &mut mesh);
        mesh
    }

    /// [`SplitOrder::mesh`] into `mesh`'s buffers (whatever they held is replaced): a caller
    /// that cuts again and again allocates nothing once they have grown.
    pub fn mesh_into(&mut self, replay: &Replay, positions: &[Vec3], k: usize, mesh: &mut TriMesh) {
        let k = k.min(self.priority.len());
        let shown = &self.appearing_corners[..self.shown_after[k] as usize];
        let size = replay.h.level_sizes[replay.min_level];
        let nodes = self.index.len() as u32 - 1;
        mesh.positions.clear();
        mesh.triangles.clear();
        mesh.triangles.reserve(shown.len());
        mesh.positions.reserve(shown.len() / 2 + 3);
        // Node ids put in `index`, level-L corners put in `corner_index`: reset after the pass
        // (the mesh's vertex count bounds both).
        let mut used: Vec<u32> = Vec::with_capacity(shown.len() / 2 + 3);
        let mut seen: Vec<u32> = Vec::with_capacity(shown.len() / 2 + 3);
        for c in shown {
            let mut tri = [0u32; 3];
            for (slot, &x) in tri.iter_mut().zip(c) {
                // Most corners were met in an earlier triangle of this mesh.
                *slot = match self.corner_index.get(x as usize) {
                    Some(&s) if s != NONE => s,
                    _ => {
                        // A corner beyond the level (a corrupt state) stands for one slot past
                        // the end, drawn at the origin.
                        let g = if x < size { cut_node_of(&self.up, replay, x, k) } else { nodes };
                        let s = &mut self.index[g as usize];
                        if *s == NONE {
                            *s = used.len() as u32;
                            used.push(g);
                            mesh.positions.push(positions.get(g as usize).copied().unwrap_or(Vec3::ZERO));
                        }
                        let s = *s;
                        if let Some(c) = self.corner_index.get_mut(x as usize) {
                            *c = s;
                            seen.push(x);
                        }
                        s
                    }
                };
            }
            mesh.triangles.push(tri);
        }
        for g in used {
            self.index[g as usize] = NONE;
        }
        for x in seen {
            self.corner_index[x as usize] = NONE;
        }
    }
}

/// The child of `p` on the way up from node `g` (global ids), if `p` is an ancestor of `g`.
#[inline]
fn child_under(up: &[[u32; 2]], mut g: u32, p: u32, levels: usize) -> Option<u32> {
    // At most `levels` steps: a corrupt map cannot loop.
    for _ in 0..levels {
        let parent = up.get(g as usize)?[0];
        if parent == p {
            return Some(g);
        }
        if parent == NONE {
            return None;
        }
        g = parent;
    }
    None
}

/// See [`SplitOrder::cut_node_of`]: walks up while the node's reveal is not before step `k`.
#[inline]
fn cut_node_of(up: &[[u32; 2]], replay: &Replay, v: u32, k: usize) -> u32 {
    let mut g = replay.h.offsets[replay.min_level] + v;
    // Each step goes one level up, so a corrupt map cannot loop: at most `levels` steps.
    for _ in 0..replay.h.levels() {
        match up.get(g as usize) {
            Some(&[p, rank]) if p != NONE && (rank as usize) >= k => g = p,
            _ => break,
        }
    }
    g
}
