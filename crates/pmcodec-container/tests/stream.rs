//! Encoding while the frames are still being read (`encode_stream`, issue 15 item 4): the same
//! bytes as encoding the whole sequence, and a clear error, never a partial file, when the
//! input fails or a frame is wrong part way through.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_container::*;
use pmcodec_mesh::Sequence;
use pmcodec_mesh::samples::{twisting_tube, waving_cloth};
use std::ops::ControlFlow;

/// Frame 0 of `seq` with every frame's name, and its later frames as a reader would give them.
fn split(seq: &Sequence) -> (Sequence, Vec<Result<Vec<Vec3>, String>>) {
    let mut head = seq.clone();
    head.frames.truncate(1);
    head.frame_names = (0..seq.frame_count()).map(|f| format!("frame-{f}")).collect();
    (head, seq.frames[1..].iter().cloned().map(Ok).collect())
}

fn whole(seq: &Sequence) -> Sequence {
    let mut s = seq.clone();
    s.frame_names = (0..seq.frame_count()).map(|f| format!("frame-{f}")).collect();
    s
}

fn go(_: usize) -> ControlFlow<()> {
    ControlFlow::Continue(())
}

#[test]
fn streamed_bytes_equal_whole_sequence_bytes() {
    // A closed tube and an open cloth, both deforming; default options and a keyframe every
    // 3 frames with mean motion (so several keyframes and both motion models are compared).
    let seqs = [twisting_tube(24, 12, 9), waving_cloth(14, 10, 8)];
    let other = EncodeOptions { keyframe_interval: 3, motion: Motion::Mean, ..Default::default() };
    for seq in &seqs {
        for opts in [EncodeOptions::default(), other.clone()] {
            let expected = encode_until(&whole(seq), &opts, go).unwrap();
            let (head, rest) = split(seq);
            let mut seen = Vec::new();
            let got = encode_stream(&head, seq.frame_count(), rest.into_iter(), &opts, |f| {
                seen.push(f);
                ControlFlow::Continue(())
            })
            .unwrap();
            assert_eq!(got, expected, "streamed encoding differs ({} vertices, {opts:?})", seq.vertex_count());
            assert_eq!(seen, (0..seq.frame_count()).collect::<Vec<_>>());
            // And the file reads back with every frame.
            let reader = Reader::open(got.as_slice()).unwrap();
            assert_eq!(reader.header().frame_count as usize, seq.frame_count());
        }
    }
}

#[test]
fn input_error_part_way_is_reported_as_input() {
    let seq = twisting_tube(16, 8, 6);
    let (head, mut rest) = split(&seq);
    rest[3] = Err("frame-4: line 7: not a number".to_string());
    let e = encode_stream(&head, seq.frame_count(), rest.into_iter(), &EncodeOptions::default(), go).unwrap_err();
    match e {
        StreamError::Input(m) => assert!(m.contains("frame-4"), "{m}"),
        other => panic!("expected the input's error, got {other}"),
    }
}

#[test]
fn bad_frame_part_way_is_a_typed_error() {
    let seq = twisting_tube(16, 8, 6);
    let (head, mut rest) = split(&seq);
    // A frame short of vertices, and one with a NaN: each named, as validation names them.
    rest[1].as_mut().unwrap().pop();
    let e = encode_stream(&head, seq.frame_count(), rest.into_iter(), &EncodeOptions::default(), go).unwrap_err();
    assert!(matches!(e, StreamError::Encode(ContainerError::Mesh(_))), "{e:?}");
    assert!(e.to_string().contains("frame-2"), "{e}");
    let (head, mut rest) = split(&seq);
    rest[2].as_mut().unwrap()[5].y = f32::NAN;
    let e = encode_stream(&head, seq.frame_count(), rest.into_iter(), &EncodeOptions::default(), go).unwrap_err();
    assert!(e.to_string().contains("frame-3"), "{e}");
}

#[test]
fn cancelled_stream_returns_cancelled() {
    let seq = twisting_tube(16, 8, 6);
    let (head, rest) = split(&seq);
    let e = encode_stream(&head, seq.frame_count(), rest.into_iter(), &EncodeOptions::default(), |f| {
        if f == 2 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
    })
    .unwrap_err();
    assert!(matches!(e, StreamError::Encode(ContainerError::Cancelled)), "{e:?}");
}
