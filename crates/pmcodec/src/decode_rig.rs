//! `pmcodec decode --skinned-glb`: a skinned file's rig as a skinned GLB (issue 19 item 4), so
//! that a skin fitted to a simulation or a capture (`encode --fit-skin --keep-skin`) or carried
//! from a glTF goes into an engine as a skinned mesh: the input's vertices at their bind
//! positions, their influences, and every frame's palette as the bones' animation. The motion
//! the skin does not explain (the residuals the file codes after skinning) is not in the GLB;
//! what it leaves out is measured against the decoded frames and reported.

use crate::codec_cmd::container_error;
use crate::{EXIT_BAD_INPUT, Exit, progress};
use anyhow::{Context, anyhow};
use glam::Vec3;
use pmcodec_container::{CutTarget, Decoder, FileSource, bind_position, influences, palette_transforms};
use pmcodec_mesh::rig_glb::{MAX_BONES, Rig, rig_glb};
use serde::Serialize;
use std::path::Path;

/// What `--json` says of a written rig.
#[derive(Serialize)]
pub struct RigOutput {
    pub path: String,
    pub vertices: usize,
    triangles: usize,
    pub bones: usize,
    pub frames: u32,
    /// Vertices no bone moves (they stay at their frame-0 position).
    still_vertices: usize,
    /// Distance between the rig's posed vertices and the decoded frames, over every vertex of
    /// every frame, as a fraction of the bounding-box diagonal: the motion left out.
    pub rms_error: f64,
    pub max_error: f64,
}

/// Decodes every frame of a skinned file at full resolution and writes its rig to `out`.
pub fn decode_rig(dec: &mut Decoder<&FileSource>, input: &Path, out: &Path, quiet: bool) -> Result<RigOutput, Exit> {
    let h = dec.reader().header().clone();
    let bad = |m: String| Exit(EXIT_BAD_INPUT, anyhow!("{}: {m}", input.display()));
    if h.skin.is_none() {
        return Err(bad("the file has no skin (encode a glTF skin, or an OBJ sequence with --fit-skin --keep-skin)".into()));
    }
    let n = h.vertex_count as usize;
    let where_ = |f: u32| format!("{} frame {f}", input.display());
    dec.seek(0).map_err(|e| container_error(e, where_(0)))?;
    let first = dec.positions();
    let triangles = dec.mesh(CutTarget::Level(0)).map_err(|e| container_error(e, where_(0)))?.triangles;
    let Some((nodes, _)) = dec.skin() else { return Err(bad("frame 0 has no skin".into())) };
    let bones = h.skin.as_ref().map_or(0, |s| s.palette_len as usize);
    if bones > MAX_BONES {
        return Err(bad(format!("{bones} palette entries; a GLB skin holds at most {MAX_BONES} bones")));
    }
    let mut rig = Rig { triangles, frame_rate: h.frame_rate, ..Default::default() };
    for v in 0..n {
        let node = nodes.get(v).copied().unwrap_or_default();
        let inf = influences(&node);
        let moved = inf.iter().any(|&(_, w)| w > 0.0);
        rig.rest.push(if moved { bind_position(&h, &node).unwrap_or_default() } else { first.get(v).copied().unwrap_or_default() });
        rig.bones.push(inf.map(|(j, w)| if w > 0.0 { j as u16 } else { 0 }));
        rig.weights.push(inf.map(|(_, w)| w));
    }
    let still = rig.weights.iter().filter(|w| w.iter().all(|&x| x == 0.0)).count();
    let diagonal = (Vec3::from_array(h.bbox_max) - Vec3::from_array(h.bbox_min)).length().max(f32::MIN_POSITIVE) as f64;
    let (mut sum, mut max) = (0.0f64, 0.0f64);
    let mut decoded = Vec::with_capacity(n);
    let bar = progress(h.frame_count as u64, "decode", quiet);
    for f in 0..h.frame_count {
        dec.seek(f).map_err(|e| container_error(e, where_(f)))?;
        let palette = dec.skin().map(|(_, p)| p).unwrap_or_default();
        let pose = palette_transforms(&h, palette).unwrap_or_default();
        if pose.len() != bones {
            return Err(bad(format!("frame {f}: {} palette entries, frame 0 has {bones}", pose.len())));
        }
        dec.positions_into(&mut decoded);
        for v in 0..n {
            let mut p = Vec3::ZERO;
            let mut total = 0.0;
            for k in 0..4 {
                let w = rig.weights[v][k];
                if w > 0.0 {
                    p += w * pose[rig.bones[v][k] as usize].transform_point3(rig.rest[v]);
                    total += w;
                }
            }
            let posed = if total > 0.0 { p / total } else { rig.rest[v] };
            let d = posed.distance(decoded.get(v).copied().unwrap_or_default()) as f64;
            sum += d * d;
            max = max.max(d);
        }
        rig.poses.push(pose);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let glb = rig_glb(&rig).map_err(|e| bad(e.to_string()))?;
    pmcodec_mesh::write::write_atomic(out, &glb).with_context(|| format!("writing {}", out.display()))?;
    let samples = (n as f64 * h.frame_count as f64).max(1.0);
    Ok(RigOutput {
        path: out.display().to_string(),
        vertices: n,
        triangles: rig.triangles.len(),
        bones,
        frames: h.frame_count,
        still_vertices: still,
        rms_error: (sum / samples).sqrt() / diagonal,
        max_error: max / diagonal,
    })
}
