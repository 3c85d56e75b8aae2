//! Coarse nodes on their clusters' surfaces (`EncodeOptions::surface_grid`) must not make a
//! skinned file much larger than the cheapest grid points do (issue 17): where skinning
//! predicts a band almost exactly, a node moved off its cheapest point pays residual bits in
//! every frame, so the encoder weighs the surface against those bits.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{EncodeOptions, encode};
use pmcodec_mesh::InputLimits;
use pmcodec_mesh::gltf_input::RiggedMesh;
use pmcodec_mesh::samples::{CharacterOptions, skinned_character};

/// A generated skinned character of `parts` tubes of 578 vertices (issue 17's, smaller and
/// shorter), 3 s at 30 frames per second.
fn character(parts: u32, seed: u64) -> pmcodec_mesh::Sequence {
    let opts = CharacterOptions { parts, limbs: 4, chain: 3, seconds: 3.0, seed, ..Default::default() };
    let mut rig = RiggedMesh::from_bytes(&skinned_character(&opts).unwrap()).unwrap();
    rig.weld();
    rig.to_sequence_with(Some(0), 30.0, &InputLimits::default()).unwrap()
}

#[test]
fn the_surface_grid_costs_a_skinned_character_little() {
    for (parts, seed) in [(8, 1), (6, 3)] {
        let seq = character(parts, seed);
        assert!(seq.skin.is_some(), "not skinned");
        let size = |surface_grid| encode(&seq, &EncodeOptions { surface_grid, ..Default::default() }, |_| {}).expect("encode").len();
        let (on, off) = (size(true), size(false));
        eprintln!("{parts} parts: surface grid on {on} B, off {off} B ({:+.2}%)", 100.0 * (on as f64 / off as f64 - 1.0));
        assert!(on as f64 <= off as f64 * 1.01, "{parts} parts: {on} B on the surface, {off} B at the cheapest points");
    }
}

/// The coarse levels' mean RMS error (% of the diagonal) over every frame of `seq` as
/// encoded with `opts`, and the file's length.
fn coarse_levels_rms(seq: &pmcodec_mesh::Sequence, opts: &EncodeOptions) -> (f64, usize) {
    use pmcodec_container::{CutTarget, Decoder, Reader};
    let bytes = encode(seq, opts, |_| {}).expect("encode");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let (levels, frames) = (reader.header().levels(), reader.header().frame_count);
    let mut d = Decoder::new(reader, 0).expect("decoder");
    let mut sum = 0.0;
    for f in 0..frames {
        d.seek(f).expect("frame");
        let original = seq.frame_mesh(f as usize).expect("frame");
        for j in 1..levels {
            let m = d.mesh(CutTarget::Level(j)).expect("level cut");
            sum += pmcodec_eval::symmetric_relative(&original, &m, &Default::default()).expect("measurable").rms;
        }
    }
    (sum / (frames as usize * (levels - 1).max(1)) as f64, bytes.len())
}

/// Without skinning, where a coarse band's residuals are wide and a step more costs a fraction
/// of a bit, the surface keeps lowering the coarse levels' error in every frame, not only in
/// the first (whose choice is made before any band's bits are known): on a generated cloth and
/// tube at 8 bits, as `frame0_levels` measures frame 0 alone.
#[test]
fn without_skinning_the_surface_still_lowers_every_frame_s_error() {
    for seq in [pmcodec_mesh::samples::waving_cloth(40, 30, 12), pmcodec_mesh::samples::twisting_tube(32, 24, 12)] {
        let at = |surface_grid| EncodeOptions {
            quantization: pmcodec_container::QuantizationChoice::Bits(8),
            keyframe_interval: 4,
            surface_grid,
            ..Default::default()
        };
        let ((on, on_bytes), (off, off_bytes)) = (coarse_levels_rms(&seq, &at(true)), coarse_levels_rms(&seq, &at(false)));
        eprintln!("surface grid on: {on:.5}% ({on_bytes} B), off: {off:.5}% ({off_bytes} B)");
        assert!(on < off * 0.995, "on the surface {on}, off {off}");
    }
}
