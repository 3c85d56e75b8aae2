//! A bounding volume hierarchy over a mesh's triangles for closest-point queries.
//!
//! Layout: a binary tree in one flat `Vec` with `u32` links, where each entry is the *pair* of
//! children of an inner node: both boxes and both links in one 64-byte, 64-byte-aligned
//! record, so expanding a node reads exactly one cache line. Triangles are copied into leaf
//! order so a leaf reads contiguous memory.
//!
//! Build: median split on the axis where the triangles' box centres spread most. For
//! nearest-point queries on meshes this does about as well as a SAH split (which optimises for
//! rays), is simpler, and bounds the depth by log2 of the triangle count, which the fixed query
//! stack relies on.
//!
//! Query: depth first, nearer child first, pruning any box farther than the best triangle so
//! far, optionally starting from a hinted triangle to have a tight bound from the start.

use crate::triangle;
use crate::{EvalError, validate};
use glam::Vec3;
use pmcodec_mesh::TriMesh;

/// Most triangles in a leaf. Small leaves prune more, large ones make fewer, shallower nodes;
/// at 4 a leaf's triangles fill about two cache lines.
const LEAF_SIZE: usize = 4;

/// Query stack capacity. Median splits give the children of a subtree of `n > LEAF_SIZE`
/// triangles at most `ceil(n / 2)` each, so for any `u32` triangle count the depth is at most
/// `ceil(log2(2^32 / LEAF_SIZE)) + 1 = 31`, and a depth-first walk holds at most one pending
/// sibling per level plus the entry being expanded.
const STACK: usize = 64;

/// A subtree: a leaf (`count` triangles from slot `link`) or an inner node (`count == 0`, its
/// children described by pair `link`).
#[derive(Clone, Copy, Debug, Default)]
struct Child {
    link: u32,
    count: u32,
}

/// The two children of one inner node: boxes and links side by side in one cache line.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Pair {
    lo: [Vec3; 2],
    hi: [Vec3; 2],
    child: [Child; 2],
}

/// Squared distance from `p` to the box (0 inside). In `f32`: validated coordinates stay far
/// from overflow, and pruning allows for the rounding (see [`prune_above`]).
#[inline(always)]
fn box_distance2(lo: Vec3, hi: Vec3, p: Vec3) -> f32 {
    (lo - p).max(p - hi).max(Vec3::ZERO).length_squared()
}

/// A pending subtree on the query stack, with the distance to its box when it was pushed.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Pending {
    node: Child,
    d2: f32,
}

/// Query scratch space, reusable from one query to the next.
pub(crate) type Stack = [Pending; STACK];

pub(crate) fn new_stack() -> Stack {
    [Pending::default(); STACK]
}

/// Closest-point index over the surface of one mesh. Build it once per target mesh and query it
/// for every approximation compared against that mesh.
#[derive(Clone, Debug)]
pub struct SurfaceIndex {
    root: Child,
    root_lo: Vec3,
    root_hi: Vec3,
    pairs: Vec<Pair>,
    /// Triangle corners in leaf order.
    tris: Vec<[Vec3; 3]>,
    /// The mesh's index of each triangle in `tris`.
    ids: Vec<u32>,
    /// The slot in `tris` of each mesh triangle (the inverse of `ids`).
    slots: Vec<u32>,
}

/// Where the build writes a finished subtree: the root, or one side of a pair.
#[derive(Clone, Copy)]
enum Slot {
    Root,
    Pair(usize, usize),
}

/// Build-time record of one triangle.
#[derive(Clone, Copy)]
struct Item {
    lo: Vec3,
    hi: Vec3,
    centre: Vec3,
    id: u32,
}

impl SurfaceIndex {
    /// Indexes the triangles of `mesh`. Errors when it has no triangles, an index out of
    /// range, or a NaN, infinite or absurdly large (beyond 1e18) coordinate. Degenerate
    /// triangles are fine.
    pub fn new(mesh: &TriMesh) -> Result<Self, EvalError> {
        validate(mesh, "target")?;
        let mut items: Vec<Item> = mesh
            .triangles
            .iter()
            .enumerate()
            .map(|(id, t)| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
                // The box centre rather than the mean of the corners: boxes are what the query
                // tests, so it is their overlap a split should reduce.
                Item { lo, hi, centre: (lo + hi) * 0.5, id: id as u32 }
            })
            .collect();

