//! Development probe: decode speed of a horse-like sequence, for profiling.
//! `cargo run --release -p pmcodec-container --example speed -- DIR [passes]`
use pmcodec_container::{Decoder, EncodeOptions, QuantizationChoice, Reader, encode};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let passes: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(50);
    let opts = EncodeOptions { quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let t = std::time::Instant::now();
    for _ in 0..passes {
        let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
        for f in 0..reader.header().frame_count {
            d.seek(f).expect("frame");
        }
    }
    let frames = (passes as u32 * reader.header().frame_count) as f64;
    println!("{:.3} ms/frame", t.elapsed().as_secs_f64() * 1e3 / frames);
}
