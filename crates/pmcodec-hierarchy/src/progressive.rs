//! The progressive representation (section 5): a keyframe holding a whole hierarchy H_f, then
//! per frame the swaps and degenerate-set deltas that turn H_{f-1} into H_f. [`Encoder`]
//! produces it; [`Replay`] plays it back and keeps a cut's shown triangles up to date
//! incrementally (section 5.1), without re-deriving them from scratch.
//!
//! The degenerate-set deltas are a function of the swaps: a triangle's degeneration node is
//! where two of its corners' ancestor chains first meet, and a swap of node v changes only the
//! chains of the triangles with a corner under v. So a replay *derives* them, for just those
//! triangles, and a stream needs to carry only the swaps (the paper's "swaps only" figure,
//! section 6); [`Encoder::degeneration`] gives the encoder's side of them, for measurement and
//! tests.
//!
//! Everything is organised by *band*: band j is what a client needs to refine down to level j.
//! A client that stops at level L reads bands top..=L only, so what it reads grows with |M_L|:
//! - swaps of level-j nodes are in band j;
//! - corner updates: a triangle *alive at level j* (its corners have three distinct level-j
//!   ancestors) is drawn by a level-j client through its level-j corners; when those change
//!   (swaps at finer levels, invisible to that client), band j carries the new corners, also
//!   when the triangle becomes alive at j or stops being alive (then the new corners repeat a
//!   node). Only a client whose finest level is exactly j needs them. Level-0 corners are the
//!   input triangles and never change.
//!
//! Convention: frame 0 has a delta too (reclustering the built base to fit frame 0), so the
//! hierarchy of frame f is the base plus the deltas of frames 0..=f; the keyframe of frame f is
//! the state after frame f's delta.

use crate::Hierarchy;
use crate::degenerate::degeneration_nodes;
use crate::hierarchy::NONE;
use crate::nodes::NodeState;
use crate::recluster::{FrameStats, ReclusterOptions, Reclusterer, Swap};
use crate::topology::FineTopology;
use glam::Vec3;

/// Sentinel degeneration node of a triangle that is not alive at a replay's finest level (its
/// node lies at or below that level, which such a replay does not track).
pub const BELOW: u32 = u32::MAX - 1;

/// New level-`level` corners of triangle `t` (two equal corners: t is no longer alive there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CornerUpdate {
    pub level: u32,
    pub t: u32,
    pub corners: [u32; 3],
}

/// What turns H_{f-1} into H_f.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameDelta {
    /// Swaps in the order they were made (coarse levels first).
    pub swaps: Vec<Swap>,
    /// Corner updates, by level then triangle.
    pub corners: Vec<CornerUpdate>,
}

/// Level of a global node id, with level(NONE) = top + 1.
#[inline]
pub fn node_level(h: &Hierarchy, g: u32) -> usize {
    if g == NONE { h.levels() } else { h.local(g).0 }
}

impl FrameDelta {
    /// The parts of this delta in bands `min_level..`.
    pub fn from_level(&self, min_level: usize) -> FrameDelta {
        FrameDelta {
            swaps: self.swaps.iter().filter(|s| s.level as usize >= min_level).copied().collect(),
            corners: self.corners.iter().filter(|c| c.level as usize >= min_level).copied().collect(),
        }
    }
}

/// One band of a keyframe: level j's parent map and the triangles alive at level j with their
/// level-j corners (empty for band 0, whose corners are the input triangles).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KeyBand {
    pub parent: Vec<u32>,
    pub faces: Vec<(u32, [u32; 3])>,
}

/// A whole hierarchy, by band (index = level).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Keyframe {
    pub bands: Vec<KeyBand>,
}

/// Produces frame deltas and keyframes by reclustering.
pub struct Encoder {
    recluster: Reclusterer,
    /// Degeneration node of every triangle in H_f, derived on first request: the stream does not
    /// carry them (see the module docs), so only measurement and tests pay for them.
    node_of: std::sync::OnceLock<Vec<u32>>,
    /// Level-j ancestors of every triangle's corners, for j >= 1 (alive at j iff distinct).
    corners: Vec<Vec<[u32; 3]>>,
}

impl Encoder {
    pub fn new(base: Hierarchy, topo: FineTopology, triangles: Vec<[u32; 3]>, opts: ReclusterOptions) -> Self {
        let mut enc =
            Encoder { recluster: Reclusterer::new(base, topo, triangles, opts), node_of: Default::default(), corners: Vec::new() };
        enc.corners = enc.current_corners();
        enc
    }

