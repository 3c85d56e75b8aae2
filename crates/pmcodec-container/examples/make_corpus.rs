//! Writes the committed fuzz corpus (tests/corpus): small valid files and damaged copies.
//! `cargo run -p pmcodec-container --example make_corpus`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{EncodeOptions, Motion, QuantizationChoice, VertexOrder, encode};

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    std::fs::create_dir_all(&dir).expect("corpus dir");
    let mut n = 0;
    let valid = [
        ("valid-cloth-k0", 3u32, 0u32, 10u8),
        ("valid-cloth-k1", 4, 1, 12),
        ("valid-tube-k2", 5, 2, 8),
        ("valid-tube-affine", 5, 3, 12),
        ("valid-tube-mean-input", 5, 3, 12),
    ];
    for (name, frames, key, bits) in valid {
        let seq = if name.contains("tube") {
            pmcodec_mesh::samples::twisting_tube(6, 5, frames)
        } else {
            pmcodec_mesh::samples::waving_cloth(6, 5, frames)
        };
        // The default (keyframe affine motion, breadth first), affine motion fitted on every
        // frame, and version 4's default (mean motion in input order).
        let (motion, order) = match name {
            n if n.contains("-affine") => (Motion::Affine, VertexOrder::BreadthFirst),
            n if n.contains("-mean-input") => (Motion::Mean, VertexOrder::Input),
            _ => (Motion::KeyframeAffine, VertexOrder::BreadthFirst),
        };
        let opts =
            EncodeOptions { keyframe_interval: key, quantization: QuantizationChoice::Bits(bits), motion, order, ..Default::default() };
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        std::fs::write(dir.join(format!("{name}.pmc")), &bytes).expect("write");
        // Damaged copies: a flipped byte in each region and truncations.
        for (i, at) in [9usize, 13, 40, bytes.len() / 3, bytes.len() / 2, bytes.len() - 5].into_iter().enumerate() {
            let mut b = bytes.clone();
            b[at] ^= 0xA5;
            std::fs::write(dir.join(format!("bad-{name}-flip{i}.pmc")), &b).expect("write");
            n += 1;
        }
        for (i, len) in [20usize, 60, bytes.len() / 2, bytes.len() - 1].into_iter().enumerate() {
            std::fs::write(dir.join(format!("bad-{name}-cut{i}.pmc")), &bytes[..len]).expect("write");
            n += 1;
        }
    }
    // Seeds of the file kinds the cloth and tube are not: a skinned glTF character (Bind and
    // Joints chunks), a textured cloth (grown charts, attributes, materials, an image) and a
    // fitted skin (skinning competing band by band). Valid only: the resealed test and the
    // fuzz target damage them.
    let character =
        pmcodec_mesh::samples::CharacterOptions { parts: 2, limbs: 2, chain: 2, segments: 5, rings: 3, seconds: 0.3, ..Default::default() };
    let glb = pmcodec_mesh::samples::skinned_character(&character).expect("character");
    let skinned = pmcodec_mesh::gltf_input::load_gltf_bytes(&glb, &Default::default()).expect("load");
    let mut tube = pmcodec_mesh::samples::twisting_tube(6, 6, 5);
    let fit = pmcodec_mesh::skin_fit::FitOptions { bones: Some(3), ..Default::default() };
    tube.skin = Some(pmcodec_mesh::skin_fit::fit_skin(&tube, &fit).expect("fit").0);
    let more = [
        ("valid-skinned-character", skinned),
        ("valid-textured-cloth", pmcodec_mesh::samples::textured_cloth(6, 5, 4, 4)),
        ("valid-fitted-tube", tube),
    ];
    for (name, seq) in &more {
        let opts = EncodeOptions { keyframe_interval: 2, quantization: QuantizationChoice::Bits(10), ..Default::default() };
        std::fs::write(dir.join(format!("{name}.pmc")), encode(seq, &opts, |_| {}).expect("encode")).expect("write");
    }
    println!("wrote {n} damaged files and {} valid ones to {}", valid.len() + more.len(), dir.display());
}
