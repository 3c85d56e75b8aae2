//! `encode_posed`: a skinned glTF's frames made as the encoder asks for them write the bytes
//! the whole sequence writes, and at most one frame is made ahead of the reclustering.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_container::{ContainerError, EncodeOptions, QuantizationChoice, encode_posed, encode_with_report};
use pmcodec_mesh::InputLimits;
use pmcodec_mesh::gltf_input::RiggedMesh;
use pmcodec_mesh::samples::{CharacterOptions, skinned_character};
use std::cell::Cell;
use std::ops::ControlFlow;

fn character(seed: u64) -> RiggedMesh {
    let opts = CharacterOptions { parts: 6, limbs: 3, chain: 2, segments: 6, rings: 4, seconds: 1.2, keys_per_second: 5.0, seed };
    let mut rig = RiggedMesh::from_bytes(&skinned_character(&opts).unwrap()).unwrap();
    rig.weld();
    rig
}

fn options() -> EncodeOptions {
    EncodeOptions { keyframe_interval: 8, quantization: QuantizationChoice::Bits(12), ..Default::default() }
}

#[test]
fn frames_posed_on_demand_encode_as_the_whole_sequence() {
    for seed in [1, 2] {
        let rig = character(seed);
        let limits = InputLimits::default();
        let whole = rig.to_sequence_with(Some(0), 15.0, &limits).unwrap();
        let (want, _) = encode_with_report(&whole, &options(), |_| ControlFlow::Continue(())).unwrap();
        let sampler = rig.sampler(Some(0), 15.0, &limits).unwrap();
        let head = sampler.head().unwrap();
        let bounds = || sampler.bounds().map_err(ContainerError::from);
        let (got, _) =
            encode_posed(&head, sampler.frame_count(), sampler.frames(1), bounds, &options(), |_| ControlFlow::Continue(())).unwrap();
        assert!(whole.skin.is_some());
        assert_eq!(got, want, "seed {seed}");
    }
}

#[test]
fn at_most_one_frame_is_made_ahead_of_the_reclustering() {
    let rig = character(3);
    let sampler = rig.sampler(Some(0), 20.0, &InputLimits::default()).unwrap();
    let head = sampler.head().unwrap();
    // Frames made (frame 0 is the head's) and frames reclustered, as the encoder goes.
    let made = Cell::new(1usize);
    let mut worst = 0usize;
    let frames = sampler.frames(1).inspect(|_| made.set(made.get() + 1));
    let bounds = || sampler.bounds().map_err(ContainerError::from);
    encode_posed(&head, sampler.frame_count(), frames, bounds, &options(), |f| {
        // Frame f is reclustered: the frames made beyond it are what the encoder holds unread.
        worst = worst.max(made.get() - (f + 1));
        ControlFlow::Continue(())
    })
    .unwrap();
    assert!(sampler.frame_count() > 20);
    assert_eq!(made.get(), sampler.frame_count());
    assert!(worst <= 1, "{worst} frames made ahead of the reclustering");
}

#[test]
fn frames_outside_the_bounds_or_missing_are_errors() {
    let rig = character(4);
    let sampler = rig.sampler(Some(0), 10.0, &InputLimits::default()).unwrap();
    let head = sampler.head().unwrap();
    let n = sampler.frame_count();
    let go = |_| ControlFlow::Continue(());
    // Bounds of frame 0 only: later frames leave them.
    let small = head.bounds().unwrap();
    let e = encode_posed(&head, n, sampler.frames(1), || Ok(small), &options(), go).unwrap_err();
    assert!(e.to_string().contains("outside the bounds"), "{e}");
    // A frame short of vertices, and a NaN, name the frame.
    let mut short = sampler.frames(1).collect::<Vec<_>>();
    short[2].pop();
    let bounds = || sampler.bounds().map_err(ContainerError::from);
    let e = encode_posed(&head, n, short.into_iter(), bounds, &options(), go).unwrap_err();
    assert!(e.to_string().contains("frame 3"), "{e}");
    let mut nan = sampler.frames(1).collect::<Vec<_>>();
    nan[4][7] = Vec3::NAN;
    let e = encode_posed(&head, n, nan.into_iter(), bounds, &options(), go).unwrap_err();
    assert!(e.to_string().contains("frame 5"), "{e}");
    // Fewer frames than the sequence has.
    let e = encode_posed(&head, n, sampler.frames(1).take(3), bounds, &options(), go).unwrap_err();
    assert!(e.to_string().contains("frames made"), "{e}");
    // A bounds pass that fails stops the encode with its error.
    let e = encode_posed(&head, n, sampler.frames(1), || Err(ContainerError::Options("no bounds".into())), &options(), go).unwrap_err();
    assert!(e.to_string().contains("no bounds"), "{e}");
}

#[test]
fn a_skinned_sequence_reclustered_every_fourth_frame_swaps_only_there() {
    let rig = character(6);
    let seq = rig.to_sequence_with(Some(0), 20.0, &InputLimits::default()).unwrap();
    // Frames (and bands) whose Delta chunk carries swaps.
    let swapped = |every: u32| -> Vec<u32> {
        let opts = EncodeOptions { skinned_recluster_every: every, keyframe_interval: 0, ..options() };
        let bytes = pmcodec_container::encode(&seq, &opts, |_| {}).unwrap();
        let r = pmcodec_container::Reader::open(bytes.as_slice()).unwrap();
        let mut frames: Vec<u32> =
            r.index().chunks.iter().filter(|e| e.kind == pmcodec_container::ChunkKind::Delta && e.raw_len > 1).map(|e| e.frame).collect();
        frames.dedup();
        frames
    };
    let every_frame = swapped(1);
    assert!(every_frame.iter().any(|f| f % 4 != 0), "reclustering every frame swaps between the fourth frames: {every_frame:?}");
    let fourth = swapped(4);
    assert!(!fourth.is_empty());
    assert!(fourth.iter().all(|f| f % 4 == 0), "{fourth:?}");
}
