//! Encode and decode speed of the container on the horse gallop.
//! `cargo bench -p pmcodec-container --bench container`
use pmcodec_container::{Decoder, EncodeOptions, MeshTarget, Reader, encode};
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

/// Playback at a budget: every frame decoded and cut at 2,000 triangles (a full-resolution
/// decoder, and one that reads only the bands a 2,000-triangle cut needs, as clients do).
#[divan::bench(sample_count = 10, args = [0, 1])]
fn decode_and_cut_2000_horse_48_frames(min_level: usize) -> usize {
    let reader = Reader::open(file().as_slice()).expect("open");
    let mut d = Decoder::new(reader.borrowed(), min_level).expect("decoder");
    let mut shown = 0;
    for f in 0..reader.header().frame_count {
        d.seek(f).expect("frame");
        shown += d.mesh(MeshTarget::Triangles(2000)).expect("mesh").triangles.len();
    }
    shown
}

/// LOD on demand on a warm frame (what the server spends per request once a frame's state is
/// cached): one cut at a budget, the split order already recorded.
#[divan::bench(args = [500, 2000, 8000, 16000])]
fn lod_cut_warm_frame(bencher: divan::Bencher, budget: u32) {
    let reader = Reader::open(file().as_slice()).expect("open");
    let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
    d.seek(24).expect("frame");
    d.mesh(MeshTarget::Triangles(u32::MAX)).expect("warm-up");
    bencher.bench_local(|| d.mesh(MeshTarget::Triangles(budget)).expect("mesh").triangles.len());
}
