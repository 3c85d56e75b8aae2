//! `pmcodec lod`: deformation-aware discrete LODs of a skinned and/or morph-target glTF, written
//! as one GLB with the skin, morph targets, animations and a geomorph correspondence table per
//! level (see `proto/lod.md`). `--report` prints each level's error over every animation, next
//! to meshoptimizer's rest-pose simplification.

use crate::{EXIT_BAD_INPUT, Exit};
use anyhow::Context;
use clap::{Args, ValueEnum};
use pmcodec_lod::measure::{MeasureOptions, animation_error, meshopt_baseline, uv_error};
use pmcodec_lod::{LodError, LodOptions, Placement, PoseOptions, PoseWeights, VertexWeighting};
use pmcodec_mesh::gltf_input::RiggedMesh;
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PlacementArg {
    /// Keep one endpoint unchanged (Mohr & Gleicher 4.3): influences exactly as authored.
    Endpoint,
    /// Blend both endpoints' influences, cut to four; optimal rest position.
    Blended,
    /// One endpoint's influences, optimal translation in its bone space (Houle & Poulin 4.1).
    HoulePoulin,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum WeightingArg {
    None,
    /// Berner & Rieger: 0.33 / 0.66 / 1.0 by displacement tertile.
    Tertiles,
    /// 1/3 + 2/3 * displacement / max.
    Smooth,
}

#[derive(Args, Debug)]
pub struct LodArgs {
    /// A skinned and/or morph-target .glb or .gltf.
    pub input: PathBuf,
    /// Triangle counts of the LODs, decreasing (e.g. 2000,800,300); a trailing % makes them
    /// shares of the input (e.g. 25%,10%).
    #[arg(long, value_delimiter = ',', required = true)]
    pub triangles: Vec<String>,
    /// Output .glb.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Where collapsed vertices go.
    #[arg(long, value_enum, default_value_t = PlacementArg::HoulePoulin)]
    pub placement: PlacementArg,
    /// Per-vertex importance from displacement over the poses.
    #[arg(long, value_enum, default_value_t = WeightingArg::Tertiles)]
    pub weighting: WeightingArg,
    /// Frames sampled from each animation for the collapse cost.
    #[arg(long, default_value_t = 16)]
    pub poses_per_animation: usize,
    /// Pose weights, NAME=W: an animation name, `rest`, `morph` (each target at full weight)
    /// or `*` (every animation not named). Default 1 each.
    #[arg(long = "pose-weight", value_delimiter = ',')]
    pub pose_weights: Vec<String>,
    /// Also print each level's error over every animation and meshoptimizer's at the same count.
    #[arg(long)]
    pub report: bool,
}

fn bad_input(e: impl Into<anyhow::Error>) -> Exit {
    Exit(EXIT_BAD_INPUT, e.into())
}

fn parse_targets(items: &[String], total: usize) -> Result<Vec<usize>, Exit> {
    items
        .iter()
        .map(|s| {
            let s = s.trim();
            let value = match s.strip_suffix('%') {
                Some(p) => p
                    .parse::<f64>()
                    .ok()
                    .filter(|p| p.is_finite() && *p > 0.0 && *p < 100.0)
                    .map(|p| ((total as f64) * p / 100.0).round().max(1.0) as usize),
                None => s.parse::<usize>().ok().filter(|&n| n > 0),
            };
            value.ok_or_else(|| bad_input(anyhow::anyhow!("--triangles: {s:?} is not a positive count or a share like 25%")))
        })
        .collect()
}

pub fn run(args: LodArgs, quiet: bool) -> Result<(), Exit> {
    let mut rig = RiggedMesh::from_path(&args.input).with_context(|| format!("reading {}", args.input.display())).map_err(bad_input)?;
    rig.weld();
    let targets = parse_targets(&args.triangles, rig.triangles.len())?;
    let placement = match args.placement {
        PlacementArg::Endpoint => Placement::Endpoint,
        PlacementArg::Blended => Placement::Blended,
        PlacementArg::HoulePoulin => Placement::HoulePoulin,
    };
    let vertex_weighting = match args.weighting {
        WeightingArg::None => VertexWeighting::None,
        WeightingArg::Tertiles => VertexWeighting::Tertiles,
        WeightingArg::Smooth => VertexWeighting::Smooth,
    };
    let weights = PoseWeights::parse(&args.pose_weights).map_err(bad_input)?;
    let opts = LodOptions { poses: PoseOptions { per_animation: args.poses_per_animation.max(1), weights, vertex_weighting }, placement };
    let chain = pmcodec_lod::build_chain(rig, &targets, &opts).map_err(|e| match e {
        LodError::Internal(_) | LodError::Write(_) => Exit(crate::EXIT_FAILURE, e.into()),
        e => bad_input(e),
    })?;
    let bytes = pmcodec_lod::gltf_out::chain_glb(&chain, placement.name())?;
    pmcodec_mesh::write::write_atomic(&args.output, &bytes)?;
    // A target is an upper bound the simplifier may not reach: every collapse left would break
    // the surface (a part already down to its last triangles, a pinch, a fin). Said even when
    // quiet, since the level is not what was asked for.
    for (k, level) in chain.levels.iter().enumerate() {
        if let Some(t) = level.target.filter(|&t| level.rig.triangles.len() > t) {
            eprintln!(
                "warning: lod{k} has {} triangles, above its target {t}: no collapse was left that keeps the surface (small disconnected parts stop at a few triangles each)",
                level.rig.triangles.len()
            );
        }
    }
    if !quiet {
        for (k, level) in chain.levels.iter().enumerate() {
            eprintln!(
                "lod{k}: {} triangles, {} vertices{}",
                level.rig.triangles.len(),
                level.rig.positions.len(),
                level.target.map(|t| format!(" (target {t})")).unwrap_or_default()
            );
        }
        let input_bytes = std::fs::metadata(&args.input).map(|m| m.len()).unwrap_or(0);
        eprintln!(
            "wrote {} ({} bytes; input {input_bytes} bytes; {} poses, placement {})",
            args.output.display(),
            bytes.len(),
            chain.pose_count,
            placement.name()
        );
    }
    if args.report {
        let measure = MeasureOptions::default();
        // Position error over every animation frame (percent of the diagonal) beside texture
        // coordinate error in the rest pose (percent of the texture; "-" without UVs).
        println!("level  triangles  ours mean %  ours max %  ours UV %  meshopt mean %  meshopt max %");
        for (k, level) in chain.levels.iter().enumerate().skip(1) {
            let ours = animation_error(&chain.input, &level.rig, &measure)?;
            let base = animation_error(&chain.input, &meshopt_baseline(&chain.input, level.rig.triangles.len()), &measure)?;
            let uv = uv_error(&chain.input, &level.rig, measure.samples.samples, measure.samples.seed)?
                .map_or_else(|| "-".to_string(), |e| format!("{e:.4}"));
            println!(
                "lod{k:<3} {:>9}  {:>11.4}  {:>10.4}  {:>9}  {:>14.4}  {:>13.4}",
                level.rig.triangles.len(),
                ours.mean,
                ours.max,
                uv,
                base.mean,
                base.max
            );
        }
    }
    Ok(())
}
