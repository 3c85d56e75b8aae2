//! A skin for a sequence that has none: a few rigid bones per frame and at most four weights
//! per vertex, fitted to the whole sequence by Le and Deng's smooth skinning decomposition with
//! rigid bones ("Smooth Skinning Decomposition with Rigid Bones", 2012; SSDR). The result is a
//! [`SequenceSkin`] like a skinned glTF's, so the container predicts every node at every level
//! by linear blend skinning from it and codes only residuals (the motion compensation of MPEG-4
//! FAMC, Mamou, Zaharia and Prêteux, 2008, for animations without a skeleton).
//!
//! The steps, one per file: `sample` (the vertices and frames the bones are fitted to),
//! `cluster` (bones from vertices clustered by motion), then alternately `weights` (each
//! vertex's non-negative, affine weights on its candidate bones) and `bones` (each bone's rigid
//! transform per frame by weighted Procrustes, `horn`). The rest pose is frame 0, where every
//! bone is the identity. Deterministic (no randomness, every loop in a fixed order) and
//! bounded: the bone count, the iterations, the vertices and the frames the search for bones
//! looks at are capped, and only the last weight step visits every vertex and frame.

// Per-vertex and per-bone loops index several parallel arrays at once, as the paper states them.
#![allow(clippy::needless_range_loop)]

mod bones;
mod cluster;
mod horn;
mod sample;
mod weights;

use crate::{Sequence, SequenceSkin};
use glam::DVec3;
use horn::{Rigid, fit_rigid};
use rayon::prelude::*;
use sample::Data;

/// Most bones a fit may have: past this the pose costs more per frame than skinning saves, and
/// the clustering's cost (vertices x bones x frames) grows out of bounds.
pub const MAX_BONES: u32 = 256;

/// Vertices the bones are fitted to per bone at least (a rigid transform needs three points
/// off a line; more average out what a bone does not explain: with 8 per bone the horse's
/// held-out residual grew past what 256 bones could pay for).
pub const SAMPLES_PER_BONE: u32 = 16;

/// What a fit is told.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Bones to fit; `None` to choose the count by cost: [`default_bones`] of the vertex count,
    /// doubled while the residuals' estimated bits drop by more than the added bones cost
    /// ([`FitOptions::bone_bits`]). At most the vertex count are used.
    pub bones: Option<u32>,
    /// Lloyd iterations of the motion clustering that places the first bones (and that
    /// settles the bones a doubling splits).
    pub cluster_iterations: u32,
    /// Alternations of SSDR's weight and transform steps at each bone count tried.
    pub iterations: u32,
    /// Candidate bones per vertex in the weight step (at least the 4 influences a vertex keeps;
    /// more pays: the fit picks the four it keeps among them), at most 8.
    pub candidates: u32,
    /// Frames the search for bones compares (pairs of consecutive frames, evenly spaced);
    /// the bones are then fitted to every frame.
    pub sample_frames: u32,
    /// Vertices the bones are fitted to (evenly spaced in the rest pose; at least
    /// [`SAMPLES_PER_BONE`] per bone, all of them on a small mesh); every vertex gets its
    /// weights once the bones are fitted.
    pub sample_vertices: u32,
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
        FitOptions {
            bones: None,
            cluster_iterations: 6,
            iterations: 6,
            candidates: 6,
            sample_frames: 16,
            sample_vertices: 4096,
            quant_bits: 12,
            bone_bits: 96,
        }
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

/// How well a fitted skin reproduces its sequence, and what the fit did.
#[derive(Clone, Debug, PartialEq)]
pub struct FitReport {
    /// Bones kept (those some vertex depends on).
    pub bones: u32,
    /// Root mean square of the distance between a vertex and its skinned position, over all
    /// vertices and frames, as a fraction of the sequence's bounding-box diagonal.
    pub rms_error: f64,
    /// The largest such distance, as the same fraction.
    pub max_error: f64,
    /// Vertices the bones were fitted to (the rest get weights only).
    pub sample_vertices: u32,
    /// Bone counts tried, in order (one when the count was given).
    pub counts_tried: Vec<u32>,
    /// Weight-and-transform alternations run, over all counts tried.
    pub alternations: u32,
}

