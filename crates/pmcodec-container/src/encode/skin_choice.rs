//! Whether a fitted skin pays for its bytes, told before the encode from the fit itself: the
//! finest band (the input vertices, most of a file's position bytes) coded on a sample of the
//! sequence's keyframe intervals under both predictions, beside the pose and bind bytes the skin
//! adds. Without it the CLI encoded with the skin, and where the skin did not clearly pay
//! encoded again without it (and a third time with every joint at every level), keeping the
//! smallest: samba-60 took three encodes.
//!
//! Why band 0 alone can be coded before the encode: its nodes are the input vertices, whose
//! positions, skins and stencils (the lower neighbours of the breadth-first order) do not
//! depend on the reclustering; and a keyframe interval's band 0 depends on nothing before its
//! keyframe (a keyframe predicts from its own frame, skinning's from the palette alone), so a
//! sample of whole intervals codes exactly as the encode will code them. The coarse bands are
//! left out: in them skinning saves more (coarse nodes sit at their skinned positions,
//! `skin::place`) and their Bind chunks cost more, and the two are about proportional to the
//! coarse node count; the estimate counts neither.
//!
//! The motion compensation weighed is MPEG-4 FAMC's (Mamou, Zaharia and Prêteux, "FAMC: the
//! MPEG-4 standard for animated mesh compression", 2008): skinning predicts, residuals are
//! coded, and the skin is worth its transforms and weights only where the residuals shrink by
//! more than those cost.

use super::positions::{PositionCoder, Skinning};
use super::{EncodeOptions, is_keyframe, quantization_step};
use crate::ContainerError;
use crate::format::{FLAGS, store_chunk};
use crate::predict::LowerNeighbours;
use crate::skin::{SkinState, band_entries, fit_skin, write_binds, write_joints};
use pmcodec_hierarchy::Hierarchy;
use pmcodec_mesh::Sequence;

/// Keyframe intervals [`skin_trial`] codes at most (evenly spread over the sequence): enough
/// to see the motion change over it, few enough that the trial stays a fraction of the encode.
pub const TRIAL_INTERVALS: usize = 2;

/// Frames [`skin_trial`] codes at most where the file has a single keyframe (interval 0).
pub const TRIAL_FRAMES: usize = 32;

/// The zstd level the trial sizes chunks at (the file's is [`crate::format::ZSTD_LEVEL`]).
const TRIAL_ZSTD_LEVEL: i32 = 3;

/// What coding band 0 both ways on a sample of frames found, in bytes scaled to the whole
/// sequence.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SkinTrial {
    /// Frames coded (whole keyframe intervals).
    pub frames_coded: u32,
    /// The sequence's frames.
    pub frames: u32,
    /// Band 0's position payload bytes under the default prediction.
    pub plain_bytes: u64,
    /// Band 0's position payload bytes with skinning competing per band, as the encoder codes
    /// them.
    pub skinned_bytes: u64,
    /// The pose bytes (one Joints chunk per frame carrying every bone, compressed as stored).
    pub pose_bytes: u64,
    /// Band 0's Bind chunk as stored.
    pub bind_bytes: u64,
}

impl SkinTrial {
    /// What skinning saves on band 0's positions over what its pose and band 0's binds cost,
    /// in bytes (negative: the skin costs more than it saves).
    pub fn margin(&self) -> i64 {
        self.plain_bytes as i64 - self.skinned_bytes as i64 - self.pose_bytes as i64 - self.bind_bytes as i64
    }

    /// Whether the skin pays: saves more than it costs.
    pub fn pays(&self) -> bool {
        self.margin() > 0
    }
}

