//! Cuts of a decoded frame: the split orders budgets and error bounds take prefixes of, whole
//! or partial splits (proto/container.md, "Cuts" and "Partial splits"), and the cut's mesh.

use super::Decoder;
use crate::{ByteSource, ContainerError};
use glam::Vec3;
use pmcodec_hierarchy::CutTarget;
use pmcodec_hierarchy::NONE;
use pmcodec_hierarchy::progressive::Replay;
use pmcodec_hierarchy::split_order::{SplitOrder, Steps};
use pmcodec_mesh::TriMesh;

/// How a decoder cuts vertex and triangle budgets (proto/container.md, "Cuts" and "Partial
/// splits"). Every choice is stateless: a decoder that seeks to a frame computes the same cut
/// whatever it decoded before.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BudgetCut {
    /// The spec's cut: whole splits by budget priority ([`Replay::split_benefits_into`]).
    #[default]
    WholeSplits,
    /// An option: partial splits, reveals ranked by reveal priorities from the positions
    /// [`BudgetPriorities`] names; a cut between levels is a partial simplification (less
    /// error there) but changes more from frame to frame. Files with attribute tables keep
    /// whole splits (their tables cover a node's charts at its own level only).
    PartialSplits(BudgetPriorities),
    /// An option: whole splits by budget priority, level-major (every splittable node of a
    /// coarser level before any of a finer one), so a budget at or above a level's count gets
    /// at least that level's cut.
    LevelSplits,
}

impl BudgetCut {
    /// Whether the cut ranks by the keyframe's positions (which a decoder then keeps).
    pub(super) fn holds_keyframe(self) -> bool {
        matches!(self, BudgetCut::PartialSplits(BudgetPriorities::Keyframe | BudgetPriorities::Banded { .. }))
    }
}

/// Which positions the reveal priorities of a partial-split cut ([`BudgetCut::PartialSplits`])
/// are computed from (proto/container.md, "Partial splits").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BudgetPriorities {
    /// The frame's own positions: reveals ranked afresh every frame; the ranking of the
    /// marginal reveals changes with every small motion, and the cut flickers.
    #[default]
    Frame,
    /// The positions of the keyframe at or before the frame, on the frame's hierarchy: within
    /// a keyframe interval only swaps change the ranking (steady), but the priorities go stale
    /// as the surface moves away from the keyframe's pose.
    Keyframe,
    /// Both: reveals ranked by the band of the frame's own priority (`per_octave` bands per
    /// factor 2, a power of two), and within a band by the keyframe's ([`banded_priority`]).
    /// The frame decides what is far off; only a node crossing a band edge trades places.
    Banded {
        /// Bands per factor 2 of the frame's priority (1, 2, 4, ...).
        per_octave: u32,
    },
}

/// The key a [`BudgetPriorities::Banded`] cut ranks reveals by: the band of the frame's
/// priority `current` (`floor(log2 current)` in `per_octave` steps, read exactly off the
/// float's exponent and mantissa so every decoder agrees bit for bit), plus the keyframe's
/// priority `held` squashed into [0, 1). Monotone in both, so a subtree's largest (what
/// priorities are raised to) keeps the order's prefixes.
pub fn banded_priority(current: f64, held: f64, per_octave: u32) -> f64 {
    let k = i64::from(per_octave.max(1));
    let band = if current > 0.0 && current.is_finite() {
        let bits = current.to_bits();
        let e = ((bits >> 52) & 0x7ff) as i64;
        if e == 0 {
            -2100 * k
        } else {
            let m = f64::from_bits((bits & ((1u64 << 52) - 1)) | (1023u64 << 52));
            (e - 1023) * k + ((m - 1.0) * k as f64).floor() as i64
        }
    } else {
        -2200 * k
    };
    let h = if held >= 0.0 && held.is_finite() { held } else { 0.0 };
    band as f64 + h / (1.0 + h)
}

