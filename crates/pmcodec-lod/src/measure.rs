//! The figures of issue 7: per-frame RMS surface distance between the input and an LOD, posed
//! at the same time of the same animation, in percent of the input frame's bounding-box
//! diagonal ([`pmcodec_eval::symmetric_relative`]); mean and max over the frames of every
//! animation. And the baseline: the rest pose simplified by meshoptimizer with its Regularize
//! option, as gltfpack does, keeping the input's skin (meshoptimizer only picks a subset of the
//! input's vertices).

use crate::LodError;
use glam::Vec3;
use pmcodec_eval::SampleOptions;
use pmcodec_mesh::TriMesh;
use pmcodec_mesh::gltf_input::RiggedMesh;
use serde::Serialize;

/// How frames are measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasureOptions {
    /// Frames per second at which every animation is sampled.
    pub frame_rate: f32,
    pub samples: SampleOptions,
}

impl Default for MeasureOptions {
    fn default() -> Self {
        MeasureOptions { frame_rate: 10.0, samples: SampleOptions { samples: 4000, seed: 0x5EED } }
    }
}

/// Error over frames, in percent of the bounding-box diagonal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Mean over frames of the per-frame RMS distance.
    pub mean: f64,
    /// Largest per-frame RMS distance.
    pub max: f64,
    pub frames: usize,
}

/// The mesh of `rig` at time `t` of animation `anim` (rest pose for `None`), without vertices
/// no triangle uses (the distance samples vertices too).
pub fn posed_mesh(rig: &RiggedMesh, anim: Option<usize>, t: f32) -> TriMesh {
    let positions = rig.pose(anim.and_then(|a| rig.animations.get(a)), t);
    compact(&positions, &rig.triangles)
}

/// Keeps the vertices `triangles` use, renumbered in order.
pub fn compact(positions: &[Vec3], triangles: &[[u32; 3]]) -> TriMesh {
    let mut map = vec![u32::MAX; positions.len()];
    let mut out = TriMesh::default();
    for tri in triangles {
        let t = tri.map(|i| {
            let slot = &mut map[i as usize];
            if *slot == u32::MAX {
                *slot = out.positions.len() as u32;
                out.positions.push(positions[i as usize]);
            }
            *slot
        });
        out.triangles.push(t);
    }
    out
}

/// The times every animation is measured at: `0, 1/rate, ...` up to its duration (the rest
/// pose alone when the rig has no animation).
pub fn frame_times(rig: &RiggedMesh, rate: f32) -> Vec<(Option<usize>, f32)> {
    if rig.animations.is_empty() {
        return vec![(None, 0.0)];
    }
    let mut out = Vec::new();
    for (i, a) in rig.animations.iter().enumerate() {
        let count = (a.duration.max(0.0) * rate).floor() as usize + 1;
        for k in 0..count.min(100_000) {
            out.push((Some(i), k as f32 / rate));
        }
    }
    out
}

/// Error of `lod` against `reference` over every frame of every animation of `reference`.
pub fn animation_error(reference: &RiggedMesh, lod: &RiggedMesh, opts: &MeasureOptions) -> Result<ErrorStats, LodError> {
    let mut stats = ErrorStats::default();
    let times = frame_times(reference, opts.frame_rate);
    for &(anim, t) in &times {
        let a = posed_mesh(reference, anim, t);
        let b = posed_mesh(lod, anim, t);
        let d = pmcodec_eval::symmetric_relative(&a, &b, &opts.samples)?;
        stats.mean += d.rms;
        stats.max = stats.max.max(d.rms);
    }
    stats.frames = times.len();
    stats.mean /= times.len().max(1) as f64;
    Ok(stats)
}

/// The baseline LOD: `rig`'s rest pose simplified by meshoptimizer (Regularize) to at most
/// `target` triangles; the rig is the input's with the new triangles.
pub fn meshopt_baseline(rig: &RiggedMesh, target: usize) -> RiggedMesh {
    let rest = rig.pose(None, 0.0);
    let positions: Vec<[f32; 3]> = rest.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = rig.triangles.iter().flatten().copied().collect();
    let out = meshopt::simplify_decoder(&indices, &positions, target * 3, f32::MAX, meshopt::SimplifyOptions::Regularize, None);
    let mut lod = rig.clone();
    lod.triangles = out.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    lod
}
