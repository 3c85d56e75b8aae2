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
    /// Bones to fit; `None` for [`default_bones`] of the vertex count. At most the vertex
    /// count are used.
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
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { bones: None, cluster_iterations: 6, iterations: 6, candidates: 6, sample_frames: 16 }
    }
}

/// The bones a fit uses by default for `n` vertices: one per 200 vertices, from 4 to 64. On
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
    let bones = (requested as usize).min(n);
    let frames = &seq.frames;
    let rest: Vec<DVec3> = frames[0].iter().map(|p| p.as_dvec3()).collect();
    let sample = cluster::sample_frames(frames.len(), opts.sample_frames as usize);
    let clusters = cluster::cluster(&rest, frames, bones, opts.cluster_iterations, &sample);
    let mut transforms = clusters.transforms;
    let mut influences: Vec<Vec<(u32, f64)>> = clusters.labels.iter().map(|&b| vec![(b, 1.0)]).collect();
    let cands = weights::candidates(&rest, frames, &transforms, bones, opts.candidates as usize, &sample);
    for _ in 0..opts.iterations {
        for (v, c) in cands.iter().enumerate() {
            influences[v] = weights::solve_vertex(v, rest[v], frames, &transforms, bones, c);
        }
        bones::update(&rest, frames, &influences, &mut transforms, bones);
    }
    Ok(to_skin(seq, &rest, &influences, &transforms, bones))
}

/// The fit as a [`SequenceSkin`]: bones no vertex depends on are dropped and the rest
/// renumbered in order, weights sorted largest first, and the report measured.
fn to_skin(
    seq: &Sequence,
    rest: &[DVec3],
    influences: &[Vec<(u32, f64)>],
    transforms: &[Rigid],
    bones: usize,
) -> (SequenceSkin, FitReport) {
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
