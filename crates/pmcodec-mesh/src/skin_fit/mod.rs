//! A skin for a sequence that has none: a few rigid bones per frame and at most four weights
//! per vertex, fitted to the whole sequence by Le and Deng's smooth skinning decomposition with
//! rigid bones ("Smooth Skinning Decomposition with Rigid Bones", 2012; SSDR). The result is a
//! [`SequenceSkin`] like a skinned glTF's, so the container predicts every node at every level
//! by linear blend skinning from it and codes only residuals (the motion compensation of MPEG-4
//! FAMC, Mamou, Zaharia and Prêteux, 2008, for animations without a skeleton).
//!
//! The steps, one per file: `cluster` (bones from vertices clustered by motion), then
//! alternately `weights` (each vertex's non-negative, affine weights on its candidate bones)
//! and `bones` (each bone's rigid transform per frame by weighted Procrustes, `horn`). The
//! rest pose is frame 0, where every bone is the identity. Deterministic (no randomness, every
//! loop in a fixed order) and bounded: the bone count, the iterations and the frames the
//! clustering compares are capped.

// Per-vertex and per-bone loops index several parallel arrays at once, as the paper states them.
#![allow(clippy::needless_range_loop)]

mod bones;
mod cluster;
mod horn;
mod weights;

use crate::{Sequence, SequenceSkin};
use glam::DVec3;
use horn::Rigid;

/// Most bones a fit may have: past this the pose costs more per frame than skinning saves, and
/// the clustering's cost (vertices x bones x frames) grows out of bounds.
pub const MAX_BONES: u32 = 256;

/// What a fit is told.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Bones to fit; `None` to choose the count by cost: [`default_bones`] of the vertex count,
    /// doubled while the residuals' estimated bits drop by more than the added bones cost
    /// ([`FitOptions::bone_bits`]). At most the vertex count are used.
    pub bones: Option<u32>,
    /// Lloyd iterations of the motion clustering that places the first bones.
    pub cluster_iterations: u32,
    /// Alternations of SSDR's weight and transform steps.
    pub iterations: u32,
    /// Candidate bones per vertex in the weight step (at least the 4 influences a vertex keeps;
    /// more pays: the fit picks the four it keeps among them).
    pub candidates: u32,
    /// Frames the clustering and the choice of candidates compare (evenly spaced).
    pub sample_frames: u32,
    /// The position quantization the skin will be coded at (bits over the bounding box's
    /// largest extent, as `pmcodec encode --quant-bits`): the unit of the residuals whose
    /// bits the choice of the bone count estimates.
    pub quant_bits: u32,
    /// What one bone costs per frame in the choice of the bone count, in bits (the container
    /// codes a bone's frame as a quaternion, a scale and a translation predicted from the
    /// frames before: about eight Exp-Golomb numbers).
    pub bone_bits: u32,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { bones: None, cluster_iterations: 6, iterations: 6, candidates: 6, sample_frames: 16, quant_bits: 12, bone_bits: 96 }
    }
}

/// The first bone count a fit not told one tries for `n` vertices (it doubles it while more
/// bones pay): one per 200 vertices, from 4 to 64. On
/// the horse (8,431 vertices) that is 42, about the 30 to 60 bones Le and Deng fit to it.
pub fn default_bones(n: usize) -> u32 {
    (n / 200).clamp(4, 64) as u32
}

/// Why a skin could not be fitted.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The sequence failed [`Sequence::validate`]; a skin needs a valid one.
    #[error("fitting a skin: the sequence is invalid: {0}")]
    Invalid(#[from] crate::MeshError),
    /// The bone count asked for is 0 or over [`MAX_BONES`].
    #[error("fitting a skin: {0} bones; use 1 to {MAX_BONES}")]
    Bones(u32),
    /// Another [`FitOptions`] field is out of its range; `name` says which, `why` its bounds.
    #[error("fitting a skin: option {name} = {value}: {why}")]
    Option {
        /// The field's name.
        name: &'static str,
        /// Its value.
        value: u32,
        /// The range it must be in.
        why: &'static str,
    },
}

/// How well a fitted skin reproduces its sequence.
#[derive(Clone, Debug, PartialEq)]
pub struct FitReport {
    /// Bones kept (those some vertex depends on).
    pub bones: u32,
    /// Root mean square of the distance between a vertex and its skinned position, over all
    /// vertices and frames, as a fraction of the sequence's bounding-box diagonal.
    pub rms_error: f64,
    /// The largest such distance, as the same fraction.
    pub max_error: f64,
}