/// What meshes of one decoded frame are cut from.
#[derive(Clone, Default)]
pub(super) struct Derived {
    /// The frame these were computed for.
    pub(super) frame: Option<u32>,
    pub(super) positions: Vec<Vec3>,
    /// The split orders error bounds and budgets take prefixes of, each computed on the
    /// frame's first cut that needs it (a full-resolution player pays for positions alone).
    pub(super) by_error: Ordered,
    pub(super) by_budget: Ordered,
}

/// One split order of a frame and the priorities it is grown by: split priorities (RMS error,
/// whole splits, so an error bound is a prefix) or reveal priorities
/// ([`Replay::reveal_benefits_into`], partial splits, so a budget between levels is a partial
/// simplification).
#[derive(Clone, Default)]
pub(super) struct Ordered {
    /// Whether `priorities` and `order` are this frame's.
    ready: bool,
    priorities: Vec<f64>,
    order: SplitOrder,
}

impl Ordered {
    /// Of a frame's two orders, the one `target` is a prefix of (a level cut uses none; it
    /// gets the error order, unread). Takes the fields, not [`Derived`], so that the caller
    /// can read the positions beside.
    pub(super) fn pick<'a>(by_error: &'a mut Ordered, by_budget: &'a mut Ordered, target: CutTarget) -> (&'a [f64], &'a mut SplitOrder) {
        let o = if matches!(target, CutTarget::Triangles(_) | CutTarget::Vertices(_)) { by_budget } else { by_error };
        (&o.priorities, &mut o.order)
    }
}

impl<S: ByteSource> Decoder<S> {
    /// Chooses the cut for `target` on the current frame and returns its mesh. Budgets are
    /// prefixes of the frame's order of whole splits by budget priority (or of partial splits
    /// by reveal priority, [`Decoder::set_budget_cut`]), error bounds of its order of whole
    /// splits by split priority (a `MaxError` diagonal fraction is of the header's bounding
    /// box); a level is every node of it (proto/container.md, "Cuts"). `Level(0)` (with a
    /// full-resolution decoder) gives every input vertex in input order and the input
    /// triangles in input order.
    pub fn mesh(&mut self, target: CutTarget) -> Result<TriMesh, ContainerError> {
        let mut mesh = TriMesh::default();
        self.mesh_into(target, &mut mesh)?;
        Ok(mesh)
    }

    /// [`Decoder::mesh`] into `mesh`'s buffers (whatever they held is replaced): a server or
    /// player that cuts again and again allocates nothing for budget and error cuts once the
    /// buffers have grown.
    pub fn mesh_into(&mut self, target: CutTarget, mesh: &mut TriMesh) -> Result<(), ContainerError> {
        let mut derived = self.take_derived(target)?;
        let result = self.cut(target, &mut derived, mesh);
        self.derived = Some(derived);
        result
    }

