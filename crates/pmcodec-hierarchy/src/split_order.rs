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

use crate::NONE;
use crate::cut::ByError;
use crate::progressive::Replay;
use crate::target::CutTarget;
use glam::Vec3;
use pmcodec_mesh::TriMesh;
use std::collections::BinaryHeap;

/// The split order of one frame (see the module docs). Built from a [`Replay`] and that
/// frame's priorities; it must be rebuilt when the replay moves to another frame.
#[derive(Clone, Debug, Default)]
pub struct SplitOrder {
    /// Frontier of the greedy refinement not yet ordered.
    heap: BinaryHeap<ByError>,
    /// Position in the order of each split node (global id); NONE while not (yet) ordered.
    rank: Vec<u32>,
    /// Per node (global id): its parent (global id) and the parent's rank, NONE for a top
    /// node or a parent not (yet) ordered. A corner's walk up to its cut node reads one pair
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
    /// Scratch of `mesh`: output index of each node, and of each level-L corner (a corner is
    /// walked up once per mesh however many triangles share it); NONE between calls.
    index: Vec<u32>,
    corner_index: Vec<u32>,
}

impl SplitOrder {
    /// The order's start: the coarsest cut (nothing split) of `replay`'s current frame.
    pub fn new(replay: &Replay, errors: &[f64]) -> SplitOrder {
        let mut order = SplitOrder::default();
        order.reset(replay, errors);
        order
    }

    /// Starts the order again for `replay`'s current frame, keeping the memory (a player that
    /// cuts every frame allocates nothing once its buffers have grown).
    pub fn reset(&mut self, replay: &Replay, errors: &[f64]) {
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
        self.heap.clear();
        self.heap.extend(
            (h.offsets[top]..h.offsets[top + 1])
                .filter(|&g| replay.expandable(g))
                .map(|g| ByError(errors.get(g as usize).copied().unwrap_or(0.0), g)),
        );
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

    /// Splits ordered so far.
    pub fn len(&self) -> usize {
        self.priority.len()
    }

    /// Whether no split is recorded yet.
    pub fn is_empty(&self) -> bool {
        self.priority.is_empty()
    }

    /// Position of node `g` in the order, if it has been ordered.
    pub fn rank(&self, g: u32) -> Option<u32> {
        self.rank.get(g as usize).copied().filter(|&r| r != NONE)
    }

    /// Orders one more split (false when every splittable node is ordered).
    fn grow(&mut self, replay: &Replay, errors: &[f64]) -> bool {
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
        for &c in children {
            if replay.expandable(c) {
                self.heap.push(ByError(errors.get(c as usize).copied().unwrap_or(0.0), c));
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

/// See [`SplitOrder::cut_node_of`]: walks up while the parent's rank is not below `k`.
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
