//! Encode and decode speed of the container on the horse gallop.
//! `cargo bench -p pmcodec-container --bench container`
use pmcodec_container::{Decoder, EncodeOptions, Reader, encode};
use std::sync::OnceLock;

fn main() {
    divan::main();
}

fn horse() -> &'static pmcodec_mesh::Sequence {
    static SEQ: OnceLock<pmcodec_mesh::Sequence> = OnceLock::new();
    SEQ.get_or_init(|| {
        let dir = std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/horse-gallop"));
        pmcodec_mesh::obj::load_obj_sequence(&dir, 30.0).expect("horse gallop")
    })
}

fn file() -> &'static Vec<u8> {
    static F: OnceLock<Vec<u8>> = OnceLock::new();
    F.get_or_init(|| encode(horse(), &EncodeOptions::default(), |_| {}).expect("encode"))
}

#[divan::bench(sample_count = 3)]
fn encode_horse_48_frames() -> usize {
    encode(horse(), &EncodeOptions::default(), |_| {}).expect("encode").len()
}

#[divan::bench(sample_count = 10)]
fn decode_horse_48_frames() -> u32 {
    let reader = Reader::open(file().as_slice()).expect("open");
    let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
    for f in 0..reader.header().frame_count {
        d.seek(f).expect("frame");
    }
    d.frame().unwrap_or(0)
}