    /// The current frame's derived state (positions, and the priorities and split order
    /// `target` needs), taken out of the decoder: kept from the last cut of this frame, or
    /// recomputed in the buffers of the last frame's. The caller puts it back.
    pub(super) fn take_derived(&mut self, target: CutTarget) -> Result<Derived, ContainerError> {
        let Some(replay) = self.replay.as_ref() else {
            return Err(ContainerError::Options("seek to a frame first".into()));
        };
        let mut d = match self.derived.take() {
            Some(d) if d.frame.is_some() && d.frame == self.frame => d,
            stale => {
                let mut d = stale.unwrap_or_default();
                self.positions_into(&mut d.positions);
                d.by_error.ready = false;
                d.by_budget.ready = false;
                d.frame = self.frame;
                d
            }
        };
        match target {
            CutTarget::Level(_) => {}
            CutTarget::MaxError(_) if !d.by_error.ready => {
                let o = &mut d.by_error;
                replay.node_errors_into(&d.positions, &mut o.priorities);
                o.order.reset(replay, &o.priorities);
                o.ready = true;
            }
            CutTarget::Triangles(_) | CutTarget::Vertices(_) if !d.by_budget.ready => {
                let o = &mut d.by_budget;
                // Attribute tables hold a node's entries for the charts around it at its own
                // level only: a partially split node would need its finer triangles' charts.
                let attributes = self.reader.header().appearance.as_ref().is_some_and(|a| a.channels() > 0);
                let held = self.key_positions.len() == d.positions.len();
                match self.budget_cut {
                    BudgetCut::PartialSplits(p) if !attributes => {
                        match p {
                            BudgetPriorities::Keyframe if held => replay.reveal_benefits_into(&self.key_positions, &mut o.priorities),
                            BudgetPriorities::Banded { per_octave } if held => {
                                replay.reveal_benefits_into(&d.positions, &mut o.priorities);
                                let mut key = Vec::new();
                                replay.reveal_benefits_into(&self.key_positions, &mut key);
                                for (x, h) in o.priorities.iter_mut().zip(&key) {
                                    *x = banded_priority(*x, *h, per_octave);
                                }
                            }
                            _ => replay.reveal_benefits_into(&d.positions, &mut o.priorities),
                        }
                        o.order.reset_steps(replay, &o.priorities, Steps::PartialSplits);
                    }
                    c => {
                        replay.split_benefits_into(&d.positions, &mut o.priorities);
                        let steps = if c == BudgetCut::LevelSplits { Steps::LevelSplits } else { Steps::WholeSplits };
                        o.order.reset_steps(replay, &o.priorities, steps);
                    }
                }
                o.ready = true;
            }
            _ => {}
        }
        Ok(d)
    }

    /// The header's bounding-box diagonal: what a `MaxError` diagonal fraction is of.
    pub(super) fn diagonal(&self) -> f64 {
        let h = self.reader.header();
        (Vec3::from_array(h.bbox_max) - Vec3::from_array(h.bbox_min)).length() as f64
    }

    /// The triangles a budget or error cut shows, each as the global ids of its corners' cut
    /// nodes (input triangle order is not kept): what identifies a shown triangle from frame to
    /// frame, for a tool that measures how much cuts change. `Level` targets are refused.
    pub fn cut_triangles(&mut self, target: CutTarget) -> Result<Vec<[u32; 3]>, ContainerError> {
        self.with_prefix(target, |replay, order, k| {
            let corners = replay.corners();
            order.shown(k).iter().filter_map(|&t| corners.get(t as usize)).map(|c| c.map(|v| order.cut_node_of(replay, v, k))).collect()
        })
    }

    /// [`Decoder::cut_triangles`], and for every vertex of the finest level decoded (the input's
    /// vertices at `min_level` 0) the cut node whose cluster holds it: what identifies a shown
    /// triangle by the content of its corners' clusters, the same way for every method `pmcodec
    /// eval` compares (node ids persist only within one file). `Level` targets are refused.
    pub fn cut_clusters(&mut self, target: CutTarget) -> Result<(Vec<[u32; 3]>, Vec<u32>), ContainerError> {
        self.with_prefix(target, |replay, order, k| {
            let corners = replay.corners();
            let n = replay.h.level_sizes[replay.min_level];
            let nodes: Vec<u32> = (0..n).map(|v| order.cut_node_of(replay, v, k)).collect();
            let triangles = order
                .shown(k)
                .iter()
                .filter_map(|&t| corners.get(t as usize))
                .map(|c| c.map(|v| nodes.get(v as usize).copied().unwrap_or(NONE)))
                .collect();
            (triangles, nodes)
        })
    }

