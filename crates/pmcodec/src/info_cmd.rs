//! `pmcodec info` and `verify`: what a container holds, and whether every chunk reads.

use crate::Exit;
use crate::codec_cmd::{container_error, open};
use anyhow::Context;
use clap::Args;
use pmcodec_container::{Motion, VertexOrder, summary, verify};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct InfoArgs {
    pub input: PathBuf,
    /// Machine-readable output.
    #[arg(long)]
    pub json: bool,
}

pub fn info_cmd(args: InfoArgs) -> Result<(), Exit> {
    let reader = open(&args.input)?;
    let s = summary(&reader);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s).context("writing JSON")?);
        return Ok(());
    }
    let h = &s.header;
    println!("file              {}", args.input.display());
    println!("bytes             {}", s.file_bytes);
    println!("vertices          {}", h.vertex_count);
    println!("triangles         {}", h.triangle_count);
    println!("frames            {} at {} fps", h.frame_count, h.frame_rate);
    let sizes: Vec<String> = h.level_sizes.iter().map(|n| n.to_string()).collect();
    println!("levels            {} nodes, finest first (branching {})", sizes.join(", "), h.branching);
    println!("keyframe interval {}", h.keyframe_interval);
    let [a, b] = [h.bbox_min, h.bbox_max];
    println!("bounding box      ({}, {}, {}) .. ({}, {}, {})", a[0], a[1], a[2], b[0], b[1], b[2]);
    println!("quantization step {}", h.quantization.step);
    println!(
        "positions         {:.2} bits/vertex/frame ({} motion between keyframes, input vertices {})",
        s.positions_bits_per_vertex_frame,
        match h.motion {
            Motion::Mean => "mean",
            Motion::Affine => "affine",
            Motion::KeyframeAffine => "keyframe affine",
        },
        match h.order {
            VertexOrder::Input => "in input order",
            VertexOrder::BreadthFirst => "breadth first",
        }
    );
    println!("topology deltas   {:.0} B/frame ({:.0} B raw)", s.delta_bytes_per_frame, s.delta_raw_bytes_per_frame);
    if let Some(skin) = &h.skin {
        let frames = h.frame_count.max(1) as f64;
        let bind: u64 = s.bind_bytes.iter().sum();
        println!("skin              {} palette entries, pose {:.0} B/frame, bind {bind} B", skin.palette_len, s.pose_bytes as f64 / frames);
    }
    println!("{:>6} {:>8} {:>12} {:>12} {:>12} {:>14}", "level", "nodes", "keyframes B", "deltas B", "positions B", "B/frame to L");
    for l in (0..h.levels()).rev() {
        println!(
            "{l:>6} {:>8} {:>12} {:>12} {:>12} {:>14.0}",
            h.level_sizes[l], s.key_bytes[l], s.delta_bytes[l], s.positions_bytes[l], s.bytes_per_frame_to_level[l]
        );
    }
    if let Some(a) = &h.appearance {
        let attrs: Vec<String> = s.attributes_bytes.iter().rev().map(|b| b.to_string()).collect();
        println!(
            "appearance        {} charts, {} smoothing groups, {} materials, {} images; {} uv sets{}",
            a.charts,
            a.groups,
            a.materials,
            a.images,
            a.uv_sets,
            if a.colors { ", colours" } else { "" }
        );
        println!(
            "appearance bytes  charts {}, materials {}, attributes {} (levels top..0), images {}",
            s.charts_bytes,
            s.materials_bytes,
            attrs.join(" + "),
            s.image_bytes
        );
    }
    // The options the file was encoded with, one per row, as a person reads them.
    let e = &h.encoded_with;
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    println!("encoded with");
    println!("  base poses      {}", e.base_poses.escape_debug());
    println!("  base weights    {}", e.base_weights.escape_debug());
    println!("  beta            {}", e.beta);
    println!("  min benefit     {}", e.min_relative_benefit);
    println!("  max passes      {}", e.max_passes);
    println!("  homeomorphism   {}", yes_no(e.homeomorphism));
    println!("  exact benefit   {}", yes_no(e.exact_benefit));
    match (e.quant_bits, e.max_error) {
        (Some(b), _) => println!("  quantization    {b} bits per axis"),
        (None, Some(m)) => println!("  quantization    max error {m} of the bounding-box diagonal"),
        (None, None) => println!("  quantization    -"),
    }
    // Strings from the file are escaped: a file should not be able to drive the terminal.
    println!("generator         {}", h.generator.escape_debug());
    Ok(())
}

#[derive(Args, Debug)]
pub struct VerifyArgs {
    pub input: PathBuf,
}

pub fn verify_cmd(args: VerifyArgs, quiet: bool) -> Result<(), Exit> {
    let reader = open(&args.input)?;
    let report = verify(&reader).map_err(|e| container_error(e, format!("verifying {}", args.input.display())))?;
    if !quiet {
        println!("{}: ok ({} chunks, {} frames, {} bytes)", args.input.display(), report.chunks, report.frames, report.bytes);
    }
    Ok(())
}
