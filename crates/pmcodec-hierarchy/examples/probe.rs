//! Development probe: per-frame swaps, time and level QEM error of reclustering vs static.
//! `cargo run --release -p pmcodec-hierarchy --example probe -- ../shared/data/horse-gallop 800`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_hierarchy::FineTopology;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::build::anchored_build;
use pmcodec_hierarchy::recluster::{ReclusterOptions, Reclusterer};
use std::time::Instant;

fn level_error(rc: &Reclusterer, level: usize) -> f64 {
    let h = rc.hierarchy();
    (h.offsets[level]..h.offsets[level + 1]).map(|g| rc.nodes().error(g)).sum()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let vertices: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(800);
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let (h, level) = anchored_build(&topo, &q, vertices, 4).expect("build");
    println!("levels {:?}, level {level}", h.level_sizes);
    let mut stat = Reclusterer::new(h.clone(), topo.clone(), seq.triangles.clone(), ReclusterOptions::default());
    let mut ro = ReclusterOptions::default();
    if let Some(x) = std::env::var("MINREL").ok().and_then(|s| s.parse().ok()) {
        ro.min_relative_benefit = x;
    }
    let mut rc = Reclusterer::new(h, topo, seq.triangles.clone(), ro);
    let mut ratio_sum = 0.0;
    let mut swaps = Vec::new();
    let mut total = 0.0;
    for (f, frame) in seq.frames.iter().enumerate() {
        stat.fit(frame);
        swaps.clear();
        let t = Instant::now();
        let s = rc.frame(frame, &mut swaps);
        let dt = t.elapsed().as_secs_f64() * 1e3;
        total += dt;
        let (es, er) = (level_error(&stat, level), level_error(&rc, level));
        ratio_sum += er / es;
        println!(
            "frame {f:3}: {:5} swaps {:3} passes {:7} cands {:6} invalid {dt:7.2} ms  static {es:.3e} recluster {er:.3e} ratio {:.3}",
            s.swaps,
            s.passes,
            s.candidates,
            s.rejected_invalid,
            er / es
        );
    }
    println!("mean {:.2} ms/frame, mean QEM ratio {:.3}", total / seq.frame_count() as f64, ratio_sum / seq.frame_count() as f64);
}
