//! The decoder side: playing a progressive representation back down to a finest level and
//! keeping one cut's shown triangles up to date (section 5.1).

use super::incidence::Incidence;
use super::*;

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
    /// The hierarchy H_f as of the last frame applied.
    pub h: Hierarchy,
    /// Finest level this replay tracks.
    pub min_level: usize,
    /// Level-L corners of every triangle (`[NONE; 3]` or a repeated node where not alive).
    pub(super) corners: Vec<[u32; 3]>,
    /// For every level-L node (local id), the triangles alive at L with a corner there.
    pub(super) incident: Incidence,
    pub(super) node_of: Vec<u32>,
    /// Scratch of `apply`: triangles whose degeneration node may have changed, and a mark per
    /// triangle so each is listed once.
    pub(super) affected: Vec<u32>,
    pub(super) marked: Vec<bool>,
    /// D sets per node (global id), unordered, and each triangle's slot in its set.
    pub(super) sets: Vec<Vec<u32>>,
    pub(super) slot_in_set: Vec<u32>,
    pub(super) children: Vec<Vec<u32>>,
    pub(super) expanded: Vec<bool>,
    pub(super) shown: Vec<u32>,
    pub(super) slot_in_shown: Vec<u32>,
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
    pub(super) fn fill_corners(&mut self, key: &Keyframe, triangles: Option<&[[u32; 3]]>) -> Result<(), DeltaError> {
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

    pub(super) fn empty(h: Hierarchy, min_level: usize, triangle_count: usize) -> Self {
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
    pub(super) fn degeneration_of(&self, t: usize) -> u32 {
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
    pub(super) fn rebuild(&mut self) {
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

    /// Whether each node (global id) is expanded in the current cut.
    pub fn expanded(&self) -> &[bool] {
        &self.expanded
    }

    /// D_g in the current hierarchy.
    pub fn degenerate_set(&self, g: u32) -> &[u32] {
        &self.sets[g as usize]
    }

    /// The children of node `g` in the current hierarchy.
    pub fn children_of(&self, g: u32) -> &[u32] {
        &self.children[g as usize]
    }

    /// Whether node g can be expanded here (its children are at `min_level` or above).
    #[inline]
    pub fn expandable(&self, g: u32) -> bool {
        g >= self.h.offsets[self.min_level + 1]
    }

    #[inline]
    pub(super) fn show(&mut self, t: u32) {
        if self.slot_in_shown[t as usize] == NONE {
            self.slot_in_shown[t as usize] = self.shown.len() as u32;
            self.shown.push(t);
        }
    }

    #[inline]
    pub(super) fn hide(&mut self, t: u32) {
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
    pub(super) fn mark(&mut self, t: u32) {
        if !self.marked[t as usize] {
            self.marked[t as usize] = true;
            self.affected.push(t);
        }
    }

    /// Moves triangle t into D_g (g may be [`NONE`] or [`BELOW`]) and shows or hides it.
    pub(super) fn set_degeneration(&mut self, t: u32, g: u32) {
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
