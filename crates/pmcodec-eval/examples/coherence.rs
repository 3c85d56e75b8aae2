//! Development probe: share of shown triangles changing per frame at a triangle budget.
//! `cargo run --release -p pmcodec-eval --example coherence -- ../shared/data/horse-gallop 1600`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_eval::{self as approx, ApproxOptions, ApproxTarget, Method};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let budget: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1600);
    let mut opts = ApproxOptions { branching: 4, ..Default::default() };
    if let Some(x) = std::env::var("MINREL").ok().and_then(|s| s.parse().ok()) {
        opts.recluster.min_relative_benefit = x;
    }
    if let Some(x) = std::env::var("CAP").ok().and_then(|s| s.parse().ok()) {
        opts.recluster.max_swaps_per_frame = x;
    }
    if let Some(x) = std::env::var("PASSES").ok().and_then(|s| s.parse().ok()) {
        opts.recluster.max_passes = x;
    }
    if std::env::var("BASE").is_ok() {
        opts.base.poses = pmcodec_hierarchy::base::PoseSet::Sampled(8);
    }
    for m in [Method::FirstFrameStatic, Method::Direct, Method::Reclustered] {
        let a = approx::approximate(&seq, ApproxTarget::Triangles(budget), m, &opts, |_| {}).expect("approx");
        let c = approx::changed_share(&a);
        let mean = c[1..].iter().sum::<f64>() / (c.len() - 1) as f64;
        let tris: Vec<usize> = a.iter().map(|x| x.mesh.triangles.len()).collect();
        if std::env::var("VERBOSE").is_ok() {
            println!("{:?}", c.iter().map(|x| (x * 1000.0).round() / 10.0).collect::<Vec<_>>());
        }
        println!("{:>8}: mean changed {:.2}%  triangles {:?}..{:?}", m.name(), 100.0 * mean, tris.iter().min(), tris.iter().max());
    }
}