/// Fits a skin to `seq` (any skin it has is ignored): returns the skin, which
/// [`SequenceSkin::validate`] accepts for `seq`, and how closely it reproduces the frames.
///
/// The bones are fitted on [`FitOptions::sample_vertices`] vertices over
/// [`FitOptions::sample_frames`] frames; a doubling of the bone count starts from the last fit
/// with its worst bones split ([`cluster::split`]); the count is chosen by the bits estimated
/// on held-out vertices; then the chosen bones are fitted to every frame and every vertex gets
/// its weights, once.
pub fn fit_skin(seq: &Sequence, opts: &FitOptions) -> Result<(SequenceSkin, FitReport), FitError> {
    seq.validate()?;
    let n = seq.vertex_count();
    let requested = opts.bones.unwrap_or_else(|| default_bones(n));
    if requested == 0 || requested > MAX_BONES {
        return Err(FitError::Bones(requested));
    }
    if opts.candidates == 0 || opts.candidates as usize > weights::MAX_CANDIDATES {
        return Err(FitError::Option { name: "candidates", value: opts.candidates, why: "use 1 to 8 candidate bones" });
    }
    if opts.sample_frames < 2 {
        return Err(FitError::Option { name: "sample_frames", value: opts.sample_frames, why: "compare at least 2 frames" });
    }
    if opts.sample_vertices == 0 {
        return Err(FitError::Option { name: "sample_vertices", value: 0, why: "fit to at least one vertex" });
    }
    if !(4..=24).contains(&opts.quant_bits) {
        return Err(FitError::Option { name: "quant_bits", value: opts.quant_bits, why: "use 4 to 24 bits" });
    }
    let cap = (MAX_BONES as usize).min(n);
    let first = (requested as usize).min(cap);
    let largest = if opts.bones.is_some() { first } else { cap };
    let fit_count = (opts.sample_vertices as usize).max(SAMPLES_PER_BONE as usize * largest).min(n);
    let (fit_ids, held_ids) = sample::vertex_samples(&seq.frames[0], fit_count);
    let search_frames = sample::frame_pairs(seq.frames.len(), opts.sample_frames as usize);
    let data = Data::new(&seq.frames, Some(&fit_ids), search_frames.clone());
    let mut report = Trace { counts: Vec::new(), alternations: 0 };
    let clusters = cluster::cluster(&data, first, opts.cluster_iterations);
    let mut best = alternate(&data, start(clusters, first), opts, &mut report);
    report.counts.push(first as u32);
    if opts.bones.is_none() && best.bones < cap {
        // The bone count by cost (Le and Deng pick it by hand; a coder can count): fits at
        // doubling counts, each from the last, kept while one pays for its bones on vertices
        // none of them was fitted to.
        let held = Data::new(&seq.frames, Some(&held_ids), search_frames);
        let mut best_bits = estimated_bits(seq, &data, &held, &best, opts);
        while best.bones < cap {
            let count = (2 * best.bones).min(cap);
            let error = errors(&data, &best);
            let labels = cluster::split(&data, &main_bones(&best), &error, best.bones, count);
            // The split bones start near their optimum: fewer Lloyd iterations and
            // alternations than a fit from scratch.
            let clusters = cluster::lloyd(&data, labels, count, opts.cluster_iterations.min(WARM_ITERATIONS));
            let warm = FitOptions { iterations: opts.iterations.min(WARM_ITERATIONS), ..opts.clone() };
            let next = alternate(&data, start(clusters, count), &warm, &mut report);
            report.counts.push(count as u32);
            let bits = estimated_bits(seq, &data, &held, &next, opts);
            if !(bits < best_bits) {
                break;
            }
            (best, best_bits) = (next, bits);
        }
    }
    let fit = finish(seq, &fit_ids, &data, &best, opts);
    let (skin, mut out) = to_skin(seq, &fit);
    out.sample_vertices = fit_ids.len() as u32;
    out.counts_tried = report.counts;
    out.alternations = report.alternations;
    Ok((skin, out))
}

/// Lloyd iterations and alternations at most for a bone count started from the last one's
/// split bones.
const WARM_ITERATIONS: u32 = 3;

/// What a fit did, for its report.
struct Trace {
    counts: Vec<u32>,
    alternations: u32,
}

/// A fit with its bone count: every vertex's influences and every bone's transform per frame
/// of its data (`transforms[fi * bones + b]`).
#[derive(Clone)]
struct Fit {
    bones: usize,
    influences: Vec<Vec<(u32, f64)>>,
    transforms: Vec<Rigid>,
}

impl Fit {
    /// Vertex `i` of `data` posed in its `fi`-th frame.
    #[inline]
    fn pose(&self, data: &Data, fi: usize, i: usize) -> DVec3 {
        let row = &self.transforms[fi * self.bones..(fi + 1) * self.bones];
        self.influences[i].iter().map(|&(b, w)| w * row[b as usize].apply(data.rest[i])).sum()
    }
}

/// A fit from a clustering: every vertex wholly on its cluster's bone.
fn start(clusters: cluster::Clusters, bones: usize) -> Fit {
    Fit { bones, influences: clusters.labels.iter().map(|&b| vec![(b, 1.0)]).collect(), transforms: clusters.transforms }
}

