//! Raw sizes of the per-frame topology deltas, counted as the paper counts them (two 32-bit
//! integers per swap; a degenerate-set change as a 32-bit triangle and a 32-bit node), beside a
//! full hierarchy per frame (a parent per node plus every node's degenerate set).
//! `cargo run --release -p pmcodec-hierarchy --example delta_sizes -- ../shared/data/horse-gallop`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::progressive::Encoder;
use pmcodec_hierarchy::*;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let branching = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(4);
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions { branching, ..Default::default() }).expect("build");
    let full = 4 * (h.node_count() + seq.triangles.len());
    let mut enc = Encoder::new(h, topo, seq.triangles.clone(), Default::default());
    let (mut swaps, mut degen, mut corners) = (0usize, 0usize, 0usize);
    for frame in &seq.frames[1..] {
        enc.encode_frame(frame);
    }
    // Measure a second pass over the sequence: steady state, without the first adaptation.
    let n = seq.frame_count();
    for frame in &seq.frames {
        // Degenerate-set changes are not part of a delta (a decoder derives them): count them
        // by comparing the encoder's degeneration nodes before and after the frame.
        let before = enc.degeneration().to_vec();
        let (d, _) = enc.encode_frame(frame);
        swaps += d.swaps.len();
        degen += before.iter().zip(enc.degeneration()).filter(|(a, b)| a != b).count();
        corners += d.corners.len();
    }
    let kb = |bytes: usize| bytes as f64 / n as f64 / 1024.0;
    println!("branching {branching}, levels {:?}", enc.hierarchy().level_sizes);
    println!(
        "per frame: {:.0} swaps, {:.0} degenerate-set changes, {:.0} corner updates",
        swaps as f64 / n as f64,
        degen as f64 / n as f64,
        corners as f64 / n as f64
    );
    println!("raw swaps (2 x u32): {:.2} KB/frame   (paper: 2.2 KB)", kb(8 * swaps));
    println!("raw swaps + degenerate sets (2 x u32 each): {:.2} KB/frame   (paper: 18.5 KB)", kb(8 * (swaps + degen)));
    println!("full hierarchy per frame: {:.1} KB   (paper: 103.4 KB)", full as f64 / 1024.0);
}
