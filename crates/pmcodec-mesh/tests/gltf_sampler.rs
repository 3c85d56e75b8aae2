//! Frames sampled one at a time ([`RiggedMesh::sampler`]) are bit for bit the frames the whole
//! sequence holds ([`RiggedMesh::to_sequence`]), on Fox and on generated characters.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::InputLimits;
use pmcodec_mesh::gltf_input::RiggedMesh;
use pmcodec_mesh::samples::{CharacterOptions, skinned_character};
use std::path::PathBuf;

fn bits(frame: &[glam::Vec3]) -> Vec<[u32; 3]> {
    frame.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// Every frame, name, the skin's matrices and the bounds of the lazy sampler against the
/// eager sequence of `animation` at `rate`.
fn lazy_equals_eager(rig: &RiggedMesh, animation: Option<usize>, rate: f32) {
    let limits = InputLimits::default();
    let eager = rig.to_sequence_with(animation, rate, &limits).unwrap();
    let sampler = rig.sampler(animation, rate, &limits).unwrap();
    assert_eq!(sampler.frame_count(), eager.frame_count());
    let head = sampler.head().unwrap();
    assert_eq!(head.frames.len(), 1, "the head holds frame 0 only");
    assert_eq!(head.frame_names, eager.frame_names);
    assert_eq!(head.triangles, eager.triangles);
    assert_eq!(head.source, eager.source);
    assert_eq!(head.morph_displacement, eager.morph_displacement);
    assert_eq!(head.skin.as_ref().map(|s| &s.matrices), eager.skin.as_ref().map(|s| &s.matrices));
    assert_eq!(bits(&head.frames[0]), bits(&eager.frames[0]));
    let mut seen = 0;
    for (f, frame) in sampler.frames(0).enumerate() {
        assert_eq!(bits(&frame), bits(&eager.frames[f]), "frame {f}");
        assert_eq!(bits(&sampler.frame(f)), bits(&eager.frames[f]), "frame {f} asked for alone");
        seen += 1;
    }
    assert_eq!(seen, eager.frame_count());
    assert_eq!(sampler.frames(3).count(), eager.frame_count().saturating_sub(3));
    let (lo, hi) = sampler.bounds().unwrap();
    assert_eq!(Some((lo, hi)), eager.bounds());
}

#[test]
fn fox_sampled_lazily_is_fox_sampled_whole() {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf/Fox.glb"));
    assert!(path.is_file(), "{} is absent; this test reads the real models in ../shared/data beside the repository", path.display());
    let mut rig = RiggedMesh::from_path(&path).unwrap();
    rig.weld();
    // Survey at a low rate, and the rest pose.
    lazy_equals_eager(&rig, Some(0), 6.0);
    lazy_equals_eager(&rig, None, 30.0);
}

#[test]
fn generated_characters_sampled_lazily_are_sampled_whole() {
    for seed in [1, 2] {
        let opts = CharacterOptions { parts: 7, limbs: 3, chain: 2, segments: 5, rings: 3, seconds: 1.5, keys_per_second: 5.0, seed };
        let mut rig = RiggedMesh::from_bytes(&skinned_character(&opts).unwrap()).unwrap();
        rig.weld();
        lazy_equals_eager(&rig, Some(0), 12.0);
    }
}

#[test]
fn the_sampler_refuses_what_the_sequence_refuses() {
    let opts = CharacterOptions { parts: 2, limbs: 1, chain: 2, segments: 4, rings: 2, seconds: 1.0, keys_per_second: 2.0, seed: 5 };
    let rig = RiggedMesh::from_bytes(&skinned_character(&opts).unwrap()).unwrap();
    let limits = InputLimits::default();
    assert!(rig.sampler(Some(0), 0.0, &limits).is_err());
    assert!(rig.sampler(Some(0), f32::NAN, &limits).is_err());
    assert!(rig.sampler(Some(7), 30.0, &limits).is_err());
    // A limit on positions is checked before any frame is made.
    let tight = InputLimits { max_positions: 10, ..InputLimits::default() };
    assert!(rig.sampler(Some(0), 30.0, &tight).is_err());
    assert!(rig.to_sequence_with(Some(0), 30.0, &tight).is_err());
}
