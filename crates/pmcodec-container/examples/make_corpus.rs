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
    println!("wrote {n} damaged files and {} valid ones to {}", valid.len(), dir.display());
}