/// Each vertex's strongest bone.
fn main_bones(fit: &Fit) -> Vec<u32> {
    fit.influences.iter().map(|i| i.first().map_or(0, |p| p.0)).collect()
}

/// Each vertex's squared error under `fit`, summed over the frames of `data`.
fn errors(data: &Data, fit: &Fit) -> Vec<f64> {
    (0..data.len())
        .into_par_iter()
        .map(|i| (0..data.frames.len()).map(|fi| data.at(fi, i).distance_squared(fit.pose(data, fi, i))).sum())
        .collect()
}

/// SSDR's alternation on `data` from `fit`: weights, then transforms, until an alternation
/// gains under 0.1% (the fit has converged for the coder) or `opts.iterations` have run.
fn alternate(data: &Data, mut fit: Fit, opts: &FitOptions, trace: &mut Trace) -> Fit {
    let k = opts.candidates as usize;
    let all: Vec<usize> = (0..data.frames.len()).collect();
    let mut last = f64::INFINITY;
    for _ in 0..opts.iterations {
        trace.alternations += 1;
        // Candidates again after every transform step: the bones have moved since.
        let near = cluster::near_bones(&data.rest, &cluster::centroids(&data.rest, &main_bones(&fit), fit.bones));
        // Vertices are independent: solved in parallel, collected in order (the same result
        // on any number of threads).
        fit.influences = (0..data.len())
            .into_par_iter()
            .map(|i| {
                let c = weights::candidates(data, i, &fit.transforms, k, &near[i], &all, &fit.influences[i]);
                weights::solve_vertex(data, i, &fit.transforms, fit.bones, c.as_slice())
            })
            .collect();
        bones::update(data, &fit.influences, &mut fit.transforms, fit.bones);
        let now: f64 = errors(data, &fit).iter().sum();
        if !(now < last * (1.0 - 1e-3)) {
            break;
        }
        last = now;
    }
    fit
}

/// The bones of `fit` (fitted to the search frames of `data`, its vertices `fit_ids`) fitted
/// to every frame, then every vertex's weights solved over every frame.
fn finish(seq: &Sequence, fit_ids: &[usize], data: &Data, fit: &Fit, opts: &FitOptions) -> Fit {
    let frames = seq.frames.len();
    let bones = fit.bones;
    let sampled = Data::new(&seq.frames, Some(fit_ids), (0..frames).collect());
    // Frames the search saw keep their transforms; the others start from a rigid fit of each
    // bone's main vertices and are refined by SSDR's transform step with the weights found.
    let mut transforms = vec![Rigid::IDENTITY; frames * bones];
    let labels = main_bones(fit);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); bones];
    for (i, &b) in labels.iter().enumerate() {
        members[b as usize].push(i);
    }
    let mut seen = vec![None; frames];
    for (fi, &f) in data.frames.iter().enumerate() {
        seen[f] = Some(fi);
    }
    transforms.par_chunks_mut(bones).enumerate().skip(1).for_each(|(f, row)| {
        for b in 0..bones {
            row[b] = match seen[f] {
                Some(fi) => fit.transforms[fi * bones + b],
                None => fit_rigid(members[b].iter().map(|&i| (sampled.rest[i], sampled.at(f, i), 1.0))),
            };
        }
    });
    for _ in 0..FINAL_TRANSFORM_STEPS {
        bones::update(&sampled, &fit.influences, &mut transforms, bones);
    }
    // Every vertex's weights, once: candidates among the bones near it, scored over the
    // search frames, solved over all frames.
    let everything = Data::new(&seq.frames, None, (0..frames).collect());
    let near = cluster::near_bones(&everything.rest, &cluster::centroids(&data.rest, &labels, bones));
    let mut own = vec![None; seq.vertex_count()];
    for (i, &v) in fit_ids.iter().enumerate() {
        own[v] = Some(i);
    }
    let k = opts.candidates as usize;
    let solve_all = |transforms: &[Rigid], keep: &(dyn Fn(usize) -> Vec<(u32, f64)> + Sync)| -> Vec<Vec<(u32, f64)>> {
        (0..everything.len())
            .into_par_iter()
            .map(|v| {
                let c = weights::candidates(&everything, v, transforms, k, &near[v], &data.frames, &keep(v));
                weights::solve_vertex(&everything, v, transforms, bones, c.as_slice())
            })
            .collect()
    };
    let mut influences = solve_all(&transforms, &|v| own[v].map_or(Vec::new(), |i| fit.influences[i].clone()));
    for _ in 0..FINAL_ALTERNATIONS {
        bones::update(&everything, &influences, &mut transforms, bones);
        let prev = influences.clone();
        influences = solve_all(&transforms, &|v| prev[v].clone());
    }
    Fit { bones, influences, transforms }
}