    /// The current hierarchy H_f.
    pub fn hierarchy(&self) -> &Hierarchy {
        self.recluster.hierarchy()
    }

    /// Every node's quadric and position in H_f for the frame last encoded.
    pub fn nodes(&self) -> &NodeState {
        self.recluster.nodes()
    }

    /// Positions of every node of H_f (global ids) in the frame last encoded: level 0 is that
    /// frame's input, coarser nodes sit at their quadric-optimal positions.
    pub fn node_positions(&self) -> &[Vec3] {
        &self.recluster.nodes().positions
    }

    /// Degeneration node of every triangle in H_f.
    pub fn degeneration(&self) -> &[u32] {
        self.node_of.get_or_init(|| {
            let mut node_of = Vec::new();
            degeneration_nodes(self.recluster.hierarchy(), self.recluster.triangles(), &mut node_of);
            node_of
        })
    }

    /// Level-j ancestors of every triangle's corners, j >= 1 (distinct iff alive at j).
    pub fn corners_at(&self, j: usize) -> &[[u32; 3]] {
        &self.corners[j]
    }

    fn current_corners(&self) -> Vec<Vec<[u32; 3]>> {
        let h = self.recluster.hierarchy();
        let anc = h.all_ancestors();
        let tris = self.recluster.triangles();
        let mut out = vec![Vec::new()];
        for anc_j in anc.iter().skip(1) {
            out.push(tris.iter().map(|t| t.map(|v| anc_j[v as usize])).collect());
        }
        out
    }

    /// Reclusters for the next frame and returns its delta.
    pub fn encode_frame(&mut self, positions: &[Vec3]) -> (FrameDelta, FrameStats) {
        let mut delta = FrameDelta::default();
        let stats = self.recluster.frame(positions, &mut delta.swaps);
        self.node_of = Default::default();
        let corners = self.current_corners();
        for (j, (now, before)) in corners.iter().zip(&self.corners).enumerate().skip(1) {
            for (t, (c, b)) in now.iter().zip(before).enumerate() {
                if c != b && (distinct(*c) || distinct(*b)) {
                    delta.corners.push(CornerUpdate { level: j as u32, t: t as u32, corners: *c });
                }
            }
        }
        self.corners = corners;
        (delta, stats)
    }

    /// The current state as a keyframe.
    pub fn keyframe(&self) -> Keyframe {
        let h = self.recluster.hierarchy();
        let bands = (0..h.levels())
            .map(|j| KeyBand {
                parent: h.parent.get(j).cloned().unwrap_or_default(),
                faces: if j == 0 {
                    Vec::new()
                } else {
                    self.corners[j].iter().enumerate().filter(|(_, c)| distinct(**c)).map(|(t, c)| (t as u32, *c)).collect()
                },
            })
            .collect();
        Keyframe { bands }
    }
}

/// Whether three corners are three different nodes (the triangle is alive at their level).
#[inline]
pub fn distinct(c: [u32; 3]) -> bool {
    c[0] != c[1] && c[1] != c[2] && c[0] != c[2]
}

/// Triangles by level-L corner: a flat list per node built at a keyframe (CSR), plus the
/// additions corner updates make until the next keyframe. Removals are not recorded: a reader
/// checks that the triangle still has that corner. (Thousands of small vectors made keyframe
/// loads, and so seeks, a tenth slower.)
#[derive(Clone, Debug, Default)]
struct Incidence {
    offsets: Vec<u32>,
    list: Vec<u32>,
    extra: std::collections::HashMap<u32, Vec<u32>>,
}

