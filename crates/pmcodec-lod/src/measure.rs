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
    /// Surface samples for the two-sided RMS distance (count and seed; fixed seed, so runs repeat).
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
    /// Frames measured, over every animation.
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
    // The baseline is geometric: its triangles no longer match the input's corner wedges.
    lod.appearance = None;
    lod
}

/// Texture-coordinate error of `lod` against `reference` in the rest pose: RMS over points
/// sampled uniformly by area on the reference surface of the distance between the reference's
/// `TEXCOORD_0` there and the LOD's `TEXCOORD_0` at the closest point of the LOD surface
/// (interpolated over its triangle's corner wedges), in percent of the texture's width. `None`
/// when either has no texture coordinates.
pub fn uv_error(reference: &RiggedMesh, lod: &RiggedMesh, samples: usize, seed: u64) -> Result<Option<f64>, LodError> {
    let (Some(ra), Some(la)) = (reference.appearance.as_ref(), lod.appearance.as_ref()) else { return Ok(None) };
    if ra.uv0.is_empty() || la.uv0.is_empty() || ra.corner_wedges.len() != reference.triangles.len() {
        return Ok(None);
    }
    let rp = reference.pose(None, 0.0);
    let lp = lod.pose(None, 0.0);
    let index = pmcodec_eval::SurfaceIndex::new(&TriMesh { positions: lp.clone(), triangles: lod.triangles.clone() })?;
    // Cumulative areas to sample triangles by area.
    let mut cumulative = Vec::with_capacity(reference.triangles.len());
    let mut total = 0.0f64;
    for t in &reference.triangles {
        let [a, b, c] = t.map(|i| rp[i as usize]);
        total += f64::from((b - a).cross(c - a).length());
        cumulative.push(total);
    }
    if !(total > 0.0) {
        return Ok(None);
    }
    let uv_at = |uv: &[[f32; 2]], cw: [u32; 3], w: [f32; 3]| -> glam::Vec2 {
        (0..3).map(|i| glam::Vec2::from_array(uv[cw[i] as usize]) * w[i]).sum()
    };
    let mut rng = pmcodec_eval::SplitMix64::new(seed);
    let mut sum = 0.0f64;
    for _ in 0..samples {
        let pick = rng.unit() * total;
        let t = cumulative.partition_point(|&c| c < pick).min(reference.triangles.len() - 1);
        let (mut s, mut r) = (rng.unit() as f32, rng.unit() as f32);
        if s + r > 1.0 {
            (s, r) = (1.0 - s, 1.0 - r);
        }
        let w = [1.0 - s - r, s, r];
        let [a, b, c] = reference.triangles[t].map(|i| rp[i as usize]);
        let x = a * w[0] + b * w[1] + c * w[2];
        let want = uv_at(&ra.uv0, ra.corner_wedges[t], w);
        let (_, lt) = index.closest(x);
        let (Some(tri), Some(cw)) = (lod.triangles.get(lt as usize), la.corner_wedges.get(lt as usize)) else { continue };
        let corners = tri.map(|i| lp[i as usize]);
        let got = uv_at(&la.uv0, *cw, barycentric(x, corners));
        sum += f64::from((want - got).length_squared());
    }
    Ok(Some(100.0 * (sum / samples.max(1) as f64).sqrt()))
}

/// Barycentric coordinates of the point of triangle `t` closest to `p`.
fn barycentric(p: Vec3, t: [Vec3; 3]) -> [f32; 3] {
    let q = pmcodec_eval::triangle::closest_point(p.as_dvec3(), t.map(|v| v.as_dvec3()));
    let (v0, v1, v2) = (t[1].as_dvec3() - t[0].as_dvec3(), t[2].as_dvec3() - t[0].as_dvec3(), q - t[0].as_dvec3());
    let (d00, d01, d11, d20, d21) = (v0.dot(v0), v0.dot(v1), v1.dot(v1), v2.dot(v0), v2.dot(v1));
    let den = d00 * d11 - d01 * d01;
    if !(den.abs() > 1e-30) {
        return [1.0, 0.0, 0.0];
    }
    let b = (d11 * d20 - d01 * d21) / den;
    let c = (d00 * d21 - d01 * d20) / den;
    [(1.0 - b - c) as f32, b as f32, c as f32]
}