/// SSDR alternations over every vertex and frame after the search: the bones fitted to the
/// subsample refitted to every vertex's weights, then the weights to those bones. One such
/// alternation brings the horse's residual (12-bit quanta) from 1.56 to 0.99 RMS with bones fitted
/// to 2,048 vertices.
const FINAL_ALTERNATIONS: usize = 1;

/// Transform steps on every frame after the search: the frames the search did not see start
/// from a rigid fit of each bone's vertices, which two steps bring to the blend's optimum
/// closely enough that a third gains nothing measurable.
const FINAL_TRANSFORM_STEPS: usize = 2;

/// About the bits a coder spends on `fit`, measured on `held` (vertices the bones were not
/// fitted to, over the search's frame pairs) and scaled to the whole sequence: the residuals'
/// changes from one frame to the next (what the container codes between keyframes, predicting
/// a frame from the previous one moved by skinning) in quanta of `opts.quant_bits`, at their
/// zeroth-order entropy, plus `opts.bone_bits` per bone per frame and 12 bits per stored
/// influence.
fn estimated_bits(seq: &Sequence, data: &Data, held: &Data, fit: &Fit, opts: &FitOptions) -> f64 {
    let extent = seq.bounds().map_or(0.0, |(lo, hi)| (hi - lo).max_element() as f64);
    let quantum = (extent / ((1u64 << opts.quant_bits) - 1) as f64).max(f64::MIN_POSITIVE);
    let near = cluster::near_bones(&held.rest, &cluster::centroids(&data.rest, &main_bones(fit), fit.bones));
    let all: Vec<usize> = (0..held.frames.len()).collect();
    // Held-out vertices are independent: solved in parallel, each into a count of its residual
    // changes, the counts summed (integer sums: the same on any number of threads).
    type Counts = (std::collections::HashMap<i64, u64>, usize);
    let per_vertex = |(mut counts, influences): Counts, i: usize| -> Counts {
        let c = weights::candidates(held, i, &fit.transforms, opts.candidates as usize, &near[i], &all, &[]);
        let weights_of = weights::solve_vertex(held, i, &fit.transforms, fit.bones, c.as_slice());
        let mut before = [0i64; 3];
        for fi in 0..held.frames.len() {
            let row = &fit.transforms[fi * fit.bones..(fi + 1) * fit.bones];
            let posed: DVec3 = weights_of.iter().map(|&(b, w)| w * row[b as usize].apply(held.rest[i])).sum();
            let e = ((held.at(fi, i) - posed) / quantum).round();
            let e = [e.x as i64, e.y as i64, e.z as i64];
            if fi > 0 && held.frames[fi] == held.frames[fi - 1] + 1 {
                for a in 0..3 {
                    *counts.entry(e[a] - before[a]).or_default() += 1;
                }
            }
            before = e;
        }
        (counts, influences + weights_of.len())
    };
    let merge = |(mut a, na): Counts, (b, nb): Counts| -> Counts {
        for (k, c) in b {
            *a.entry(k).or_default() += c;
        }
        (a, na + nb)
    };
    let (counts, influences) = (0..held.len()).into_par_iter().fold(Counts::default, per_vertex).reduce(Counts::default, merge);
    let total = counts.values().sum::<u64>() as f64;
    // Summed in the order of the values, so the estimate does not depend on the map's order.
    let mut sorted: Vec<(i64, u64)> = counts.into_iter().collect();
    sorted.sort_unstable();
    let per_symbol: f64 = sorted.iter().map(|&(_, c)| -(c as f64 / total) * (c as f64 / total).log2()).sum::<f64>();
    let (n, frames) = (seq.vertex_count() as f64, seq.frames.len() as f64);
    let per_vertex_influences = influences as f64 / held.len().max(1) as f64;
    let residual_bits = if total > 0.0 { per_symbol * 3.0 * n * (frames - 1.0) } else { 0.0 };
    residual_bits + frames * (fit.bones * opts.bone_bits as usize) as f64 + 12.0 * per_vertex_influences * n
}

/// The fit as a [`SequenceSkin`]: bones no vertex depends on are dropped and the rest
/// renumbered in order, weights sorted largest first, and the report measured. `fit` holds
/// every vertex and every frame.
fn to_skin(seq: &Sequence, fit: &Fit) -> (SequenceSkin, FitReport) {
    let rest: Vec<DVec3> = seq.frames[0].iter().map(|p| p.as_dvec3()).collect();
    let (influences, transforms, bones) = (&fit.influences[..], &fit.transforms[..], fit.bones);
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
        sample_vertices: 0,
        counts_tried: Vec::new(),
        alternations: 0,
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