/// Fits a skin to `seq` (any skin it has is ignored): returns the skin, which
/// [`SequenceSkin::validate`] accepts for `seq`, and how closely it reproduces the frames.
pub fn fit_skin(seq: &Sequence, opts: &FitOptions) -> Result<(SequenceSkin, FitReport), FitError> {
    seq.validate()?;
    let n = seq.vertex_count();
    let requested = opts.bones.unwrap_or_else(|| default_bones(n));
    if requested == 0 || requested > MAX_BONES {
        return Err(FitError::Bones(requested));
    }
    if opts.candidates == 0 {
        return Err(FitError::Option { name: "candidates", value: 0, why: "a vertex needs at least one candidate bone" });
    }
    if opts.sample_frames < 2 {
        return Err(FitError::Option { name: "sample_frames", value: opts.sample_frames, why: "compare at least 2 frames" });
    }
    if !(4..=24).contains(&opts.quant_bits) {
        return Err(FitError::Option { name: "quant_bits", value: opts.quant_bits, why: "use 4 to 24 bits" });
    }
    let cap = (MAX_BONES as usize).min(n);
    if opts.bones.is_none() {
        // The bone count by cost (Le and Deng pick it by hand; a coder can count): fits at
        // doubling counts, kept while one pays for its bones.
        let mut best = fit_bones(seq, opts, (requested as usize).min(cap));
        let mut best_bits = estimated_bits(seq, &best, opts);
        let mut count = best.bones;
        while count < cap {
            count = (2 * count).min(cap);
            let next = fit_bones(seq, opts, count);
            let bits = estimated_bits(seq, &next, opts);
            if !(bits < best_bits) {
                break;
            }
            (best, best_bits) = (next, bits);
        }
        return Ok(to_skin(seq, &best));
    }
    let fit = fit_bones(seq, opts, (requested as usize).min(n));
    Ok(to_skin(seq, &fit))
}

/// A fit with its bone count: every vertex's influences and every bone's transform per frame
/// (`transforms[f * bones + b]`).
struct Fit {
    bones: usize,
    rest: Vec<DVec3>,
    influences: Vec<Vec<(u32, f64)>>,
    transforms: Vec<Rigid>,
}

impl Fit {
    /// Vertex `v` posed in frame `f`.
    fn pose(&self, f: usize, v: usize) -> DVec3 {
        let row = &self.transforms[f * self.bones..(f + 1) * self.bones];
        self.influences[v].iter().map(|&(b, w)| w * row[b as usize].apply(self.rest[v])).sum()
    }
}

/// SSDR with `bones` bones (1 to the vertex count): the motion clustering, then alternate
/// weight and transform steps.
fn fit_bones(seq: &Sequence, opts: &FitOptions, bones: usize) -> Fit {
    let frames = &seq.frames;
    let rest: Vec<DVec3> = frames[0].iter().map(|p| p.as_dvec3()).collect();
    let sample = cluster::sample_frames(frames.len(), opts.sample_frames as usize);
    let clusters = cluster::cluster(&rest, frames, bones, opts.cluster_iterations, &sample);
    let mut fit =
        Fit { bones, influences: clusters.labels.iter().map(|&b| vec![(b, 1.0)]).collect(), transforms: clusters.transforms, rest };
    let k = opts.candidates as usize;
    let mut last = f64::INFINITY;
    for _ in 0..opts.iterations {
        // Candidates again after every transform step: the bones have moved since.
        let cands = weights::candidates(&fit.rest, frames, &fit.transforms, bones, k, &sample, Some(&fit.influences));
        for (v, c) in cands.iter().enumerate() {
            fit.influences[v] = weights::solve_vertex(v, fit.rest[v], frames, &fit.transforms, bones, c);
        }
        bones::update(&fit.rest, frames, &fit.influences, &mut fit.transforms, bones);
        // Stop once an alternation gains under 0.1%: the fit has converged for the coder.
        let now = objective(seq, &fit);
        if !(now < last * (1.0 - 1e-3)) {
            break;
        }
        last = now;
    }
    fit
}

