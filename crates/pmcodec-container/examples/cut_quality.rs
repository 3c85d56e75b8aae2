//! What coarse-node quantization costs in cut quality: encodes a sequence with and without
//! `coarse_grid`, decodes every frame at a triangle budget, and prints the mean symmetric RMS
//! distance to the input frame (% of its bounding-box diagonal).
//! `cargo run --release -p pmcodec-container --example cut_quality -- DIR [triangles] [bits]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{Decoder, EncodeOptions, MeshTarget, QuantizationChoice, Reader, encode};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let budget: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(seq.triangles.len() as u32 / 10);
    let bits: u8 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(12);
    let sample = pmcodec_eval::SampleOptions { samples: 20_000, ..Default::default() };
    for grid in [None, Some(0), Some(1)] {
        let opts = EncodeOptions { quantization: QuantizationChoice::Bits(bits), coarse_grid: grid, ..Default::default() };
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let reader = Reader::open(bytes.as_slice()).expect("open");
        let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
        let mut sum = 0.0;
        for (f, frame) in seq.frames.iter().enumerate() {
            d.seek(f as u32).expect("seek");
            let cut = d.mesh(MeshTarget::Triangles(budget)).expect("mesh");
            let input = pmcodec_mesh::TriMesh { positions: frame.clone(), triangles: seq.triangles.clone() };
            sum += pmcodec_eval::symmetric_relative(&input, &cut, &sample).expect("distance").rms;
        }
        println!(
            "coarse_grid {grid:?}: {} bytes, mean RMS at {budget} triangles {:.4}% of the diagonal",
            bytes.len(),
            sum / seq.frames.len() as f64
        );
    }
}
