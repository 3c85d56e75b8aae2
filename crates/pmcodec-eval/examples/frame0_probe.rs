//! Development probe for issue 15 item 1: frame 0 of a sequence simplified by our QEM build to
//! N vertices, beside meshoptimizer's, with what the level's mesh does wrong: triangles whose
//! normal turned against their fine triangle's (folds), and boundary edges.
//!
//! `cargo run --release -p pmcodec-eval --example frame0_probe -- INPUT N [N...]`

use pmcodec_eval::made::boundary_loops;
use pmcodec_eval::{SampleOptions, symmetric_relative};
use pmcodec_hierarchy::CutTarget;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::build::anchored_build;
use pmcodec_hierarchy::cut::{self, ChildIndex};
use pmcodec_hierarchy::{DegenerateSets, FineTopology, NodeState};
use pmcodec_mesh::TriMesh;
use std::path::Path;

fn normal(m: &TriMesh, t: [u32; 3]) -> glam::Vec3 {
    let [a, b, c] = t.map(|v| m.positions[v as usize]);
    (b - a).cross(c - a)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(input) = args.first() else {
        eprintln!("usage: frame0_probe INPUT N [N...]");
        std::process::exit(2);
    };
    let seq = match pmcodec_mesh::obj::load_obj_sequence(Path::new(input), 30.0) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{input}: {e}");
            std::process::exit(3);
        }
    };
    let Some(original) = seq.frame_mesh(0) else { return };
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let (edges, loops) = boundary_loops(seq.vertex_count(), &seq.triangles);
    println!("{input}: {} vertices, {edges} boundary edges in {loops} loops", seq.vertex_count());
    for n in &args[1..] {
        let Ok(n) = n.parse::<u32>() else { continue };
        let t = std::time::Instant::now();
        let Ok((h, level)) = anchored_build(&topo, &q, n, 4) else { continue };
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let nodes = NodeState::compute(&h, &q, &seq.frames[0]);
        let d = DegenerateSets::new(&h, &seq.triangles);
        let c = pmcodec_eval::select_cut(&h, &d, &ChildIndex::new(&h), &nodes, CutTarget::Level(level));
        let (mesh, _) = cut::extract(&h, &d, &seq.triangles, &c, &nodes.positions);
        // Folds: a shown triangle (fine triangle t with its corners' nodes) facing away from t.
        let shown = cut::shown_triangles(&d, &c);
        let folds = shown
            .iter()
            .zip(&mesh.triangles)
            .filter(|&(&t, &m)| normal(&mesh, m).dot(normal(&original, seq.triangles[t as usize])) < 0.0)
            .count();
        let (be, bl) = boundary_loops(mesh.positions.len(), &mesh.triangles);
        let dist = symmetric_relative(&original, &mesh, &SampleOptions::default()).map(|d| d.rms).unwrap_or(f64::NAN);
        println!(
            "N {n}: {} vertices {} triangles, rms {dist:.4}%, {folds} folded triangles, {be} boundary edges in {bl} loops, build {ms:.0} ms",
            mesh.positions.len(),
            mesh.triangles.len()
        );
    }
}
