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