impl Incidence {
    /// Over `size` nodes, from every triangle whose corners are distinct.
    fn new(size: usize, corners: &[[u32; 3]]) -> Self {
        let alive = |c: &[u32; 3]| c[0] != NONE && distinct(*c);
        let mut offsets = vec![0u32; size + 1];
        for c in corners.iter().filter(|c| alive(c)) {
            for &x in c {
                offsets[x as usize + 1] += 1;
            }
        }
        for i in 0..size {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut list = vec![0u32; offsets[size] as usize];
        for (t, c) in corners.iter().enumerate().filter(|(_, c)| alive(c)) {
            for &x in c {
                list[fill[x as usize] as usize] = t as u32;
                fill[x as usize] += 1;
            }
        }
        Incidence { offsets, list, extra: Default::default() }
    }

    fn add(&mut self, x: u32, t: u32) {
        self.extra.entry(x).or_default().push(t);
    }

    /// Triangles that have, or had, corner x (callers filter stale entries).
    fn of(&self, x: u32) -> (&[u32], &[u32]) {
        let (a, b) = (self.offsets[x as usize] as usize, self.offsets[x as usize + 1] as usize);
        (&self.list[a..b], self.extra.get(&x).map_or(&[], Vec::as_slice))
    }
}

/// Data that does not fit the hierarchy it is applied to.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum DeltaError {
    #[error("swap {index}: level {level} has no node {v} or no cluster {to} above it")]
    SwapOutOfRange { index: usize, level: u32, v: u32, to: u32 },
    #[error("swap {index}: node {v} of level {level} is in cluster {actual}, not {from}")]
    SwapMismatch { index: usize, level: u32, v: u32, from: u32, actual: u32 },
    #[error("swap {index}: cluster {from} of level {} would be left empty", level + 1)]
    EmptyCluster { index: usize, level: u32, from: u32 },
    #[error("corner update {index}: triangle {triangle} or a corner out of range at level {level}")]
    CornerOutOfRange { index: usize, level: u32, triangle: u32 },
    #[error("keyframe: {0}")]
    Keyframe(String),
}

/// Plays back a progressive representation down to a finest level `L` and maintains one cut.
///
/// The cut is the set of expanded nodes (levels L+1 and up), closed upward. The shown triangles
/// are kept as a dense list (ready to become an index buffer) with each triangle's slot, so
/// showing and hiding are O(1). A triangle whose degeneration node changes is shown or hidden
/// according to whether its new node is expanded; a swap that hangs an expanded node under an
/// unexpanded one collapses that node's subtree so the cut stays closed (section 5.1 leaves the
/// policy open; collapsing never raises the triangle count).
#[derive(Clone, Debug)]
pub struct Replay {
    pub h: Hierarchy,
    /// Finest level this replay tracks.
    pub min_level: usize,
    /// Level-L corners of every triangle (`[NONE; 3]` or a repeated node where not alive).
    corners: Vec<[u32; 3]>,
    /// For every level-L node (local id), the triangles alive at L with a corner there.
    incident: Incidence,
    node_of: Vec<u32>,
    /// Scratch of `apply`: triangles whose degeneration node may have changed, and a mark per
    /// triangle so each is listed once.
    affected: Vec<u32>,
    marked: Vec<bool>,
    /// D sets per node (global id), unordered, and each triangle's slot in its set.
    sets: Vec<Vec<u32>>,
    slot_in_set: Vec<u32>,
    children: Vec<Vec<u32>>,
    expanded: Vec<bool>,
    shown: Vec<u32>,
    slot_in_shown: Vec<u32>,
}

impl Replay {
    /// Makes this replay a copy of `other`, reusing this one's buffers (a decoder restoring
    /// a kept keyframe state does this on every seek back; a fresh clone would allocate every
    /// node's set and child list again).
    pub fn copy_from(&mut self, other: &Replay) {
        self.h.clone_from(&other.h);
        self.min_level = other.min_level;
        self.corners.clone_from(&other.corners);
        self.incident.offsets.clone_from(&other.incident.offsets);
        self.incident.list.clone_from(&other.incident.list);
        self.incident.extra.clone_from(&other.incident.extra);
        self.node_of.clone_from(&other.node_of);
        self.affected.clone_from(&other.affected);
        self.marked.clone_from(&other.marked);
        self.sets.clone_from(&other.sets);
        self.slot_in_set.clone_from(&other.slot_in_set);
        self.children.clone_from(&other.children);
        self.expanded.clone_from(&other.expanded);
        self.shown.clone_from(&other.shown);
        self.slot_in_shown.clone_from(&other.slot_in_shown);
    }

    /// A full-resolution replay (L = 0) starting at hierarchy `h`.
    pub fn new(h: Hierarchy, triangles: &[[u32; 3]]) -> Self {
        let mut r = Self::empty(h, 0, triangles.len());
        r.corners = triangles.to_vec();
        r.rebuild();
        r
    }