        let bounds =
            |items: &[Item]| items.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), it| (lo.min(it.lo), hi.max(it.hi)));
        let (root_lo, root_hi) = bounds(&items);
        let mut pairs: Vec<Pair> = Vec::with_capacity(items.len().div_ceil(LEAF_SIZE));
        // Pending subtrees: where to write the finished `Child`, and their range of `items`.
        // Iterative, so no recursion depth to worry about.
        let mut root = Child::default();
        let mut work = vec![(Slot::Root, 0usize, items.len())];
        while let Some((slot, start, end)) = work.pop() {
            let range = &mut items[start..end];
            let child = if range.len() <= LEAF_SIZE {
                Child { link: start as u32, count: range.len() as u32 }
            } else {
                let (clo, chi) =
                    range.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), it| (lo.min(it.centre), hi.max(it.centre)));
                let spread = chi - clo;
                let axis = if spread.x >= spread.y && spread.x >= spread.z {
                    0
                } else if spread.y >= spread.z {
                    1
                } else {
                    2
                };
                // Split at the median even when all centres coincide: the halves then overlap
                // completely, but the depth bound the query stack needs still holds.
                let half = range.len() / 2;
                range.select_nth_unstable_by(half, |x, y| x.centre[axis].total_cmp(&y.centre[axis]));
                let (l, r) = (bounds(&range[..half]), bounds(&range[half..]));
                let index = pairs.len();
                pairs.push(Pair { lo: [l.0, r.0], hi: [l.1, r.1], child: [Child::default(); 2] });
                work.push((Slot::Pair(index, 1), start + half, end));
                work.push((Slot::Pair(index, 0), start, start + half));
                Child { link: index as u32, count: 0 }
            };
            match slot {
                Slot::Root => root = child,
                Slot::Pair(pair, side) => pairs[pair].child[side] = child,
            }
        }

        let tris = items.iter().map(|it| mesh.triangles[it.id as usize].map(|i| mesh.positions[i as usize])).collect();
        let ids: Vec<u32> = items.iter().map(|it| it.id).collect();
        let mut slots = vec![0u32; ids.len()];
        for (slot, &id) in ids.iter().enumerate() {
            slots[id as usize] = slot as u32;
        }
        Ok(SurfaceIndex { root, root_lo, root_hi, pairs, tris, ids, slots })
    }

    /// Number of indexed triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Squared distance from `p` to the closest point of the surface, and the index (in the
    /// mesh) of a triangle that point lies on. A NaN point gets `(inf, u32::MAX)`.
    pub fn closest(&self, p: Vec3) -> (f32, u32) {
        let (d2, slot) = self.query(p, None, &mut new_stack());
        (d2 as f32, self.ids.get(slot as usize).copied().unwrap_or(u32::MAX))
    }

    /// [`SurfaceIndex::closest`] starting from mesh triangle `near` (the answer for a nearby
    /// point, or for the same point on a slightly different surface; anything out of range is
    /// no hint): its distance bounds the walk from the start, so most of the tree is pruned.
    /// The same distance as `closest`; among triangles at exactly that distance, `near` is
    /// kept.
    pub fn closest_near(&self, p: Vec3, near: u32) -> (f32, u32) {
        let hint = self.slots.get(near as usize).copied();
        let (d2, slot) = self.query(p, hint, &mut new_stack());
        (d2 as f32, self.ids.get(slot as usize).copied().unwrap_or(u32::MAX))
    }

    /// Squared distance (in `f64`) and leaf slot of the closest triangle (`u32::MAX` and
    /// infinity when nothing is closer than infinity, i.e. for a NaN point). `hint` is a leaf
    /// slot to try first: the previous answer for a nearby point gives a tight bound before the
    /// walk starts, so most of the tree is pruned at once.
    pub(crate) fn query(&self, p: Vec3, hint: Option<u32>, stack: &mut Stack) -> (f64, u32) {
        let mut best = f64::INFINITY;
        let mut best_slot = u32::MAX;
        if let Some(h) = hint
            && let Some(t) = self.tris.get(h as usize)
        {
            best = triangle::distance2(p, t);
            best_slot = h;
        }
        let mut limit = prune_above(best);
        let mut top = 0usize;
        let d2 = box_distance2(self.root_lo, self.root_hi, p);
        if d2 <= limit {
            stack[0] = Pending { node: self.root, d2 };
            top = 1;
        }
        while top > 0 {
            top -= 1;
            let Pending { node, d2 } = stack[top];
            // The bound may have tightened since this entry was pushed.
            if d2 > limit {
                continue;
            }
            if node.count > 0 {
                for slot in node.link..node.link + node.count {
                    if slot == best_slot {
                        continue; // the hint, already measured
                    }
                    let t = &self.tris[slot as usize];
                    if box_distance2(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]), p) > limit {
                        continue;
                    }
                    let d = triangle::distance2_below(p, t, best);
                    if d < best {
                        best = d;
                        best_slot = slot;
                        limit = prune_above(best);
                    }
                }
                continue;
            }
            let pair = &self.pairs[node.link as usize];
            let d0 = box_distance2(pair.lo[0], pair.hi[0], p);
            let d1 = box_distance2(pair.lo[1], pair.hi[1], p);
            // Push the farther child first so the nearer one is expanded next: it is more
            // likely to hold the answer, and finding that early prunes the other.
            let (near, far) = if d0 <= d1 {
                (Pending { node: pair.child[0], d2: d0 }, Pending { node: pair.child[1], d2: d1 })
            } else {
                (Pending { node: pair.child[1], d2: d1 }, Pending { node: pair.child[0], d2: d0 })
            };
            for e in [far, near] {
                // `top < STACK` always holds (see STACK); the test only keeps this panic-free.
                if e.d2 <= limit && top < STACK {
                    stack[top] = e;
                    top += 1;
                }
            }
        }
        (best, best_slot)
    }
}

/// The box distance above which a subtree cannot hold anything closer than `best`. Box
/// distances are computed in `f32` and triangle distances in `f64`, so a box distance may come
/// out a few ulps above the true distance of a triangle inside it; the relative margin (far
/// larger than that rounding, far smaller than anything measurable) guarantees the closest
/// triangle is never pruned, so the answer equals a brute-force minimum exactly.
#[inline]
fn prune_above(best: f64) -> f32 {
    (best * (1.0 + 1e-5)) as f32
}
