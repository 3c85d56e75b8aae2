//! Fits the growth exponent beta of equation 2 by regression, as Kircher & Garland did: the
//! total quadric error of a level grows like |M_i|^-beta as levels coarsen.
//! `cargo run --release -p pmcodec-hierarchy --example fit_beta -- ../shared/data/horse-gallop`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::*;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions { branching: 2, min_coarsest: 16, level_sizes: None, anchors: Vec::new() }).expect("build");
    let nodes = NodeState::compute(&h, &q, &seq.frames[0]);
    let (mut sx, mut sy, mut sxx, mut sxy, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for k in 1..h.levels() {
        let total: f64 = (h.offsets[k]..h.offsets[k + 1]).map(|g| nodes.error(g)).sum();
        let (x, y) = ((h.level_sizes[k] as f64).ln(), total.ln());
        println!("level {k}: {} nodes, total error {total:.3e}", h.level_sizes[k]);
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
        n += 1.0;
    }
    let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    println!("fitted beta = {:.4}", -slope);
}
