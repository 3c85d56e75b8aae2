//! The measurement behind issue 7's bar: per-frame RMS distance (% of the bounding-box
//! diagonal, mean and max over the frames of every animation) at 25% and 10% of the triangles,
//! for meshoptimizer on the rest pose (Regularize) and for our LODs with each placement.
//!
//! `cargo run --release -p pmcodec-lod --example lod_eval [-- FILE.glb ...]`
//! (default: Fox, RobotExpressive, Horse, Parrot from ../shared/data/gltf; the Parrot's Draco
//! geometry is decoded by the reader). A file that does not load is reported and skipped.
//! `LOD_WEIGHTING=none|tertiles|smooth` and `LOD_PER_ANIMATION=N` change the pose options;
//! `LOD_REFIT=N` the refit rounds (0: off), `LOD_REFIT_MORPH=0` and `LOD_REFIT_SKIN=0`
//! keep morph deltas and skin weights out of it.

use pmcodec_lod::measure::{MeasureOptions, animation_error, meshopt_baseline};
use pmcodec_lod::{LodOptions, Placement, RefitOptions, build_chain_with};
use pmcodec_mesh::gltf_input::RiggedMesh;
use std::path::PathBuf;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut files: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    if files.is_empty() {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/gltf");
        files = ["Fox", "RobotExpressive", "Horse", "Parrot"].iter().map(|m| dir.join(format!("{m}.glb"))).collect();
    }
    let measure = MeasureOptions::default();
    println!(
        "error = per-frame RMS surface distance, % of bbox diagonal, over every animation at {} fps ({} samples per mesh)",
        measure.frame_rate, measure.samples.samples
    );
    println!("{:<16} {:>6} {:>6} {:<22} {:>8} {:>8} {:>7}", "model", "share", "tris", "method", "mean", "max", "vs (a)");
    for file in &files {
        let mut rig = match RiggedMesh::from_path(file) {
            Ok(rig) => rig,
            Err(e) => {
                println!("{}: skipped: {e}", file.display());
                continue;
            }
        };
        rig.weld();
        let name = file.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        let total = rig.triangles.len();
        let targets: Vec<usize> = [0.25, 0.10].iter().map(|s| ((total as f64) * s).round() as usize).collect();
        let mut ours = Vec::new();
        for placement in Placement::ALL {
            let t0 = Instant::now();
            let mut opts = LodOptions { placement, ..Default::default() };
            opts.poses.vertex_weighting = match std::env::var("LOD_WEIGHTING").as_deref() {
                Ok("none") => pmcodec_lod::VertexWeighting::None,
                Ok("smooth") => pmcodec_lod::VertexWeighting::Smooth,
                _ => pmcodec_lod::VertexWeighting::Tertiles,
            };
            if let Some(n) = std::env::var("LOD_PER_ANIMATION").ok().and_then(|s| s.parse().ok()) {
                opts.poses.per_animation = n;
            }
            let mut refit = RefitOptions::default();
            if let Some(n) = std::env::var("LOD_REFIT").ok().and_then(|s| s.parse().ok()) {
                refit.iterations = n;
            }
            if std::env::var("LOD_REFIT_MORPH").as_deref() == Ok("0") {
                refit.morph = false;
            }
            if std::env::var("LOD_REFIT_SKIN").as_deref() == Ok("0") {
                refit.skin = false;
            }
            let chain = build_chain_with(rig.clone(), &targets, &opts, &refit)?;
            eprintln!("{name}: {} built in {:.1?} over {} poses", placement.name(), t0.elapsed(), chain.pose_count);
            ours.push((placement, chain));
        }
        for (k, (&share, &target)) in [25, 10].iter().zip(&targets).enumerate() {
            let base = meshopt_baseline(&rig, target);
            let a = animation_error(&rig, &base, &measure)?;
            println!(
                "{:<16} {:>5}% {:>6} {:<22} {:>8.4} {:>8.4} {:>7}",
                name,
                share,
                base.triangles.len(),
                "(a) meshopt rest pose",
                a.mean,
                a.max,
                ""
            );
            for (placement, chain) in &ours {
                let level = &chain.levels[k + 1];
                let b = animation_error(&chain.input, &level.rig, &measure)?;
                println!(
                    "{:<16} {:>5}% {:>6} {:<22} {:>8.4} {:>8.4} {:>+6.0}%",
                    name,
                    share,
                    level.rig.triangles.len(),
                    format!("(b) ours {}", placement.name()),
                    b.mean,
                    b.max,
                    100.0 * (b.mean - a.mean) / a.mean
                );
            }
        }
    }
    Ok(())
}
