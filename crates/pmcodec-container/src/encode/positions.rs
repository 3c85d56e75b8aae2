//! Coding one band's node positions: the prediction (the default one, or skinning's where it
//! leaves smaller residuals), the stored position within the bound, and the residuals.

use super::Motion;
use super::rate::RateModel;
use crate::grid::{SLACK2, choose, on_grid, on_surface_grid, on_surface_grid_rated};
use crate::payload;
use crate::predict::{AffineFits, Band0Motion, LowerNeighbours, Siblings, StencilWeights, predict};
use crate::skin::{CoarseQuadrics, NodeSkin, lbs, skinned_motion};
use glam::DVec3;
use pmcodec_hierarchy::{Hierarchy, Quadric};

/// The state of position coding across frames: the stored positions of the previous and
/// current frames and the predictors' scratch, as the decoder keeps them.
#[derive(Default)]
pub(super) struct PositionCoder {
    motion: Motion,
    lower: LowerNeighbours,
    shifts: Vec<u32>,
    previous: Vec<[i32; 3]>,
    current: Vec<[i32; 3]>,
    residuals: Vec<[i32; 3]>,
    siblings: Siblings,
    fits: AffineFits,
    weights: StencilWeights,
    /// A band's positions and residuals from the other predictor, while the two are compared.
    saved: Vec<[i32; 3]>,
    saved_residuals: Vec<[i32; 3]>,
    /// Every node's skinned position under this frame's palette, kept for the next frame, whose
    /// prediction moves each node by its skinned position now less the one before: each
    /// palette poses each node once, not twice (the same values, so the same bytes).
    posed: [Posed; 2],
    /// The last generation given to a [`Posed`].
    generation: u32,
    /// Whether the report's `plain_bits` must be exact where skinning competes: the default
    /// prediction's coding then runs to the band's end even once it lost.
    pub(super) exact_plain: bool,
    /// Per coarse band, on keyframes and between them (index `2 j + intra`), the counts of
    /// its stored residuals that [`on_surface_grid_rated`] weighs the surface against.
    rates: Vec<RateModel>,
    /// What a stopped coding had cost (see [`Self::code`]).
    stopped_at: u64,
    pub(super) report: EncodeReport,
}

/// Nodes posed by one palette: `at[g]` is [`lbs`] of node `g`'s skin (of the skins at `nodes`)
/// by `palette` where `stamp[g]` is `generation`.
#[derive(Default)]
struct Posed {
    palette: Vec<i64>,
    nodes: usize,
    generation: u32,
    at: Vec<[i32; 3]>,
    stamp: Vec<u32>,
}

impl Posed {
    /// Whether this holds poses of the skins at `nodes` by `palette`.
    fn holds(&self, nodes: &[NodeSkin], palette: &[i64]) -> bool {
        self.generation != 0 && self.nodes == nodes.as_ptr() as usize && self.palette == palette
    }

    /// Node `g` posed, if this holds it.
    fn get(&self, g: usize) -> Option<[i32; 3]> {
        (self.stamp.get(g) == Some(&self.generation)).then(|| self.at[g])
    }
}

/// What an encode found beside its bytes: how often skinning predicted a band and about how
/// many bits it saved, so that a caller can tell whether a skin paid for its pose and bind
/// chunks (a fitted skin may not).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct EncodeReport {
    /// Bands coded (bands times frames), and how many of them skinning predicted.
    pub bands: u64,
    /// Of `bands`, those whose nodes skinning predicted.
    pub skinned_bands: u64,
    /// About the bits of every band's residuals (an Elias gamma code of each) under the default
    /// prediction, and as stored (the smaller of the two where skinning competed). Exact from
    /// [`super::encode_with_report`]; from [`super::encode_posed`], where skinning predicted
    /// a band, what the default prediction had cost when it came to cost more (a lower bound:
    /// its coding stops there).
    pub plain_bits: u64,
    /// The same estimate as stored; `plain_bits - stored_bits` is about what skinning saved.
    pub stored_bits: u64,
}