    /// A replay down to level `min_level` from a keyframe. `level_sizes` comes from the
    /// container header; `triangles` (the input triangles) is needed only when `min_level` is 0.
    pub fn from_keyframe(
        level_sizes: &[u32],
        branching: u32,
        key: &Keyframe,
        min_level: usize,
        triangle_count: usize,
        triangles: Option<&[[u32; 3]]>,
    ) -> Result<Self, DeltaError> {
        let levels = level_sizes.len();
        if levels == 0 || min_level >= levels || key.bands.len() != levels {
            return Err(DeltaError::Keyframe(format!("{} bands for {levels} levels, finest level {min_level}", key.bands.len())));
        }
        // Parent maps below min_level are unknown to this replay: map every node to 0 there so
        // the structure stays well formed; nothing reads them.
        let mut parent = Vec::with_capacity(levels - 1);
        for j in 0..levels - 1 {
            let p = if j >= min_level {
                let p = &key.bands[j].parent;
                if p.len() != level_sizes[j] as usize || p.iter().any(|&x| x >= level_sizes[j + 1]) {
                    return Err(DeltaError::Keyframe(format!("band {j}: parent map does not fit the level sizes")));
                }
                p.clone()
            } else {
                vec![0; level_sizes[j] as usize]
            };
            parent.push(p);
        }
        let mut h = Hierarchy::from_parents(branching, level_sizes[0], parent);
        h.level_sizes = level_sizes.to_vec();
        h.offsets = std::iter::once(0)
            .chain(level_sizes.iter().scan(0u32, |acc, &s| {
                *acc = acc.saturating_add(s);
                Some(*acc)
            }))
            .collect();
        let mut r = Self::empty(h, min_level, triangle_count);
        r.fill_corners(key, triangles)?;
        r.rebuild();
        Ok(r)
    }

    /// Loads another keyframe of the same file into this replay, reusing its memory (a seek
    /// that crosses keyframes then allocates almost nothing). Same checks as [`Self::from_keyframe`];
    /// on error the replay is left unusable until a keyframe loads.
    pub fn reload(&mut self, key: &Keyframe, triangles: Option<&[[u32; 3]]>) -> Result<(), DeltaError> {
        let (levels, min_level) = (self.h.levels(), self.min_level);
        if key.bands.len() != levels {
            return Err(DeltaError::Keyframe(format!("{} bands for {levels} levels", key.bands.len())));
        }
        for j in min_level..levels - 1 {
            let p = &key.bands[j].parent;
            if p.len() != self.h.level_sizes[j] as usize || p.iter().any(|&x| x >= self.h.level_sizes[j + 1]) {
                return Err(DeltaError::Keyframe(format!("band {j}: parent map does not fit the level sizes")));
            }
            self.h.parent[j].copy_from_slice(p);
        }
        self.corners.iter_mut().for_each(|c| *c = [NONE; 3]);
        self.fill_corners(key, triangles)?;
        self.rebuild();
        Ok(())
    }

    /// Level-L corners from the input triangles (L = 0) or the keyframe's faces.
    fn fill_corners(&mut self, key: &Keyframe, triangles: Option<&[[u32; 3]]>) -> Result<(), DeltaError> {
        let (min_level, triangle_count) = (self.min_level, self.corners.len());
        if min_level == 0 {
            let tris = triangles.ok_or_else(|| DeltaError::Keyframe("level 0 needs the input triangles".into()))?;
            if tris.len() != triangle_count || tris.iter().flatten().any(|&v| v >= self.h.level_sizes[0]) {
                return Err(DeltaError::Keyframe("input triangles do not fit the header".into()));
            }
            self.corners.copy_from_slice(tris);
        } else {
            let size = self.h.level_sizes[min_level];
            for &(t, c) in &key.bands[min_level].faces {
                if t as usize >= triangle_count || c.iter().any(|&x| x >= size) {
                    return Err(DeltaError::Keyframe(format!("band {min_level}: face of triangle {t} out of range")));
                }
                self.corners[t as usize] = c;
            }
        }
        Ok(())
    }

    fn empty(h: Hierarchy, min_level: usize, triangle_count: usize) -> Self {
        let total = h.node_count();
        Replay {
            h,
            min_level,
            corners: vec![[NONE; 3]; triangle_count],
            incident: Incidence::default(),
            node_of: vec![BELOW; triangle_count],
            affected: Vec::new(),
            marked: vec![false; triangle_count],
            sets: vec![Vec::new(); total],
            slot_in_set: vec![NONE; triangle_count],
            children: vec![Vec::new(); total],
            expanded: vec![false; total],
            shown: Vec::new(),
            slot_in_shown: vec![NONE; triangle_count],
        }
    }

    /// Degeneration node of triangle t from its level-L corners and the parent maps: the node
    /// where two corners' ancestor chains first meet ([`NONE`] if they never do, [`BELOW`] if
    /// they meet at L already, i.e. t is not alive here).
    fn degeneration_of(&self, t: usize) -> u32 {
        let h = &self.h;
        let [mut x, mut y, mut z] = self.corners[t];
        if x == NONE || !distinct([x, y, z]) {
            return BELOW;
        }
        for k in self.min_level..h.levels() - 1 {
            let p = &h.parent[k];
            (x, y, z) = (p[x as usize], p[y as usize], p[z as usize]);
            if x == y || x == z {
                return h.offsets[k + 1] + x;
            }
            if y == z {
                return h.offsets[k + 1] + y;
            }
        }
        NONE
    }