/// About the bits a coder spends on `fit`: the residuals' changes from frame to frame (what
/// the container codes between keyframes, predicting a frame from the previous one moved by
/// skinning) in quanta of `opts.quant_bits`, at their zeroth-order entropy, plus
/// `opts.bone_bits` per bone per frame and 12 bits per stored influence.
fn estimated_bits(seq: &Sequence, fit: &Fit, opts: &FitOptions) -> f64 {
    let extent = seq.bounds().map_or(0.0, |(lo, hi)| (hi - lo).max_element() as f64);
    let quantum = (extent / ((1u64 << opts.quant_bits) - 1) as f64).max(f64::MIN_POSITIVE);
    let n = fit.rest.len();
    let mut before = vec![[0i64; 3]; n];
    let mut counts: std::collections::BTreeMap<i64, u64> = std::collections::BTreeMap::new();
    for (f, frame) in seq.frames.iter().enumerate() {
        for v in 0..n {
            let e = ((frame[v].as_dvec3() - fit.pose(f, v)) / quantum).round();
            let e = [e.x as i64, e.y as i64, e.z as i64];
            if f > 0 {
                for a in 0..3 {
                    *counts.entry(e[a] - before[v][a]).or_default() += 1;
                }
            }
            before[v] = e;
        }
    }
    let total = counts.values().sum::<u64>() as f64;
    let residual_bits: f64 = counts.values().map(|&c| -(c as f64) * (c as f64 / total).log2()).sum();
    let influences: usize = fit.influences.iter().map(Vec::len).sum();
    residual_bits + (seq.frames.len() * fit.bones * opts.bone_bits as usize) as f64 + 12.0 * influences as f64
}

/// The fit's objective, Le and Deng's: squared residuals over all vertices and frames.
fn objective(seq: &Sequence, fit: &Fit) -> f64 {
    let mut total = 0.0;
    for (f, frame) in seq.frames.iter().enumerate() {
        for (v, p) in frame.iter().enumerate() {
            total += p.as_dvec3().distance_squared(fit.pose(f, v));
        }
    }
    total
}

/// The fit as a [`SequenceSkin`]: bones no vertex depends on are dropped and the rest
/// renumbered in order, weights sorted largest first, and the report measured.
fn to_skin(seq: &Sequence, fit: &Fit) -> (SequenceSkin, FitReport) {
    let (rest, influences, transforms, bones) = (&fit.rest[..], &fit.influences[..], &fit.transforms[..], fit.bones);
    let mut used = vec![false; bones];
    for infl in influences {
        for &(b, w) in infl {
            used[b as usize] |= w > 0.0;
        }
    }
    let mut renumber = vec![u32::MAX; bones];
    let mut kept = Vec::new();
    for b in 0..bones {
        if used[b] {
            renumber[b] = kept.len() as u32;
            kept.push(b);
        }
    }
    let n = rest.len();
    let mut skin = SequenceSkin {
        palette_len: kept.len() as u32,
        palette_names: (0..kept.len()).map(|b| format!("fitted bone {b}")).collect(),
        rest: seq.frames[0].clone(),
        joints: vec![[0; 4]; n],
        weights: vec![[0.0; 4]; n],
        ..Default::default()
    };
    for (v, infl) in influences.iter().enumerate() {
        for (slot, &(b, w)) in infl.iter().take(weights::MAX_INFLUENCES).enumerate() {
            skin.joints[v][slot] = renumber[b as usize];
            skin.weights[v][slot] = w as f32;
        }
        // f32 rounding: the strongest weight takes the difference so the sum is one.
        let sum: f32 = skin.weights[v].iter().sum();
        skin.weights[v][0] += 1.0 - sum;
    }
    for f in 0..seq.frames.len() {
        skin.matrices.push(kept.iter().map(|&b| rows(&transforms[f * bones + b])).collect());
    }
    let diagonal = seq.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length() as f64).max(f64::MIN_POSITIVE);
    let (mut sum2, mut max2, mut count) = (0.0f64, 0.0f64, 0usize);
    for (f, frame) in seq.frames.iter().enumerate() {
        for (v, p) in frame.iter().enumerate() {
            let x: DVec3 = influences[v].iter().map(|&(b, w)| w * transforms[f * bones + b as usize].apply(rest[v])).sum();
            let d2 = x.distance_squared(p.as_dvec3());
            sum2 += d2;
            max2 = max2.max(d2);
            count += 1;
        }
    }
    let report = FitReport {
        bones: kept.len() as u32,
        rms_error: (sum2 / count.max(1) as f64).sqrt() / diagonal,
        max_error: max2.sqrt() / diagonal,
    };
    (skin, report)
}

/// `[R | t]` as the skin's three rows, row-major.
fn rows(m: &Rigid) -> [f32; 12] {
    let r = m.r;
    let mut out = [0.0f32; 12];
    for a in 0..3 {
        let row = r.row(a);
        out[4 * a..4 * a + 4].copy_from_slice(&[row.x as f32, row.y as f32, row.z as f32, m.t[a] as f32]);
    }
    out
}