/// What skinning predicts a frame's nodes from: every node's skin, and the frame's and the
/// previous frame's palettes.
#[derive(Clone, Copy)]
pub(super) struct Skinning<'a> {
    pub(super) nodes: &'a [NodeSkin],
    pub(super) palette: &'a [i64],
    pub(super) previous: &'a [i64],
    /// The frame's coarse-node quadrics, where coarse nodes may be stored at their skinned
    /// positions.
    pub(super) coarse: Option<&'a CoarseQuadrics<'a>>,
}

/// A frame's coarse-node quadrics in the quantization grid's terms, so that coarse nodes are
/// stored on their clusters' surfaces ([`on_surface_grid`]; [`super::EncodeOptions::surface_grid`]).
#[derive(Clone, Copy)]
pub(super) struct Surface<'a> {
    /// The quadrics of nodes `first..`, by global id.
    pub(super) quadrics: &'a [Quadric],
    pub(super) first: usize,
    /// The quantization grid's origin and step.
    pub(super) lo: DVec3,
    pub(super) step: f64,
}

impl Surface<'_> {
    /// Node `g`'s excess at a point `x` (in quanta) over its true position `t`: the increase
    /// of its quadric error per unit of its area, in quanta squared. None where the node has
    /// no quadric or no area (it is then stored as [`on_grid`] stores it).
    fn excess(&self, g: usize, t: [f64; 3]) -> Option<impl Fn([f64; 3]) -> f64 + '_> {
        let q = g.checked_sub(self.first).and_then(|k| self.quadrics.get(k))?;
        let scale = q.area * self.step * self.step;
        if !(scale.is_finite() && scale > 0.0) {
            return None;
        }
        let world = |x: [f64; 3]| self.lo + DVec3::from_array(x) * self.step;
        let at_t = q.eval(world(t));
        Some(move |x: [f64; 3]| (q.eval(world(x)) - at_t) / scale)
    }
}

/// About the bits a residual costs (an Elias gamma code of its zigzag value): enough to tell
/// which of two predictors leaves the smaller residuals.
fn cost(residuals: &[[i32; 3]]) -> u64 {
    residuals.iter().flatten().map(|&r| 2 * (32 - payload::zigzag(r).leading_zeros()) as u64 + 1).sum()
}

impl PositionCoder {
    /// A coder of `total` nodes whose band 0 moves by `motion` over `lower`, band j's residuals
    /// in units of `2^shifts[j]` quanta.
    pub(super) fn new(motion: Motion, lower: LowerNeighbours, shifts: Vec<u32>, total: usize) -> Self {
        PositionCoder { motion, lower, shifts, previous: vec![[0; 3]; total], current: vec![[0; 3]; total], ..Default::default() }
    }

    /// Stores band `j` of a frame (`intra`: a keyframe) whose hierarchy is `h` and whose true
    /// node positions, in quanta, `truth` gives; returns the band's positions payload and
    /// whether skinning predicted it (when `skin` is given and leaves smaller residuals).
    pub(super) fn band(
        &mut self,
        j: usize,
        intra: bool,
        h: &Hierarchy,
        truth: impl Fn(usize) -> [f64; 3],
        (skin, surface): (Option<Skinning>, Option<Surface>),
    ) -> (Vec<u8>, bool) {
        let skinned = self.code_band(j, intra, h, truth, (skin, surface));
        (payload::write_positions(self.shifts[j], &self.residuals), skinned)
    }

    /// [`Self::band`] without its payload: returns the band's residual shift and residuals
    /// (what [`payload::write_positions`] makes the payload of; nothing of the coder's state
    /// depends on it, so the encoder writes it on another thread) and whether skinning
    /// predicted the band.
    pub(super) fn band_residuals(
        &mut self,
        j: usize,
        intra: bool,
        h: &Hierarchy,
        truth: impl Fn(usize) -> [f64; 3],
        (skin, surface): (Option<Skinning>, Option<Surface>),
    ) -> (u32, Vec<[i32; 3]>, bool) {
        let skinned = self.code_band(j, intra, h, truth, (skin, surface));
        (self.shifts[j], self.residuals.clone(), skinned)
    }