    /// Derives degeneration nodes, D sets, incidence and children from corners and parent
    /// maps, with the coarsest cut.
    fn rebuild(&mut self) {
        let h = &self.h;
        let l = self.min_level;
        for t in 0..self.corners.len() {
            self.node_of[t] = self.degeneration_of(t);
        }
        self.incident = Incidence::new(h.level_sizes[l] as usize, &self.corners);
        self.affected.clear();
        self.marked.iter_mut().for_each(|m| *m = false);
        for s in &mut self.sets {
            s.clear();
        }
        for (t, &g) in self.node_of.iter().enumerate() {
            if g != NONE && g != BELOW {
                self.slot_in_set[t] = self.sets[g as usize].len() as u32;
                self.sets[g as usize].push(t as u32);
            }
        }
        for c in &mut self.children {
            c.clear();
        }
        for k in l..h.levels() - 1 {
            for (v, &p) in h.parent[k].iter().enumerate() {
                self.children[(h.offsets[k + 1] + p) as usize].push(h.offsets[k] + v as u32);
            }
        }
        self.expanded.iter_mut().for_each(|e| *e = false);
        self.shown.clear();
        self.slot_in_shown.iter_mut().for_each(|s| *s = NONE);
        for t in 0..self.node_of.len() {
            if self.node_of[t] == NONE {
                self.show(t as u32);
            }
        }
    }

    /// Degeneration node of every triangle ([`BELOW`] for triangles not alive at `min_level`).
    pub fn degeneration(&self) -> &[u32] {
        &self.node_of
    }

    /// Level-`min_level` corners of every triangle alive there.
    pub fn corners(&self) -> &[[u32; 3]] {
        &self.corners
    }

    /// The shown triangles (unordered).
    pub fn shown(&self) -> &[u32] {
        &self.shown
    }

    /// Whether triangle t is shown.
    #[inline]
    pub fn is_shown(&self, t: u32) -> bool {
        self.slot_in_shown.get(t as usize).is_some_and(|&s| s != NONE)
    }

    pub fn expanded(&self) -> &[bool] {
        &self.expanded
    }

    pub fn degenerate_set(&self, g: u32) -> &[u32] {
        &self.sets[g as usize]
    }

    pub fn children_of(&self, g: u32) -> &[u32] {
        &self.children[g as usize]
    }

    /// Whether node g can be expanded here (its children are at `min_level` or above).
    #[inline]
    pub fn expandable(&self, g: u32) -> bool {
        g >= self.h.offsets[self.min_level + 1]
    }

    #[inline]
    fn show(&mut self, t: u32) {
        if self.slot_in_shown[t as usize] == NONE {
            self.slot_in_shown[t as usize] = self.shown.len() as u32;
            self.shown.push(t);
        }
    }

    #[inline]
    fn hide(&mut self, t: u32) {
        let slot = self.slot_in_shown[t as usize];
        if slot != NONE {
            self.shown.swap_remove(slot as usize);
            if let Some(&moved) = self.shown.get(slot as usize) {
                self.slot_in_shown[moved as usize] = slot;
            }
            self.slot_in_shown[t as usize] = NONE;
        }
    }

    /// Expands node g (and, to keep the cut closed, its unexpanded ancestors).
    pub fn expand(&mut self, g: u32) {
        let mut x = g;
        while x != NONE && self.expandable(x) && !self.expanded[x as usize] {
            self.expanded[x as usize] = true;
            for i in 0..self.sets[x as usize].len() {
                let t = self.sets[x as usize][i];
                self.show(t);
            }
            x = self.h.parent_global(x);
        }
    }

    /// Collapses node g and every expanded node below it.
    pub fn collapse(&mut self, g: u32) {
        let mut stack = vec![g];
        while let Some(x) = stack.pop() {
            if !self.expanded[x as usize] {
                continue;
            }
            self.expanded[x as usize] = false;
            for i in 0..self.sets[x as usize].len() {
                let t = self.sets[x as usize][i];
                self.hide(t);
            }
            stack.extend_from_slice(&self.children[x as usize]);
        }
    }