/// Codes band 0 of `seq` (whose skin, fitted or not, skinning predicts from) under `opts` with
/// and without skinning on at most [`TRIAL_INTERVALS`] keyframe intervals, and says what each
/// cost, scaled to the whole sequence.
pub fn skin_trial(seq: &Sequence, opts: &EncodeOptions) -> Result<SkinTrial, ContainerError> {
    seq.validate()?;
    let skin = seq.skin.as_ref().ok_or_else(|| ContainerError::Options("skin trial: the sequence has no skin".into()))?;
    let placement = opts.skin.unwrap_or_default();
    let (lo, hi) = seq.bounds().ok_or_else(|| ContainerError::Options("empty sequence".into()))?;
    let step = quantization_step(opts, lo, hi)?;
    let n = seq.vertex_count();
    // One level: band 0's nodes are the input vertices at their own positions.
    let h = Hierarchy::from_parents(opts.build.branching, n as u32, Vec::new());
    let fit = fit_skin(skin, &h, &seq.frames[0], (lo, step), (placement, 0.0))?;
    let entries = band_entries(&fit.nodes, &h.offsets, 0, fit.header.palette_len).swap_remove(0);
    // Sizes about as the file stores the chunks (small bands' varint payloads shrink under
    // zstd), at a fast level: the file's own level costs more than the trial's coding.
    let stored = |raw: &[u8]| {
        store_chunk(raw, TRIAL_ZSTD_LEVEL, FLAGS).map(|z| z.len() as u64).map_err(|e| ContainerError::Io(format!("zstd: {e}")))
    };
    let bind = stored(&write_binds(&fit.nodes))?;
    let frames = trial_frames(seq.frame_count(), opts.keyframe_interval as usize);
    let lower = || LowerNeighbours::new(n, &seq.triangles, opts.order);
    let inv = 1.0 / step as f64;
    let truth_of = |f: usize| {
        let positions = &seq.frames[f];
        move |g: usize| {
            let p = positions[g] - lo;
            [p.x as f64 * inv, p.y as f64 * inv, p.z as f64 * inv]
        }
    };
    let mut out = SkinTrial { frames: seq.frame_count() as u32, frames_coded: frames.len() as u32, ..Default::default() };
    // The two codings are independent: the default prediction's on a thread of its own.
    // Band 0 is never on a coarser grid than the quantum (`predict::coarse_shift`).
    let (plain_bytes, skinned_side) = std::thread::scope(|scope| {
        let plain_side = scope.spawn(|| -> Result<u64, ContainerError> {
            let mut plain = PositionCoder::new(opts.motion, lower(), vec![0], n);
            let mut bytes = 0u64;
            for &f in &frames {
                bytes += stored(&plain.band(0, is_keyframe(opts, f), &h, truth_of(f), (None, None)).0)?;
                plain.next_frame();
            }
            Ok(bytes)
        });
        let skinned_side = (|| -> Result<(u64, u64), ContainerError> {
            let mut skinned = PositionCoder::new(opts.motion, lower(), vec![0], n);
            let mut held = SkinState::default();
            let (mut pose, mut skinned_bytes) = (0u64, 0u64);
            for &f in &frames {
                let intra = is_keyframe(opts, f);
                let palette = fit.joints(f, &held, intra)?;
                let skinning = Skinning { nodes: &fit.nodes, palette: &palette.palette, previous: &held.palette, coarse: None };
                let (payload, used) = skinned.band(0, intra, &h, truth_of(f), (Some(skinning), None));
                skinned_bytes += stored(&payload)?;
                let raw = write_joints(used as u64, &entries, &palette, &held.joint_prediction(intra));
                pose += stored(&raw)?;
                let crate::skin::JointsFrame { palette, rig, links, .. } = palette;
                held.advance_rig(palette, (rig, links), intra, used as u64);
                skinned.next_frame();
            }
            Ok((pose, skinned_bytes))
        })();
        let plain = match plain_side.join() {
            Ok(r) => r,
            Err(panic) => std::panic::resume_unwind(panic),
        };
        (plain, skinned_side)
    });
    let (pose, skinned_bytes) = skinned_side?;
    let plain_bytes = plain_bytes?;
    let scale = |b: u64| (b as f64 * out.frames as f64 / out.frames_coded.max(1) as f64).round() as u64;
    out.plain_bytes = scale(plain_bytes);
    out.skinned_bytes = scale(skinned_bytes);
    out.pose_bytes = scale(pose);
    out.bind_bytes = bind;
    Ok(out)
}

/// The frames the trial codes, in order: whole keyframe intervals (each starting at its
/// keyframe), at most [`TRIAL_INTERVALS`] of them spread evenly over the sequence; with a
/// single keyframe, the first [`TRIAL_FRAMES`].
fn trial_frames(frames: usize, interval: usize) -> Vec<usize> {
    if interval == 0 {
        return (0..frames.min(TRIAL_FRAMES)).collect();
    }
    let intervals = frames.div_ceil(interval);
    let take = intervals.clamp(1, TRIAL_INTERVALS);
    let mut out = Vec::new();
    for i in 0..take {
        // Evenly spread: the first and (with two or more) the last interval among them.
        let k = if take == 1 { 0 } else { i * (intervals - 1) / (take - 1) };
        out.extend(k * interval..((k + 1) * interval).min(frames));
    }
    out.dedup();
    out
}

#[cfg(test)]
mod tests {
    use super::trial_frames;

    #[test]
    fn whole_intervals_spread_over_the_sequence() {
        assert_eq!(trial_frames(5, 16), (0..5).collect::<Vec<_>>());
        assert_eq!(trial_frames(48, 16), (0..16).chain(32..48).collect::<Vec<_>>());
        assert_eq!(trial_frames(40, 16), (0..16).chain(32..40).collect::<Vec<_>>());
        assert_eq!(trial_frames(100, 0), (0..32).collect::<Vec<_>>());
        assert_eq!(trial_frames(10, 0), (0..10).collect::<Vec<_>>());
        assert!(trial_frames(0, 16).is_empty());
    }
}