    /// Codes band `j` into `current` and `residuals`; returns whether skinning predicted it.
    fn code_band(
        &mut self,
        j: usize,
        intra: bool,
        h: &Hierarchy,
        truth: impl Fn(usize) -> [f64; 3],
        (skin, surface): (Option<Skinning>, Option<Surface>),
    ) -> bool {
        self.report.bands += 1;
        let (chosen, skinned) = match skin {
            None => {
                let plain = self.code(j, intra, h, &truth, (None, surface), u64::MAX).unwrap_or(u64::MAX);
                self.report.plain_bits += plain;
                (plain, false)
            }
            Some(s) => self.compete(j, intra, h, &truth, (s, surface)),
        };
        self.report.skinned_bands += skinned as u64;
        self.report.stored_bits += chosen;
        if j > 0 && surface.is_some() {
            // The stored residuals whichever prediction made them: both codings of a later
            // frame weigh the surface against the same counts, whether or not the default
            // prediction's coding stopped early here.
            let k = 2 * j + intra as usize;
            if self.rates.len() <= k {
                self.rates.resize(k + 1, RateModel::default());
            }
            self.rates[k].add(&self.residuals);
        }
        if j == 0 && intra && self.motion == Motion::KeyframeAffine {
            self.weights.compute(&self.lower, &self.current, h.level_sizes[0] as usize);
        }
        skinned
    }

    /// Codes band `j` under both predictions and keeps skinning's where its residuals cost
    /// less (the default prediction's on ties); returns the kept residuals' cost and whether
    /// they are skinning's. Skinning's are coded first: unless the report must say exactly what
    /// the default prediction costs ([`Self::exact_plain`]), its coding stops as soon as it
    /// costs more (where skinning is exact, as for a glTF's own skin, that is early in every
    /// band). Each coding reads only what it wrote of the band (as a decoder would), so the
    /// order changes nothing of what is kept.
    fn compete(
        &mut self,
        j: usize,
        intra: bool,
        h: &Hierarchy,
        truth: &impl Fn(usize) -> [f64; 3],
        (s, surface): (Skinning, Option<Surface>),
    ) -> (u64, bool) {
        let band = h.offsets[j] as usize..h.offsets[j + 1] as usize;
        let with_skin = self.code(j, intra, h, truth, (Some(s), surface), u64::MAX).unwrap_or(u64::MAX);
        self.saved.clear();
        self.saved.extend_from_slice(&self.current[band.clone()]);
        std::mem::swap(&mut self.residuals, &mut self.saved_residuals);
        let limit = if self.exact_plain { u64::MAX } else { with_skin };
        let plain = self.code(j, intra, h, truth, (None, surface), limit);
        // Stopped: the default prediction costs more than `with_skin`, by at least what it
        // had cost so far (what the report counts).
        let (plain, skinned) = match plain {
            Some(p) => (p, with_skin < p),
            None => (self.stopped_at, true),
        };
        self.report.plain_bits += plain;
        if skinned {
            self.current[band].copy_from_slice(&self.saved);
            std::mem::swap(&mut self.residuals, &mut self.saved_residuals);
        }
        (plain.min(with_skin), skinned)
    }