    /// Runs `f` on the current frame's replay, the split order `target` is a prefix of, and
    /// the prefix's length (what [`Decoder::cut_triangles`] and [`Decoder::cut_clusters`]
    /// read). `Level` targets are refused.
    fn with_prefix<T>(&mut self, target: CutTarget, f: impl FnOnce(&Replay, &SplitOrder, usize) -> T) -> Result<T, ContainerError> {
        if let CutTarget::Level(l) = target {
            return Err(ContainerError::Options(format!("cut triangles of level {l}: give a budget or an error")));
        }
        let diagonal = self.diagonal();
        let mut d = self.take_derived(target)?;
        let result = match self.replay.as_ref() {
            Some(replay) => {
                let (priorities, order) = Ordered::pick(&mut d.by_error, &mut d.by_budget, target);
                // Never `Err`: levels are refused above.
                let k = order.prefix(replay, priorities, target, diagonal).unwrap_or_default();
                Ok(f(replay, order, k))
            }
            None => Err(ContainerError::Options("seek to a frame first".into())),
        };
        self.derived = Some(d);
        result
    }

    fn cut(&mut self, target: CutTarget, d: &mut Derived, mesh: &mut TriMesh) -> Result<(), ContainerError> {
        let diagonal = self.diagonal();
        let min_level = self.min_level;
        let replay = self.replay.as_mut().ok_or_else(|| ContainerError::Options("seek to a frame first".into()))?;
        // Budgets and error bounds are prefixes of a split order: no change to the replay.
        let (priorities, order) = Ordered::pick(&mut d.by_error, &mut d.by_budget, target);
        let k = match order.prefix(replay, priorities, target, diagonal) {
            Ok(k) => k,
            Err(0) if min_level == 0 => {
                let n0 = replay.h.level_sizes[0] as usize;
                mesh.positions.clear();
                mesh.positions.extend_from_slice(&d.positions[..n0]);
                mesh.triangles.clear();
                mesh.triangles.extend_from_slice(self.triangles.as_deref().unwrap_or_default());
                return Ok(());
            }
            Err(l) => {
                replay.select_level(l);
                *mesh = ordered_mesh(replay, &d.positions);
                return Ok(());
            }
        };
        order.mesh_into(replay, &d.positions, k, mesh);
        Ok(())
    }
}

/// The current cut's mesh with triangles in input order and vertices in node order, so equal
/// cuts give byte-identical meshes. A corner's cut node is found by walking up from it; a
/// small cut sorts its shown triangles and used nodes, a large one finds them with a pass over
/// the triangles and a mark per node (so neither costs more than the cut or a linear pass).
pub fn ordered_mesh(replay: &Replay, positions: &[Vec3]) -> TriMesh {
    let nodes = replay.h.node_count();
    let size = replay.h.level_sizes[replay.min_level];
    // A corner beyond the level (a corrupt state) stands for one slot past the end, drawn at
    // the origin.
    let node_of = |c: u32| if c < size { replay.cut_node_of(c) } else { nodes as u32 };
    let position = |g: u32| positions.get(g as usize).copied().unwrap_or(Vec3::ZERO);
    let shown = replay.shown();
    let triangle_count = replay.corners().len();
    if shown.len() * 16 < triangle_count {
        let mut order = shown.to_vec();
        order.sort_unstable();
        let corners: Vec<[u32; 3]> = order.iter().map(|&t| replay.corners()[t as usize].map(node_of)).collect();
        let mut used: Vec<u32> = corners.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        let index_of = |g: u32| used.binary_search(&g).map_or(0, |i| i as u32);
        return TriMesh {
            positions: used.iter().map(|&g| position(g)).collect(),
            triangles: corners.iter().map(|c| c.map(index_of)).collect(),
        };
    }
    let mut corners: Vec<[u32; 3]> = Vec::with_capacity(shown.len());
    let mut index = vec![NONE; nodes + 1];
    for (t, c) in replay.corners().iter().enumerate() {
        if replay.is_shown(t as u32) {
            let c = c.map(node_of);
            for &g in &c {
                index[g as usize] = 0;
            }
            corners.push(c);
        }
    }
    let mut out = Vec::new();
    for (g, slot) in index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = out.len() as u32;
            out.push(position(g as u32));
        }
    }
    TriMesh { positions: out, triangles: corners.iter().map(|c| c.map(|g| index[g as usize])).collect() }
}
