//! Writes the committed fuzz corpus (tests/corpus): small valid files and damaged copies.
//! `cargo run -p pmcodec-container --example make_corpus`
use pmcodec_container::{EncodeOptions, Motion, QuantizationChoice, encode};

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    std::fs::create_dir_all(&dir).expect("corpus dir");
    let mut n = 0;
    for (name, frames, key, bits) in
        [("valid-cloth-k0", 3u32, 0u32, 10u8), ("valid-cloth-k1", 4, 1, 12), ("valid-tube-k2", 5, 2, 8), ("valid-tube-affine", 5, 3, 12)]
    {
        let seq = if name.contains("tube") {
            pmcodec_mesh::samples::twisting_tube(6, 5, frames)
        } else {
            pmcodec_mesh::samples::waving_cloth(6, 5, frames)
        };
        let motion = if name.contains("affine") { Motion::Affine } else { Motion::Mean };
        let opts = EncodeOptions { keyframe_interval: key, quantization: QuantizationChoice::Bits(bits), motion, ..Default::default() };
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
    println!("wrote {n} damaged files and 4 valid ones to {}", dir.display());
}
