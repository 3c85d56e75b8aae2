//! Encode and decode speed of the container on the horse gallop.
//! `cargo bench -p pmcodec-container --bench container`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{Decoder, EncodeOptions, MeshTarget, Motion, Reader, VertexOrder, encode};
use std::sync::OnceLock;

fn main() {
    // Encode the files first, so that no sample times an encode.
    let _ = (file(), other_file(Motion::Affine), other_file(Motion::Mean));
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

/// The same with band 0 predicted otherwise: affine motion fitted on every frame, or the mean
/// motion in input order (what version 4 wrote by default).
fn other_file(motion: Motion) -> &'static Vec<u8> {
    static AFFINE: OnceLock<Vec<u8>> = OnceLock::new();
    static MEAN: OnceLock<Vec<u8>> = OnceLock::new();
    let (cell, order) = if motion == Motion::Affine { (&AFFINE, VertexOrder::BreadthFirst) } else { (&MEAN, VertexOrder::Input) };
    cell.get_or_init(|| encode(horse(), &EncodeOptions { motion, order, ..Default::default() }, |_| {}).expect("encode"))
}

#[divan::bench(sample_count = 3)]
fn encode_horse_48_frames() -> usize {
    encode(horse(), &EncodeOptions::default(), |_| {}).expect("encode").len()
}

#[divan::bench(sample_count = 10, args = ["keyframe-affine", "affine", "mean"])]
fn decode_horse_48_frames(motion: &str) -> u32 {
    let bytes = match motion {
        "affine" => other_file(Motion::Affine),
        "mean" => other_file(Motion::Mean),
        _ => file(),
    };
    let reader = Reader::open(bytes.as_slice()).expect("open");
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

/// LOD on demand as the server sees it: every frame's state warm, requests at random frames
/// and budgets (200..16,000 triangles, as the load test asks), each cut and written as the
/// compact binary. One iteration is 64 requests; the states of 48 frames do not fit the
/// caches together, so this measures the cut's memory traffic, which the one-frame bench hides.
#[divan::bench(sample_count = 20)]
fn lod_on_demand_random_frames(bencher: divan::Bencher) {
    let reader = Reader::open(file().as_slice()).expect("open");
    let frames = reader.header().frame_count;
    let mut states: Vec<_> = (0..frames)
        .map(|f| {
            let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
            d.seek(f).expect("frame");
            d.mesh(MeshTarget::Triangles(u32::MAX)).expect("warm-up");
            d
        })
        .collect();
    // A fixed xorshift stream: the same requests in every run.
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    bencher.bench_local(|| {
        let mut bytes = 0;
        for _ in 0..64 {
            let f = (next() % frames as u64) as usize;
            let budget = 200 + (next() % 15_801) as u32;
            let mesh = states[f].mesh(MeshTarget::Triangles(budget)).expect("mesh");
            bytes += pmcodec_mesh::binmesh::encode_bin(&mesh).len();
        }
        bytes
    });
}