    /// Replaces the cut by `expanded` (closed upward; entries at or below `min_level` ignored).
    pub fn set_cut(&mut self, expanded: &[bool]) {
        for (g, &wanted) in expanded.iter().enumerate().take(self.expanded.len()) {
            let want = wanted && self.expandable(g as u32);
            if self.expanded[g] != want {
                self.expanded[g] = want;
                for i in 0..self.sets[g].len() {
                    let t = self.sets[g][i];
                    if want { self.show(t) } else { self.hide(t) }
                }
            }
        }
    }

    /// For every node at `min_level` and above, the cut node standing for it (NONE if expanded).
    pub fn cut_nodes(&self) -> Vec<u32> {
        crate::cut::cut_nodes_from(&self.h, &self.expanded, self.min_level)
    }

    /// Applies one frame's delta (the bands from `min_level` up; other parts are ignored):
    /// swaps, then corner updates at `min_level`, then the degeneration nodes of exactly the
    /// triangles these can have changed (a corner under a moved node, or new corners) are
    /// derived again, and those triangles move between D sets and are shown or hidden. The
    /// delta's own `degenerate` list is not read. On error the replay is left partly updated
    /// and should be discarded (the stream is corrupt).
    pub fn apply(&mut self, delta: &FrameDelta) -> Result<(), DeltaError> {
        let levels = self.h.levels();
        let l = self.min_level;
        let level_base = self.h.offsets[l];
        // Moved nodes with their level.
        let mut moved: Vec<(u32, usize)> = Vec::new();
        for (index, s) in delta.swaps.iter().enumerate() {
            let k = s.level as usize;
            if k < l {
                continue;
            }
            if k + 1 >= levels || s.v >= self.h.level_sizes[k] || s.to >= self.h.level_sizes[k + 1] || s.from >= self.h.level_sizes[k + 1] {
                return Err(DeltaError::SwapOutOfRange { index, level: s.level, v: s.v, to: s.to });
            }
            let actual = self.h.parent[k][s.v as usize];
            if actual != s.from {
                return Err(DeltaError::SwapMismatch { index, level: s.level, v: s.v, from: s.from, actual });
            }
            let (gv, ga, gb) = (self.h.offsets[k] + s.v, self.h.offsets[k + 1] + s.from, self.h.offsets[k + 1] + s.to);
            if ga == gb {
                continue;
            }
            self.h.parent[k][s.v as usize] = s.to;
            if let Some(i) = self.children[ga as usize].iter().position(|&c| c == gv) {
                self.children[ga as usize].swap_remove(i);
            }
            self.children[gb as usize].push(gv);
            if self.expanded[gv as usize] && !self.expanded[gb as usize] {
                self.collapse(gv);
            }
            moved.push((gv, k));
        }
        // A cluster may empty transiently when net parent changes are applied in node order;
        // only the state after all swaps must leave no cluster empty.
        for (index, s) in delta.swaps.iter().enumerate() {
            let k = s.level as usize;
            if k >= l && self.children[(self.h.offsets[k + 1] + s.from) as usize].is_empty() {
                return Err(DeltaError::EmptyCluster { index, level: s.level, from: s.from });
            }
        }
        if l > 0 {
            let size = self.h.level_sizes[l];
            for (index, c) in delta.corners.iter().enumerate() {
                if c.level as usize != l {
                    continue;
                }
                let t = c.t as usize;
                if t >= self.corners.len() || c.corners.iter().any(|&x| x >= size) {
                    return Err(DeltaError::CornerOutOfRange { index, level: c.level, triangle: c.t });
                }
                self.corners[t] = c.corners;
                if distinct(c.corners) {
                    for x in c.corners {
                        self.incident.add(x, c.t);
                    }
                }
                self.mark(c.t);
            }
        }
        // Triangles with a level-L corner under a moved level-k node: their ancestor chains
        // changed above k. Only those whose corners had not met by level k can change (two
        // corners that meet at or below k meet under the moved node, wherever it hangs), which
        // skips most triangles under a coarse node. `node_of` still holds the previous frame's.
        let mut stack: Vec<u32> = Vec::new();
        for (gv, k) in moved {
            let above = self.h.offsets[k + 1];
            stack.push(gv);
            while let Some(x) = stack.pop() {
                if x < self.h.offsets[l + 1] {
                    let xl = x - level_base;
                    let (base, extra) = self.incident.of(xl);
                    for &t in base.iter().chain(extra) {
                        // Entries go stale when corner updates move a triangle away from xl.
                        let c = self.corners[t as usize];
                        let g = self.node_of[t as usize];
                        if (g == NONE || g >= above) && c.contains(&xl) && distinct(c) && !self.marked[t as usize] {
                            self.marked[t as usize] = true;
                            self.affected.push(t);
                        }
                    }
                } else {
                    stack.extend_from_slice(&self.children[x as usize]);
                }
            }
        }
        for i in 0..self.affected.len() {
            let t = self.affected[i];
            self.marked[t as usize] = false;
            let g = self.degeneration_of(t as usize);
            self.set_degeneration(t, g);
        }
        self.affected.clear();
        Ok(())
    }