    /// Codes band `j` with skinning's prediction or the default one into `current` and
    /// `residuals` (coarse nodes on their surfaces where `surface` is given); returns the
    /// residuals' cost, or None (the cost so far in `stopped_at`) as soon as it exceeds
    /// `limit`, leaving the band's other nodes uncoded.
    fn code(
        &mut self,
        j: usize,
        intra: bool,
        h: &Hierarchy,
        truth: &impl Fn(usize) -> [f64; 3],
        (skin, surface): (Option<Skinning>, Option<Surface>),
        limit: u64,
    ) -> Option<u64> {
        let (sizes, offsets, levels) = (&h.level_sizes, &h.offsets, h.levels());
        self.residuals.clear();
        let shift = self.shifts[j];
        self.siblings.reset(if j + 1 < levels { sizes[j + 1] as usize } else { 0 });
        let n0 = sizes[0] as usize;
        let reuse = skin.is_some_and(|s| self.pose_by(s));
        let motion = Band0Motion::select(self.motion, j == 0 && !intra, &self.lower, &self.previous, n0, &mut self.fits, &self.weights);
        // Band 0 in its decoding order, coarser bands in node order.
        let sequence = (j == 0).then(|| self.lower.sequence());
        let mut before = None;
        let mut spent = 0u64;
        let rates = if j > 0 && surface.is_some() { self.rates.get(2 * j + intra as usize).and_then(RateModel::rates) } else { None };
        for k in 0..sizes[j] as usize {
            let v = sequence.map_or(k, |s| s[k] as usize);
            let g = offsets[j] as usize + v;
            let parent = (j + 1 < levels).then(|| ((offsets[j + 1] + h.parent[j][v]) as usize, h.parent[j][v] as usize));
            let p = match skin {
                Some(s) => {
                    let [now, before] = &mut self.posed;
                    let at = lbs(&s.nodes[g], s.palette);
                    now.at[g] = at;
                    now.stamp[g] = now.generation;
                    if intra {
                        at
                    } else {
                        let was = if reuse { before.get(g) } else { None };
                        skinned_motion(at, was.unwrap_or_else(|| lbs(&s.nodes[g], s.previous)), self.previous[g])
                    }
                }
                None => predict(j, v, g, before, parent, &self.lower, motion, &self.siblings, intra, &self.current, &self.previous),
            };
            before = Some(g);
            let t = truth(g);
            let at_skin = j > 0 && skin.and_then(|s| s.coarse).is_some_and(|c| c.accepts(g, t, p, shift));
            let (q, r) = match (j, at_skin) {
                (0, _) => choose(t, p, SLACK2),
                // The zero residual adds nothing to the prediction, whatever the band's grid.
                (_, true) => (p, [0; 3]),
                _ => match surface.as_ref().and_then(|s| s.excess(g, t)) {
                    Some(excess) => match &rates {
                        Some(rates) => on_surface_grid_rated(t, p, shift, SLACK2, excess, (|r| rates.bits(r), rates.excess_worth())),
                        None => on_surface_grid(t, p, shift, SLACK2, excess),
                    },
                    None => on_grid(t, p, shift, SLACK2),
                },
            };
            self.current[g] = q;
            if let Some((_, local)) = parent {
                self.siblings.add(local, q, self.previous[g]);
            }
            self.residuals.push(r);
            spent += cost(&[r]);
            if spent > limit {
                self.stopped_at = spent;
                return None;
            }
        }
        Some(spent)
    }

    /// Readies `posed[0]` for the nodes posed by `s.palette` (kept if it already holds that
    /// palette's, else emptied), and says whether `posed[1]` holds their poses by the
    /// previous frame's palette.
    fn pose_by(&mut self, s: Skinning) -> bool {
        let total = self.current.len();
        let [now, before] = &mut self.posed;
        if !now.holds(s.nodes, s.palette) {
            self.generation = self.generation.wrapping_add(1).max(1);
            now.generation = self.generation;
            now.nodes = s.nodes.as_ptr() as usize;
            now.palette.clear();
            now.palette.extend_from_slice(s.palette);
            now.at.resize(total, [0; 3]);
            now.stamp.resize(total, 0);
        }
        before.holds(s.nodes, s.previous)
    }

    /// Ends a frame: its positions become the previous frame's, and so do its nodes' poses.
    pub(super) fn next_frame(&mut self) {
        std::mem::swap(&mut self.previous, &mut self.current);
        self.posed.swap(0, 1);
    }
}
