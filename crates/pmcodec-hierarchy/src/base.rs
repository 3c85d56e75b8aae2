//! The quadrics the base hierarchy H_0 is built from.
//!
//! Kircher & Garland ("Progressive Multiresolution Meshes for Deforming Surfaces", 2005) build H_0
//! from frame 0 alone. Mohr & Gleicher ("Deformation Sensitive Decimation", 2003, section 4) sum
//! one quadric per example pose, so a collapse is cheap only if it is cheap in every pose; Berner &
//! Rieger ("Surface Simplification Guided by Morph-Targets", 2006) weight each vertex's quadric by
//! how far it moves between morph targets, so regions that deform are kept denser. Both are options
//! here.

use crate::quadric::{Quadric, QuadricOptions, vertex_quadrics};
use crate::topology::FineTopology;
use pmcodec_mesh::Sequence;

/// Which frames' quadrics are summed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PoseSet {
    /// Frame 0 only (Kircher & Garland).
    #[default]
    FirstFrame,
    /// Every frame (Mohr & Gleicher).
    AllFrames,
    /// This many frames spread evenly over the sequence, frame 0 included.
    Sampled(u32),
}

/// Per-vertex importance multiplied into the quadrics.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum VertexWeights {
    /// Every vertex weighs 1.
    #[default]
    None,
    /// Berner & Rieger: displacement between the morph targets (from the input), falling back to
    /// per-frame displacement when the input has no morph targets; weights 0.33 / 0.66 / 1.0 by
    /// tertile of displacement.
    Tertiles,
    /// As `Tertiles` but continuous: 1/3 + 2/3 * d / max d.
    Smooth,
}

/// The quadrics the base hierarchy H_0 is built from: which frames, how vertices are weighted,
/// and the quadric options.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct BaseOptions {
    /// The frames whose quadrics are summed (Mohr & Gleicher 2003: several poses).
    pub poses: PoseSet,
    /// Per-vertex weights on the quadrics (Berner & Rieger 2006).
    pub weights: VertexWeights,
    /// How each frame's quadrics are made.
    pub quadric: QuadricOptions,
}

/// The frames `poses` selects from a sequence of `frames` frames.
pub fn pose_frames(poses: PoseSet, frames: usize) -> Vec<usize> {
    match poses {
        _ if frames == 0 => Vec::new(),
        PoseSet::FirstFrame => vec![0],
        PoseSet::AllFrames => (0..frames).collect(),
        PoseSet::Sampled(k) => {
            let k = (k.max(1) as usize).min(frames);
            let mut out: Vec<usize> = (0..k).map(|i| i * frames / k).collect();
            out.dedup();
            out
        }
    }
}

/// Per-vertex displacement: morph-target displacement from the input if present, else the sum
/// over frames of the distance to frame 0.
pub fn displacement(seq: &Sequence) -> Vec<f32> {
    if !seq.morph_displacement.is_empty() {
        return seq.morph_displacement.clone();
    }
    let n = seq.vertex_count();
    let mut d = vec![0f32; n];
    if let Some(first) = seq.frames.first() {
        for frame in &seq.frames[1..] {
            for ((acc, p), p0) in d.iter_mut().zip(frame).zip(first) {
                *acc += (*p - *p0).length();
            }
        }
    }
    d
}

/// Importance weights from displacements.
pub fn weights_from_displacement(d: &[f32], mode: VertexWeights) -> Vec<f64> {
    match mode {
        VertexWeights::None => vec![1.0; d.len()],
        VertexWeights::Smooth => {
            let max = d.iter().copied().fold(0f32, f32::max) as f64;
            d.iter().map(|&x| if max > 0.0 { 1.0 / 3.0 + 2.0 / 3.0 * x as f64 / max } else { 1.0 }).collect()
        }
        VertexWeights::Tertiles => {
            let mut sorted: Vec<f32> = d.to_vec();
            sorted.sort_unstable_by(f32::total_cmp);
            if sorted.is_empty() {
                return Vec::new();
            }
            let t1 = sorted[sorted.len() / 3];
            let t2 = sorted[sorted.len() * 2 / 3];
            d.iter()
                .map(|&x| {
                    if x < t1 {
                        0.33
                    } else if x < t2 {
                        0.66
                    } else {
                        1.0
                    }
                })
                .collect()
        }
    }
}

/// The fine-vertex quadrics to build H_0 from.
pub fn base_quadrics(seq: &Sequence, topo: &FineTopology, opts: &BaseOptions) -> Vec<Quadric> {
    let mut total = vec![Quadric::default(); seq.vertex_count()];
    let mut scratch = Vec::new();
    for f in pose_frames(opts.poses, seq.frame_count()) {
        vertex_quadrics(&seq.frames[f], &seq.triangles, &topo.boundary, &opts.quadric, &mut scratch);
        for (t, q) in total.iter_mut().zip(&scratch) {
            *t += q;
        }
    }
    if opts.weights != VertexWeights::None {
        let w = weights_from_displacement(&displacement(seq), opts.weights);
        for (q, w) in total.iter_mut().zip(w) {
            q.scale(w);
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_spread() {
        assert_eq!(pose_frames(PoseSet::Sampled(4), 48), vec![0, 12, 24, 36]);
        assert_eq!(pose_frames(PoseSet::Sampled(10), 3), vec![0, 1, 2]);
        assert_eq!(pose_frames(PoseSet::FirstFrame, 3), vec![0]);
    }

    #[test]
    fn tertile_weights() {
        let d = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(weights_from_displacement(&d, VertexWeights::Tertiles), vec![0.33, 0.33, 0.66, 0.66, 1.0, 1.0]);
        let s = weights_from_displacement(&d, VertexWeights::Smooth);
        assert!((s[0] - 1.0 / 3.0).abs() < 1e-9 && (s[5] - 1.0).abs() < 1e-9);
    }
}