    #[inline]
    fn mark(&mut self, t: u32) {
        if !self.marked[t as usize] {
            self.marked[t as usize] = true;
            self.affected.push(t);
        }
    }

    /// Moves triangle t into D_g (g may be [`NONE`] or [`BELOW`]) and shows or hides it.
    fn set_degeneration(&mut self, t: u32, g: u32) {
        let old = self.node_of[t as usize];
        if old == g {
            return;
        }
        if old != NONE && old != BELOW {
            let set = &mut self.sets[old as usize];
            let slot = self.slot_in_set[t as usize] as usize;
            if slot < set.len() {
                set.swap_remove(slot);
                if let Some(&moved) = set.get(slot) {
                    self.slot_in_set[moved as usize] = slot as u32;
                }
            }
        }
        if g != NONE && g != BELOW {
            self.slot_in_set[t as usize] = self.sets[g as usize].len() as u32;
            self.sets[g as usize].push(t);
        } else {
            self.slot_in_set[t as usize] = NONE;
        }
        self.node_of[t as usize] = g;
        if g == NONE || (g != BELOW && self.expanded[g as usize]) { self.show(t) } else { self.hide(t) }
    }
}

/// Cuts chosen from decoded data alone. The file carries no quadrics, so a decoder makes them
/// from what it decodes (Garland & Heckbert's plane quadrics, as the encoder's clusters are
/// built on; Kircher & Garland section 3): each triangle alive at the replay's finest level L
/// gives its three level-L corners the quadric of its plane weighted by a third of its area, a
/// node's quadric is the sum over its cluster, and its *own error* is the RMS distance
/// `sqrt(Q(x) / area)` of its cluster's faces from its decoded position `x`. A node's split
/// priority is the largest own error in its subtree, so priorities are monotone (a node's is
/// at least each child's) and "every split above an error bound" is a prefix of the order.
///
/// Against the largest distance to any finer node (what versions up to 4 of the spec used), a
/// flat cluster, however wide, no longer asks to be split first: on the horse, vertex-budget
/// cuts at 843 vertices have 28% less RMS surface error (0.094% -> 0.068% of the diagonal,
/// as good as the level of that size), 35% less at 3,000. Specified in proto/container.md
/// ("Cuts"), operation by operation, so every decoder picks the same cut.
impl Replay {
    /// Split priorities of every node from node positions (global ids).
    pub fn node_errors(&self, positions: &[Vec3]) -> Vec<f64> {
        let mut err = Vec::new();
        self.node_errors_into(positions, &mut err);
        err
    }

