//! Diagnostic for issue 15's frame-0 bar: at each level of the encoder's base hierarchy (the
//! container's defaults: anchors at 25% and 10% of the triangles, then every 4x), frame 0's
//! level cut taken four ways, each measured against the input frame by the same sampled
//! distance as `pmcodec eval`:
//! - `base`: the level of H_0 as built (`pmcodec_hierarchy::build`), before any reclustering;
//! - `recl`: the same level after frame 0's reclustering (what the encoder stores for frame 0);
//! - `direct`: our own QEM run on frame 0 stopped at exactly that vertex count (the sweep's
//!   "direct");
//! - `mopt`: meshoptimizer's simplifier at (within 1% of) that vertex count (see
//!   `qem_reference.rs`).
//!
//! Beside the symmetric RMS (percent of the diagonal) it prints the two one-sided RMS distances
//! (input to level: "fwd", level to input: "bwd"), the level's boundary edges and loops and its
//! folded triangles (facing against their fine triangle), which is where the differences are
//! found.
//!
//! `cargo run --release -p pmcodec-eval --example frame0_levels -- INPUT [INPUT...]`
//! (an input is an OBJ folder or a built-in sample name: `waving-cloth`, `twisting-tube`).
//!
//! `frame0_levels --compare INPUT A.obj [B.obj...]` measures meshes written elsewhere (e.g.
//! `pmcodec decode X.pmc --level 1 -o A.obj`, a container's level as a client gets it) against
//! INPUT's frame 0 the same way.

use pmcodec_eval::made::boundary_loops;
use pmcodec_eval::{SampleOptions, one_sided, symmetric_relative};
use pmcodec_hierarchy::CutTarget;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::build::{BuildOptions, build};
use pmcodec_hierarchy::cut::{self, ChildIndex};
use pmcodec_hierarchy::recluster::{ReclusterOptions, Reclusterer};
use pmcodec_hierarchy::{DegenerateSets, FineTopology, Hierarchy, NodeState};
use pmcodec_mesh::{Sequence, TriMesh};
use std::path::Path;
use std::process::ExitCode;

#[path = "common/qem.rs"]
mod qem;

fn load(input: &str) -> Result<Sequence, String> {
    if let Some(s) = pmcodec_mesh::samples::by_name(input) {
        return Ok(s);
    }
    pmcodec_mesh::obj::load_obj_sequence(Path::new(input), 30.0).map_err(|e| format!("{input}: {e}"))
}

fn level_mesh(h: &Hierarchy, triangles: &[[u32; 3]], nodes: &NodeState, level: usize) -> (TriMesh, usize) {
    let d = DegenerateSets::new(h, triangles);
    let c = pmcodec_eval::select_cut(h, &d, &ChildIndex::new(h), nodes, CutTarget::Level(level));
    let (mesh, _) = cut::extract(h, &d, triangles, &c, &nodes.positions);
    let shown = cut::shown_triangles(&d, &c);
    let normal = |m: &[glam::Vec3], t: [u32; 3]| {
        let [a, b, c] = t.map(|v| m[v as usize]);
        (b - a).cross(c - a)
    };
    let fine = &nodes.positions[..h.level_sizes[0] as usize];
    let folds = shown
        .iter()
        .zip(&mesh.triangles)
        .filter(|&(&t, &m)| normal(&mesh.positions, m).dot(normal(fine, triangles[t as usize])) < 0.0)
        .count();
    (mesh, folds)
}

/// Symmetric RMS (as `pmcodec eval` measures it) and the two one-sided RMS, in percent of the input's diagonal.
fn measure(original: &TriMesh, m: &TriMesh, diagonal: f64) -> Result<[f64; 3], String> {
    let opts = SampleOptions::default();
    let fwd = one_sided(original, m, &opts).map_err(|e| e.to_string())?;
    let bwd = one_sided(m, original, &SampleOptions { seed: opts.seed ^ 0x5EED_0001, ..opts }).map_err(|e| e.to_string())?;
    let both = symmetric_relative(original, m, &opts).map_err(|e| e.to_string())?;
    let s = 100.0 / diagonal;
    Ok([both.rms, fwd.rms * s, bwd.rms * s])
}

