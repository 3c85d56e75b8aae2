//! `pmcodec encode`, `decode`, `info` and `verify`: the container from the command line.

use crate::input::{self, InputArgs};
use crate::{EXIT_BAD_INPUT, Exit, progress};
use anyhow::{Context, anyhow};
use clap::{Args, ValueEnum};
use pmcodec_container::{
    Decoder, EncodeOptions, FileSource, MeshTarget, Motion, QuantizationChoice, Reader, VertexOrder, encode, summary, verify, write_file,
};
use pmcodec_hierarchy::base::{PoseSet, VertexWeights};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum WeightsArg {
    None,
    Tertiles,
    Smooth,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MotionArg {
    KeyframeAffine,
    Affine,
    Mean,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OrderArg {
    BreadthFirst,
    Input,
}

#[derive(Args, Debug)]
pub struct EncodeArgs {
    /// An OBJ folder or glob, or a glTF/GLB file.
    pub input: PathBuf,
    /// The .pmc file to write.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub input_args: InputArgs,
    /// Branching factor: each level has about 1/b of the vertices of the one below (2..=16),
    /// from the last level anchor down.
    #[arg(long, default_value_t = 4)]
    pub branching: u32,
    /// Levels at these shares of the input vertices first (decreasing percentages), so that
    /// clients at those budgets read only the coarser bands; `none` for 1/b, 1/b^2, ...
    #[arg(long, default_value = "25%,10%", value_name = "P%,...")]
    pub level_anchors: String,
    /// A keyframe every K frames (0: only frame 0).
    #[arg(long, default_value_t = 16)]
    pub keyframe_interval: u32,
    /// Position error bound, relative to the bounding-box diagonal.
    #[arg(long, conflicts_with = "quant_bits")]
    pub max_error: Option<f64>,
    /// Quantize positions to this many bits per axis of the bounding box instead.
    #[arg(long)]
    pub quant_bits: Option<u8>,
    /// Store level j >= 1 on a grid of 2^(j + K) quanta: fewer bits, coarser cuts (the input
    /// vertices stay within the error bound); `none` stores every node within the bound.
    #[arg(long, value_name = "K|none", default_value = "0")]
    pub coarse_grid: String,
    /// How input vertices are predicted between keyframes: `keyframe-affine` (the affine
    /// motion of their neighbourhood, weighted as the keyframe's shape gives), `affine` (the
    /// same fitted on every frame: 1% fewer bytes, decoding about half again slower) or `mean`
    /// (their neighbours' mean motion: on the horse 24% more position bytes).
    #[arg(long, value_enum, default_value_t = MotionArg::KeyframeAffine)]
    pub motion: MotionArg,
    /// The order input vertices are decoded in: `breadth-first` over the triangles, or `input`
    /// (what format version 4 used; better with `--motion mean`).
    #[arg(long, value_enum, default_value_t = OrderArg::BreadthFirst)]
    pub order: OrderArg,
    /// Quadrics the base hierarchy is built from: `first`, `all`, or a number of sampled frames.
    #[arg(long, default_value = "first")]
    pub base_poses: String,
    /// Per-vertex weights from morph-target or per-frame displacement (Berner & Rieger).
    #[arg(long, value_enum, default_value_t = WeightsArg::None)]
    pub base_weights: WeightsArg,
    /// Hierarchical QEM growth exponent (equation 2).
    #[arg(long)]
    pub beta: Option<f64>,
    /// Smallest swap benefit relative to the moving node's error (hysteresis).
    #[arg(long)]
    pub min_benefit: Option<f64>,
    /// At most this many swaps per frame.
    #[arg(long)]
    pub max_swaps: Option<u32>,
    /// Keep approximations homeomorphic (section 4.2's optional rule).
    #[arg(long)]
    pub homeomorphism: bool,
}

fn parse_anchors(s: &str) -> anyhow::Result<Vec<f64>> {
    if s.trim() == "none" || s.trim().is_empty() {
        return Ok(Vec::new());
    }
    let mut out: Vec<f64> = Vec::new();
    for part in s.split(',') {
        let p = part.trim();
        let v: f64 =
            p.strip_suffix('%').unwrap_or(p).trim().parse().map_err(|_| anyhow!("--level-anchors {p:?}: use percentages like 25%,10%"))?;
        if !(v > 0.0 && v < 100.0) || out.last().is_some_and(|&last| v / 100.0 >= last) {
            return Err(anyhow!("--level-anchors {s:?}: percentages must decrease and lie between 0 and 100"));
        }
        out.push(v / 100.0);
    }
    Ok(out)
}

fn parse_poses(s: &str) -> anyhow::Result<PoseSet> {
    match s {
        "first" => Ok(PoseSet::FirstFrame),
        "all" => Ok(PoseSet::AllFrames),
        n => n.parse::<u32>().map(PoseSet::Sampled).map_err(|_| anyhow!("--base-poses {n:?}: use first, all or a number of frames")),
    }
}

pub fn encode_cmd(args: EncodeArgs, quiet: bool) -> Result<(), Exit> {
    let seq = input::load(&args.input, &args.input_args)?;
    let coarse_grid = match args.coarse_grid.trim() {
        "none" => None,
        k => Some(k.parse::<u32>().map_err(|_| Exit(2, anyhow!("--coarse-grid {k:?}: use a number of levels or none")))?),
    };
    let motion = match args.motion {
        MotionArg::KeyframeAffine => Motion::KeyframeAffine,
        MotionArg::Affine => Motion::Affine,
        MotionArg::Mean => Motion::Mean,
    };
    let order = match args.order {
        OrderArg::BreadthFirst => VertexOrder::BreadthFirst,
        OrderArg::Input => VertexOrder::Input,
    };
    let mut opts = EncodeOptions { keyframe_interval: args.keyframe_interval, coarse_grid, motion, order, ..Default::default() };
    opts.build.branching = args.branching;
    opts.build.anchors = parse_anchors(&args.level_anchors).map_err(|e| Exit(2, e))?;
    opts.base.poses = parse_poses(&args.base_poses).map_err(|e| Exit(2, e))?;
    opts.base.weights = match args.base_weights {
        WeightsArg::None => VertexWeights::None,
        WeightsArg::Tertiles => VertexWeights::Tertiles,
        WeightsArg::Smooth => VertexWeights::Smooth,
    };
    if let Some(b) = args.beta {
        opts.recluster.beta = b;
    }
    if let Some(m) = args.min_benefit {
        opts.recluster.min_relative_benefit = m;
    }
    if let Some(m) = args.max_swaps {
        opts.recluster.max_swaps_per_frame = m;
    }
    opts.recluster.homeomorphism = args.homeomorphism;
    opts.quantization = match (args.max_error, args.quant_bits) {
        (_, Some(b)) => QuantizationChoice::Bits(b),
        (Some(e), None) => QuantizationChoice::MaxError(e),
        (None, None) => QuantizationChoice::MaxError(1e-4),
    };
    let bar = progress(seq.frame_count() as u64, "encode", quiet);
    let bytes = encode(&seq, &opts, |_| bar.inc(1)).with_context(|| format!("encoding {}", args.input.display()))?;
    bar.finish_and_clear();
    write_file(&args.output, &bytes).with_context(|| format!("writing {}", args.output.display()))?;
    if !quiet {
        let reader = Reader::open(bytes.as_slice()).context("re-reading what was written")?;
        let s = summary(&reader);
        eprintln!(
            "{}: {} frames, {} vertices, levels {:?}; {} bytes; positions {:.2} bits/vertex/frame; topology {:.0} B/frame",
            args.output.display(),
            s.header.frame_count,
            s.header.vertex_count,
            s.header.level_sizes,
            s.file_bytes,
            s.positions_bits_per_vertex_frame,
            s.delta_bytes_per_frame
        );
    }
    Ok(())
}

pub(crate) fn open(path: &Path) -> Result<Reader<FileSource>, Exit> {
    let src = FileSource::open(path).map_err(|e| Exit(EXIT_BAD_INPUT, anyhow!(e)))?;
    Reader::open(src).with_context(|| format!("reading {}", path.display())).map_err(|e| Exit(EXIT_BAD_INPUT, e))
}

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("target").args(["triangles", "vertices", "level", "max_error"])))]
pub struct DecodeArgs {
    /// The .pmc file.
    pub input: PathBuf,
    /// Frame to decode (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: u32,
    /// Every frame, one OBJ per frame into the folder given by -o (names sort in frame order).
    #[arg(long, conflicts_with = "frame")]
    pub all_frames: bool,
    /// At most this many triangles.
    #[arg(long)]
    pub triangles: Option<u32>,
    /// At most this many vertices.
    #[arg(long)]
    pub vertices: Option<u32>,
    /// A whole level (0 = the input mesh, every input vertex in input order).
    #[arg(long)]
    pub level: Option<usize>,
    /// Refine every node whose error bound exceeds this fraction of the bounding-box diagonal.
    #[arg(long)]
    pub max_error: Option<f64>,
    /// Output: .glb or .obj (a folder with --all-frames).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn decode_cmd(args: DecodeArgs, quiet: bool) -> Result<(), Exit> {
    let reader = open(&args.input)?;
    let target = match (args.triangles, args.vertices, args.level, args.max_error) {
        (Some(n), ..) => MeshTarget::Triangles(n),
        (_, Some(n), ..) => MeshTarget::Vertices(n),
        (_, _, Some(l), _) => MeshTarget::Level(l),
        (.., Some(e)) => MeshTarget::MaxError(e),
        _ => MeshTarget::Level(0),
    };
    // A level-limited decode reads only the bands it needs.
    let min_level = match target {
        MeshTarget::Level(l) => l.min(reader.header().top()),
        _ => 0,
    };
    let mut dec = Decoder::new(reader.borrowed(), min_level).context("starting the decoder")?;
    if args.all_frames {
        std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
        let frames = reader.header().frame_count;
        let width = frames.to_string().len().max(4);
        let bar = progress(frames as u64, "decode", quiet);
        for f in 0..frames {
            dec.seek(f).with_context(|| format!("decoding frame {f}"))?;
            let mesh = dec.mesh(target)?;
            let path = args.output.join(format!("frame-{f:0width$}.obj"));
            pmcodec_mesh::write::write_mesh_file(&path, &mesh).with_context(|| format!("writing {}", path.display()))?;
            bar.inc(1);
        }
        bar.finish_and_clear();
    } else {
        dec.seek(args.frame).with_context(|| format!("decoding frame {}", args.frame))?;
        let mesh = dec.mesh(target)?;
        pmcodec_mesh::write::write_mesh_file(&args.output, &mesh).with_context(|| format!("writing {}", args.output.display()))?;
        if !quiet {
            eprintln!(
                "{}: frame {}, {} vertices, {} triangles",
                args.output.display(),
                args.frame,
                mesh.positions.len(),
                mesh.triangles.len()
            );
        }
    }
    Ok(())
}

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
    println!("levels            {:?} (branching {})", h.level_sizes, h.branching);
    println!("keyframe interval {}", h.keyframe_interval);
    println!("bounding box      {:?} .. {:?}", h.bbox_min, h.bbox_max);
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
    println!("{:>6} {:>8} {:>12} {:>12} {:>12} {:>14}", "level", "nodes", "keyframes B", "deltas B", "positions B", "B/frame to L");
    for l in (0..h.levels()).rev() {
        println!(
            "{l:>6} {:>8} {:>12} {:>12} {:>12} {:>14.0}",
            h.level_sizes[l], s.key_bytes[l], s.delta_bytes[l], s.positions_bytes[l], s.bytes_per_frame_to_level[l]
        );
    }
    println!("encoded with      {:?}", h.encoded_with);
    Ok(())
}

#[derive(Args, Debug)]
pub struct VerifyArgs {
    pub input: PathBuf,
}

pub fn verify_cmd(args: VerifyArgs, quiet: bool) -> Result<(), Exit> {
    let reader = open(&args.input)?;
    let report = verify(&reader).with_context(|| format!("verifying {}", args.input.display())).map_err(|e| Exit(EXIT_BAD_INPUT, e))?;
    if !quiet {
        println!("{}: ok ({} chunks, {} frames, {} bytes)", args.input.display(), report.chunks, report.frames, report.bytes);
    }
    Ok(())
}
