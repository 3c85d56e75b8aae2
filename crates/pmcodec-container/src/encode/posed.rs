//! Encoding frames made on demand (a skinned glTF posed frame by frame): the frames stream
//! through the reclustering and are dropped once reclustered, the quantization grid coming
//! from a bounds pass of their own (issue 17, "Encode cost").

use super::{EncodeOptions, EncodeReport, encode_frames, encode_with_report, quantization_step};
use crate::ContainerError;
use glam::Vec3;
use pmcodec_hierarchy::base::PoseSet;
use pmcodec_mesh::Sequence;
use std::ops::ControlFlow;

/// Encodes a sequence whose frames are made when the encoder asks for them (a skinned glTF's
/// frames posed from its skeleton, [`pmcodec_mesh::gltf_input::FrameSampler`]) and whose
/// bounding box a cheaper pass gives (posing every frame without keeping it): `head` holds
/// frame 0 (with the triangles, appearance, skin and every frame's name), `rest` makes frames
/// 1.. (`frame_count` in all) and `bounds` the box of them all. The bytes are those
/// [`encode_with_report`] writes for the whole sequence.
///
/// Unlike [`encode_stream`], nothing queues: the quantization grid comes from `bounds`, which
/// runs on a thread of its own beside the base hierarchy's build, so each frame is made as the
/// reclustering reaches it and dropped once reclustered, and the frames held at once are the
/// few the coding side is behind ([`FRAMES_AHEAD`] at most, besides the one reclustered).
/// A frame outside `bounds` (a bounds pass that disagrees with the frames) is an error, and
/// nothing is returned.
///
/// With base poses other than the first frame, the base hierarchy needs every frame: `rest` is
/// collected first.
pub fn encode_posed(
    head: &Sequence,
    frame_count: usize,
    rest: impl Iterator<Item = Vec<Vec3>>,
    bounds: impl FnOnce() -> Result<(Vec3, Vec3), ContainerError> + Send,
    opts: &EncodeOptions,
    progress: impl FnMut(usize) -> ControlFlow<()>,
) -> Result<(Vec<u8>, EncodeReport), ContainerError> {
    if opts.base.poses != PoseSet::FirstFrame || head.frames.len() != 1 {
        let mut seq = head.clone();
        seq.frames.extend(rest);
        return encode_with_report(&seq, opts, progress);
    }
    head.validate()?;
    let (lo0, hi0) = head.bounds().ok_or_else(|| ContainerError::Options("empty sequence".into()))?;
    // An option out of range is refused before any work, as the whole sequence's would be.
    quantization_step(opts, lo0, hi0)?;
    let n = head.vertex_count();
    // The frames' own box, and the first bad frame, seen as the reclustering takes them.
    let seen = std::cell::Cell::new((lo0, hi0));
    let bad = std::cell::RefCell::new(None);
    let mut made = 1;
    let checked = rest.take(frame_count.saturating_sub(1)).enumerate().map_while(|(i, p)| {
        made += 1;
        match check_frame(head, i + 1, n, &p) {
            Ok(()) => {
                if let Some((a, b)) = pmcodec_mesh::bounds_of(&p) {
                    let (lo, hi) = seen.get();
                    seen.set((lo.min(a), hi.max(b)));
                }
                Some(std::borrow::Cow::Owned(p))
            }
            Err(e) => {
                *bad.borrow_mut() = Some(e);
                None
            }
        }
    });
    let first = std::borrow::Cow::Borrowed(head.frames[0].as_slice());
    let all = std::iter::once(first).chain(checked);
    let given = std::sync::Mutex::new(None);
    let out = std::thread::scope(|scope| {
        let given = &given;
        // The bounds pass starts now, beside the base hierarchy's build; the coding side
        // waits for it before its first frame.
        let pass = scope.spawn(bounds);
        let joined = move || {
            let b = match pass.join() {
                Ok(b) => b?,
                Err(panic) => std::panic::resume_unwind(panic),
            };
            if let Ok(mut slot) = given.lock() {
                *slot = Some(b);
            }
            Ok(b)
        };
        encode_frames(head, frame_count, all, joined, opts, (progress, false))
    });
    if let Some(e) = bad.into_inner() {
        return Err(e);
    }
    let out = out?;
    if made != frame_count {
        return Err(ContainerError::Options(format!("{made} frames made where the sequence has {frame_count}")));
    }
    let (lo, hi) = seen.get();
    match given.into_inner().ok().flatten() {
        Some((glo, ghi)) if glo.cmple(lo).all() && hi.cmple(ghi).all() => Ok(out),
        b => Err(ContainerError::Options(format!("the frames span {lo}..{hi}, outside the bounds given ({b:?})"))),
    }
}

/// Frame `f` of a streamed sequence checked as [`Sequence::validate`] checks every frame.
pub(super) fn check_frame(head: &Sequence, f: usize, n: usize, p: &[Vec3]) -> Result<(), ContainerError> {
    let label = || match head.frame_names.get(f) {
        Some(name) => format!("{f} ({name})"),
        None => f.to_string(),
    };
    if p.len() != n {
        return Err(pmcodec_mesh::MeshError::FrameMismatch {
            frame: label(),
            detail: format!("{} vertices where frame 0 has {n}", p.len()),
        }
        .into());
    }
    if let Some(v) = p.iter().position(|x| !x.is_finite()) {
        return Err(pmcodec_mesh::MeshError::NonFinite { frame: label(), vertex: v as u32 }.into());
    }
    Ok(())
}