fn run(input: &str) -> Result<(), String> {
    let seq = load(input)?;
    let original = seq.frame_mesh(0).ok_or("no frames")?;
    let diagonal = original.bounds().map_or(0.0, |(lo, hi)| (hi.as_dvec3() - lo.as_dvec3()).length());
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let t = std::time::Instant::now();
    let h = build(&topo, &q, &BuildOptions { anchors: vec![0.25, 0.10], ..BuildOptions::default() }).map_err(|e| e.to_string())?;
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let (be, bl) = boundary_loops(seq.vertex_count(), &seq.triangles);
    println!(
        "{input}: {} vertices, {be} boundary edges in {bl} loops, levels {:?}, build {build_ms:.0} ms",
        seq.vertex_count(),
        h.level_sizes
    );
    let sizes: Vec<u32> = h.level_sizes[1..].to_vec();
    let quadric_rms: Vec<String> =
        NodeState::compute(&h, &q, &seq.frames[0]).level_rms_errors(&h).iter().map(|e| format!("{:.4}", 100.0 * e / diagonal)).collect();
    println!("quadric RMS error per level, % of the diagonal: {quadric_rms:?}");
    let direct =
        build(&topo, &q, &BuildOptions { level_sizes: Some(sizes.clone()), ..BuildOptions::default() }).map_err(|e| e.to_string())?;
    let base_nodes = NodeState::compute(&h, &q, &seq.frames[0]);
    let direct_nodes = NodeState::compute(&direct, &q, &seq.frames[0]);
    let mut rc = Reclusterer::new(h.clone(), topo.clone(), seq.triangles.clone(), ReclusterOptions::default());
    let mut swaps = Vec::new();
    rc.frame(&seq.frames[0], &mut swaps);
    println!("frame 0 reclustering: {} swaps", swaps.len());
    println!(
        "{:>5} {:>7} | {:>22} | {:>22} | {:>22} | {:>22} | {:>6} {:>6} {:>6} | loops b/r/d/m | folds b/r/d",
        "level", "verts", "base rms fwd bwd", "recl rms fwd bwd", "direct rms fwd bwd", "mopt rms fwd bwd", "b/d", "r/d", "r/mo"
    );
    for (j, &n) in sizes.iter().enumerate() {
        let level = j + 1;
        if n < 8 {
            break;
        }
        let (mb, fb) = level_mesh(&h, &seq.triangles, &base_nodes, level);
        let (mr, fr) = level_mesh(rc.hierarchy(), &seq.triangles, rc.nodes(), level);
        let dl = direct.level_sizes.iter().position(|&s| s == n).unwrap_or(direct.top());
        let (md, fd) = level_mesh(&direct, &seq.triangles, &direct_nodes, dl);
        let mo = qem::reference(&seq, n as usize)?;
        let [b, r, d, o] = [&mb, &mr, &md, &mo].map(|m| measure(&original, m, diagonal));
        let (b, r, d, o) = (b?, r?, d?, o?);
        let loops = [&mb, &mr, &md, &mo].map(|m| boundary_loops(m.positions.len(), &m.triangles).1);
        let f = |x: [f64; 3]| format!("{:.4} {:.4} {:.4}", x[0], x[1], x[2]);
        println!(
            "{level:>5} {n:>7} | {:>22} | {:>22} | {:>22} | {:>22} | {:>6.3} {:>6.3} {:>6.3} | {:?} | {fb}/{fr}/{fd}",
            f(b),
            f(r),
            f(d),
            f(o),
            b[0] / d[0],
            r[0] / d[0],
            r[0] / o[0],
            loops
        );
    }
    Ok(())
}

fn compare(input: &str, meshes: &[String]) -> Result<(), String> {
    let seq = load(input)?;
    let original = seq.frame_mesh(0).ok_or("no frames")?;
    let diagonal = original.bounds().map_or(0.0, |(lo, hi)| (hi.as_dvec3() - lo.as_dvec3()).length());
    for path in meshes {
        let m = pmcodec_mesh::obj::load_obj_sequence(Path::new(path), 30.0).map_err(|e| format!("{path}: {e}"))?;
        let m = m.frame_mesh(0).ok_or("no frames")?;
        let [r, f, b] = measure(&original, &m, diagonal)?;
        println!("{path}: {} vertices, rms {r:.4} fwd {f:.4} bwd {b:.4}", m.positions.len());
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() >= 2 && args[0] == "--compare" {
        return match compare(&args[1], &args[2..]) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("frame0_levels: {e}");
                ExitCode::from(3)
            }
        };
    }
    if args.is_empty() {
        eprintln!("usage: frame0_levels INPUT [INPUT...]");
        return ExitCode::from(2);
    }
    for a in &args {
        if let Err(e) = run(a) {
            eprintln!("frame0_levels: {e}");
            return ExitCode::from(3);
        }
    }
    ExitCode::SUCCESS
}