    /// [`Self::node_errors`] into a buffer (resized to the node count).
    pub fn node_errors_into(&self, positions: &[Vec3], err: &mut Vec<f64>) {
        let h = &self.h;
        let nodes = h.node_count();
        err.clear();
        err.resize(nodes, 0.0);
        // Quadric coefficients per node: a00 a01 a02 a11 a12 a22 b0 b1 b2 c, then the area.
        let mut q = vec![[0f64; 11]; nodes];
        let (base, size) = (h.offsets[self.min_level] as usize, h.level_sizes[self.min_level] as usize);
        let at = |v: u32| positions.get(base + v as usize).map(|p| [p.x as f64, p.y as f64, p.z as f64]);
        for c in &self.corners {
            if !distinct(*c) || c.iter().any(|&v| v as usize >= size) {
                continue;
            }
            let (Some(p0), Some(p1), Some(p2)) = (at(c[0]), at(c[1]), at(c[2])) else { continue };
            let e1 = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
            let e2 = [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]];
            let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if !(len > 0.0 && len.is_finite()) {
                continue;
            }
            let u = [n[0] / len, n[1] / len, n[2] / len];
            let d = -(u[0] * p0[0] + u[1] * p0[1] + u[2] * p0[2]);
            let w = len / 6.0;
            let plane = [
                w * (u[0] * u[0]),
                w * (u[0] * u[1]),
                w * (u[0] * u[2]),
                w * (u[1] * u[1]),
                w * (u[1] * u[2]),
                w * (u[2] * u[2]),
                w * (d * u[0]),
                w * (d * u[1]),
                w * (d * u[2]),
                w * (d * d),
                w,
            ];
            for &v in c {
                let acc = &mut q[base + v as usize];
                for i in 0..11 {
                    acc[i] += plane[i];
                }
            }
        }
        // Sums over clusters, finest level first; then each node's own error at its position.
        for k in self.min_level..h.levels() - 1 {
            for (v, &p) in h.parent[k].iter().enumerate() {
                let (c, a) = ((h.offsets[k] + v as u32) as usize, (h.offsets[k + 1] + p) as usize);
                if let (Some(&child), Some(_)) = (q.get(c), q.get(a)) {
                    for i in 0..11 {
                        q[a][i] += child[i];
                    }
                }
            }
        }
        let first_above = h.offsets.get(self.min_level + 1).map_or(nodes, |&o| o as usize);
        for ((out, m), x) in err.iter_mut().zip(&q).zip(positions).skip(first_above) {
            let x = [x.x as f64, x.y as f64, x.z as f64];
            let ax = m[0] * x[0] + m[1] * x[1] + m[2] * x[2];
            let ay = m[1] * x[0] + m[3] * x[1] + m[4] * x[2];
            let az = m[2] * x[0] + m[4] * x[1] + m[5] * x[2];
            let e = x[0] * ax + x[1] * ay + x[2] * az + 2.0 * (m[6] * x[0] + m[7] * x[1] + m[8] * x[2]) + m[9];
            *out = if m[10] > 0.0 && e > 0.0 { (e / m[10]).sqrt() } else { 0.0 };
        }
        // The largest own error in each subtree, finest level first.
        for k in self.min_level..h.levels() - 1 {
            for (v, &p) in h.parent[k].iter().enumerate() {
                let (c, a) = ((h.offsets[k] + v as u32) as usize, (h.offsets[k + 1] + p) as usize);
                if let (Some(&e), Some(_)) = (err.get(c), err.get(a))
                    && e > err[a]
                {
                    err[a] = e;
                }
            }
        }
    }

    /// Collapses the whole cut, in time proportional to it: the cut is closed upward, so every
    /// expanded node lies under an expanded top-level node.
    fn collapse_all(&mut self) {
        let top = self.h.top();
        for g in self.h.offsets[top]..self.h.offsets[top + 1] {
            if self.expanded[g as usize] {
                self.collapse(g);
            }
        }
        debug_assert!(!self.expanded.iter().any(|&e| e), "the cut was not closed upward");
    }

    /// The cut node standing for level-L node `v` (local id): its highest ancestor (itself
    /// included) whose parent is expanded, or its top-level ancestor. Walks up the local
    /// parent maps, so its cost is the node's depth below the cut.
    #[inline]
    pub fn cut_node_of(&self, v: u32) -> u32 {
        let h = &self.h;
        let (mut k, mut v) = (self.min_level, v);
        while k < h.top() {
            let p = h.parent[k][v as usize];
            if self.expanded[(h.offsets[k + 1] + p) as usize] {
                break;
            }
            (k, v) = (k + 1, p);
        }
        h.offsets[k] + v
    }

    /// Every node above `level` expanded (clamped to what this replay tracks). Budgets and
    /// error bounds are prefixes of the frame's [`crate::split_order::SplitOrder`].
    pub fn select_level(&mut self, level: usize) {
        self.collapse_all();
        let level = level.max(self.min_level).min(self.h.top());
        for g in self.h.offsets[level + 1]..self.h.offsets[self.h.levels()] {
            self.expand(g);
        }
    }

    /// The mesh the current cut shows, with node positions (global ids): its vertices are the
    /// cut nodes used by shown triangles, in first-use order.
    pub fn mesh(&self, positions: &[Vec3]) -> (pmcodec_mesh::TriMesh, Vec<u32>) {
        let rep = self.cut_nodes();
        let base = self.h.offsets[self.min_level];
        let mut index_of = std::collections::HashMap::new();
        let mut nodes = Vec::new();
        let mut mesh = pmcodec_mesh::TriMesh::default();
        for &t in &self.shown {
            let c = self.corners[t as usize];
            let tri = c.map(|x| {
                let g = rep.get((base + x) as usize).copied().unwrap_or(NONE);
                *index_of.entry(g).or_insert_with(|| {
                    nodes.push(g);
                    mesh.positions.push(positions.get(g as usize).copied().unwrap_or(Vec3::ZERO));
                    nodes.len() as u32 - 1
                })
            });
            mesh.triangles.push(tri);
        }
        (mesh, nodes)
    }
}
