//! `pmcodec encode`, and what the container commands share (errors, opening a file).

use crate::input::{self, InputArgs};
use crate::{EXIT_BAD_INPUT, EXIT_FAILURE, Exit, progress};
use anyhow::{Context, anyhow};
use clap::{Args, ValueEnum};
use pmcodec_container::{
    ContainerError, DerivedTopology, EncodeOptions, FileSource, Motion, QuantizationChoice, Reader, SkinPlacement, SkinTrial,
    SkinnedCoarse, StreamError, VertexOrder, encode, encode_posed, encode_stream, encode_with_report, skin_trial, summary, write_file,
};
use pmcodec_hierarchy::base::{PoseSet, VertexWeights};
use pmcodec_hierarchy::recluster::ReclusterOptions;
use pmcodec_mesh::InputLimits;
use pmcodec_mesh::gltf_input::{AnimationSelector, FrameSampler, RiggedMesh};
use pmcodec_mesh::skin_fit::{FitOptions, MAX_BONES, fit_skin};
use serde::Serialize;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

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

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DerivedArg {
    Always,
    Never,
    WhenCheaper,
    PerBand,
}

/// How `encode --fit-skin` tells whether the fitted skin pays (`--skin-choice`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SkinChoiceArg {
    /// From a trial coding of the input vertices both ways before the encode: one encode.
    Estimate,
    /// From the files themselves: up to three encodes, the smallest kept.
    Exhaustive,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SkinArg {
    BackPropagated,
    Centroid,
    None,
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
    /// Levels holding at least these shares of the input triangles first (decreasing
    /// percentages), so that clients at those budgets read only the coarser bands; `none` for
    /// 1/b, 1/b^2, ... of the vertices
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
    /// Store coarse nodes at the cheapest grid point within reach even where it is off their
    /// cluster's surface (as files before the surface grid; for comparison).
    #[arg(long)]
    pub off_surface_grid: bool,
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
    /// Which bands' faces and corner updates their readers derive from the triangles and the
    /// parent maps below them instead of reading them: `always` (the smallest file), `never`
    /// (every band sends them, as files before), `when-cheaper` (in the keyframe intervals where
    /// a coarse client then reads no more bytes), or `per-band` (the bands whose clients then
    /// read no more bytes over the whole file, the triangles counted).
    #[arg(long, value_enum, default_value_t = DerivedArg::Always)]
    pub derived_topology: DerivedArg,
    /// Write the frame-by-frame index (proto/container.md, "Index") instead of the banded one,
    /// the default: a frame's chunks are then one byte range, but a client at a coarse level
    /// fetches every band's index entries.
    #[arg(long, conflicts_with = "banded_index")]
    pub frame_index: bool,
    /// The banded index where it is no longer than the frame-by-frame one: the default, kept
    /// for scripts that ask for it.
    #[arg(long, hide = true)]
    pub banded_index: bool,
    /// For a skinned glTF, where coarse nodes sit in bind space for prediction by skinning:
    /// `back-propagated` (their frame-0 position through their blended transform, Houle &
    /// Poulin), `centroid` (their cluster's rest centroid), or `none` (no skinning).
    #[arg(long, value_enum, default_value_t = SkinArg::BackPropagated)]
    pub skin: SkinArg,
    /// Fit a skin of BONES rigid bones (default: chosen by cost, from one per 200 vertices up) to the
    /// sequence and predict it by skinning (Le & Deng's SSDR), replacing any skin the input
    /// has; the encoder falls back to the plain file where the skin does not pay for itself.
    #[arg(long, num_args = 0..=1, default_missing_value = "auto", value_name = "BONES")]
    pub fit_skin: Option<String>,
    /// With --fit-skin: keep the fitted skin even where the plain file would be smaller (for
    /// `decode --skinned-glb`, which exports a file's skin as a skinned glTF).
    #[arg(long, requires = "fit_skin")]
    pub keep_skin: bool,
    /// With --fit-skin: how the encoder tells whether the skin pays. `estimate` codes the
    /// input vertices both ways on a sample of keyframe intervals before the encode and
    /// encodes once; `exhaustive` encodes with the skin and, where that does not clearly pay,
    /// without it (and with every joint at every level), keeping the smallest file.
    #[arg(long, value_enum, default_value_t = SkinChoiceArg::Estimate, requires = "fit_skin")]
    pub skin_choice: SkinChoiceArg,
    /// Print what was written (sizes, times, the fitted skin and whether it was used) as JSON
    /// on stdout.
    #[arg(long)]
    pub json: bool,
    /// Quadrics the base hierarchy is built from: `first`, `all`, or a number of sampled frames.
    #[arg(long, default_value = "first")]
    pub base_poses: String,
    /// Per-vertex weights from morph-target or per-frame displacement (Berner & Rieger).
    #[arg(long, value_enum, default_value_t = WeightsArg::None)]
    pub base_weights: WeightsArg,
    #[command(flatten)]
    pub recluster: ReclusterArgs,
    /// For a skinned input predicted by skinning, recluster only every N frames (the frames
    /// between keep their clusters; their nodes still move). Default: a glTF's own skin keeps
    /// frame 0's clusters throughout (its motion is the skin's, and Houle & Poulin's coarse
    /// nodes are points the skeleton carries), a fitted skin reclusters every frame (1).
    #[arg(long, value_name = "N")]
    pub skinned_recluster_every: Option<u32>,
}

/// The reclustering flags `encode` and `eval` share; a flag left out keeps the library's
/// default ([`ReclusterOptions::default`]).
#[derive(Args, Debug, Default)]
pub struct ReclusterArgs {
    /// Hierarchical QEM growth exponent (Kircher & Garland equation 2; the paper used 1.9127)
    /// [default: 4].
    #[arg(long, allow_hyphen_values = true)]
    pub beta: Option<f64>,
    /// Smallest swap benefit relative to the moving node's error (hysteresis) [default: 1].
    #[arg(long, allow_hyphen_values = true)]
    pub min_benefit: Option<f64>,
    /// At most this many swaps per frame [default: no limit].
    #[arg(long)]
    pub max_swaps: Option<u32>,
    /// Independent-set passes per level per frame [default: 16].
    #[arg(long)]
    pub max_passes: Option<u32>,
    /// Rank swaps by equation 1's conservative estimate instead of the exact error change.
    #[arg(long)]
    pub estimated_benefit: bool,
    /// Keep approximations homeomorphic (section 4.2's optional rule).
    #[arg(long)]
    pub homeomorphism: bool,
}

impl ReclusterArgs {
    /// The library's options with these flags applied; a value out of range is bad input.
    pub fn options(&self) -> Result<ReclusterOptions, Exit> {
        for (flag, v) in [("--beta", self.beta), ("--min-benefit", self.min_benefit)] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(Exit(EXIT_BAD_INPUT, anyhow!("{flag} {v}: use a finite number >= 0")));
            }
        }
        let mut opts = ReclusterOptions::default();
        if let Some(b) = self.beta {
            opts.beta = b;
        }
        if let Some(m) = self.min_benefit {
            opts.min_relative_benefit = m;
        }
        if let Some(m) = self.max_swaps {
            opts.max_swaps_per_frame = m;
        }
        if let Some(m) = self.max_passes {
            opts.max_passes = m;
        }
        opts.exact_benefit = !self.estimated_benefit;
        opts.homeomorphism = self.homeomorphism;
        Ok(opts)
    }
}

/// Anchors as percentages: a value that is not a number is a usage error (2), one out of range
/// bad input (3), as everywhere in the command line.
fn parse_anchors(s: &str) -> Result<Vec<f64>, Exit> {
    if s.trim() == "none" || s.trim().is_empty() {
        return Ok(Vec::new());
    }
    let mut out: Vec<f64> = Vec::new();
    for part in s.split(',') {
        let p = part.trim();
        let v: f64 = p
            .strip_suffix('%')
            .unwrap_or(p)
            .trim()
            .parse()
            .map_err(|_| Exit(2, anyhow!("--level-anchors {p:?}: use percentages like 25%,10%")))?;
        if !(v > 0.0 && v < 100.0) || out.last().is_some_and(|&last| v / 100.0 >= last) {
            return Err(Exit(EXIT_BAD_INPUT, anyhow!("--level-anchors {s:?}: percentages must decrease and lie between 0 and 100")));
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

/// The frame rates accepted: a frame every 100 s to a thousand a second. A glTF animation is
/// sampled at this rate, so a high rate means as many frames, and players pace by it.
const FPS_RANGE: std::ops::RangeInclusive<f32> = 0.01..=1000.0;

/// `--fps` out of [`FPS_RANGE`] is bad input (`1e-30` was accepted, and players of the file
/// then overflowed their frame times).
pub(crate) fn check_fps(args: &InputArgs) -> Result<(), Exit> {
    if FPS_RANGE.contains(&args.fps) {
        return Ok(());
    }
    let (lo, hi) = (FPS_RANGE.start(), FPS_RANGE.end());
    Err(Exit(EXIT_BAD_INPUT, anyhow!("--fps {:?}: use {lo}..={hi} frames per second", args.fps)))
}

/// The bone count `--fit-skin` asks for: `None` for the default.
fn parse_bones(s: &str) -> Result<Option<u32>, Exit> {
    if s == "auto" {
        return Ok(None);
    }
    let n: u32 = s.trim().parse().map_err(|_| Exit(2, anyhow!("--fit-skin {s:?}: use a number of bones (or no value for the default)")))?;
    if n == 0 || n > MAX_BONES {
        return Err(Exit(EXIT_BAD_INPUT, anyhow!("--fit-skin {n}: use 1 to {MAX_BONES} bones")));
    }
    Ok(Some(n))
}

/// What `encode --json` prints.
#[derive(Serialize)]
struct EncodeOutput {
    output: String,
    bytes: u64,
    frames: u32,
    vertices: u32,
    positions_bits_per_vertex_frame: f64,
    /// Pose and bind chunks, bytes (0 without a skin).
    skin_bytes: u64,
    /// The whole command, loading included.
    seconds: f64,
    encode_seconds: f64,
    fitted_skin: Option<FittedSkinOutput>,
}

#[derive(Serialize)]
struct FittedSkinOutput {
    bones: u32,
    rms_error: f64,
    max_error: f64,
    /// Vertices the bones were fitted to, the bone counts tried (doubling from the default)
    /// and the SSDR alternations run over all of them: the fit's work.
    sample_vertices: u32,
    counts_tried: Vec<u32>,
    alternations: u32,
    fit_seconds: f64,
    /// The fit's share of the whole command's time.
    fit_share: f64,
    /// Whether the file predicts by the fitted skin; if not, why.
    used: bool,
    reason: String,
    /// The trial that told whether the skin pays before the encode (`--skin-choice
    /// estimate`; none with --keep-skin or `exhaustive`).
    trial: Option<SkinTrial>,
    /// The file's size with the fitted skin (`bytes` when it was used; none when the trial
    /// dropped the skin and no file with it was made), and its pose (bone transforms, every
    /// frame), bind (every node's weights and bind position) and position bytes.
    bytes_with_skin: Option<u64>,
    pose_bytes: u64,
    bind_bytes: u64,
    positions_bytes_with_skin: u64,
    encoder: Option<pmcodec_container::EncodeReport>,
}

impl FittedSkinOutput {
    /// What `--json` says of `fit` before any file with the skin is measured: whether the
    /// skin is used and why, and the trial that told.
    fn of(fit: &pmcodec_mesh::skin_fit::FitReport, fit_seconds: f64, (used, reason): (bool, String), trial: Option<SkinTrial>) -> Self {
        FittedSkinOutput {
            bones: fit.bones,
            rms_error: fit.rms_error,
            max_error: fit.max_error,
            sample_vertices: fit.sample_vertices,
            counts_tried: fit.counts_tried.clone(),
            alternations: fit.alternations,
            fit_seconds,
            fit_share: 0.0,
            used,
            reason,
            trial,
            bytes_with_skin: None,
            pose_bytes: 0,
            bind_bytes: 0,
            positions_bytes_with_skin: 0,
            encoder: None,
        }
    }
}

pub fn encode_cmd(args: EncodeArgs, quiet: bool) -> Result<(), Exit> {
    let started = Instant::now();
    check_fps(&args.input_args)?;
    let fit_bones = args.fit_skin.as_deref().map(parse_bones).transpose()?;
    if fit_bones.is_some() && args.skin == SkinArg::None {
        return Err(Exit(2, anyhow!("--fit-skin with --skin none: a fitted skin is only used for prediction by skinning")));
    }
    // OBJ frames after the first are parsed on a thread of their own while the encoder works;
    // glTF frames are posed as the encoder asks for them; a skin fit needs every frame first.
    let rig = if fit_bones.is_some() { None } else { open_rig(&args.input, &args.input_args)? };
    let sampler = rig.as_ref().map(|(rig, animation)| posed(rig, *animation, &args.input, &args.input_args)).transpose()?;
    let (mut seq, rest) = match &sampler {
        Some((_, head)) => (head.clone(), None),
        None if fit_bones.is_some() => (input::load(&args.input, &args.input_args)?, None),
        None => input::open(&args.input, &args.input_args)?,
    };
    let mut fitted = None;
    if let Some(bones) = fit_bones {
        if seq.skin.is_some() && !quiet {
            eprintln!("warning: {}: --fit-skin replaces the input's own skin", args.input.display());
        }
        let t = Instant::now();
        // The fit weighs residuals in the quanta they will be coded in (about 12 bits under the
        // default error bound).
        let quant_bits = args.quant_bits.map_or(12, u32::from);
        let (skin, report) = fit_skin(&seq, &FitOptions { bones, quant_bits, ..Default::default() })
            .map_err(|e| Exit(EXIT_BAD_INPUT, anyhow::Error::msg(e.to_string()).context(format!("encoding {}", args.input.display()))))?;
        seq.skin = Some(skin);
        fitted = Some((report, t.elapsed().as_secs_f64()));
    }
    for w in seq.skin.iter().flat_map(|s| &s.warnings).filter(|_| !quiet) {
        eprintln!("warning: {}: {w}", args.input.display());
    }
    let mut opts = encode_options(&args)?;
    if let (Some(_), Some(_), None) = (&sampler, &seq.skin, args.skinned_recluster_every) {
        // A glTF's own skin: its frames move exactly as the skeleton does, so frame 0's
        // clusters stay clusters and a coarse node's skin (fitted to its frame-0 cluster) goes
        // on predicting it, where reclustered nodes drift from theirs (the generated 34,102-vertex
        // character of scripts/benchmarks.py: 11.2 MB -> 7.1 MB, positions 1.98 -> 1.25 bits per
        // vertex per frame, and no swap search, the largest part of the reclustering thread's
        // work; on a 6,936-vertex one, `pmcodec eval --sweep 3 --frames 12`, the cuts' RMS
        // error at 25% of the vertices grows 11%, at the other budgets by 3% at most).
        opts.skinned_recluster_every = u32::MAX;
    }
    let encoding = Instant::now();
    let what = || format!("encoding {}", args.input.display());
    let frames = if rest.is_some() || sampler.is_some() { seq.frame_names.len() } else { seq.frame_count() };
    // The exhaustive skin choice may encode twice; the trial's once.
    let twice = fitted.is_some() && args.skin_choice == SkinChoiceArg::Exhaustive;
    let bar = progress(frames as u64 * (1 + twice as u64), "encode", quiet || args.json);
    let mut fitted_out = None;
    // What the encoder refuses is the input or an option value out of range: bad input.
    let bytes = if let Some((fit, fit_seconds)) = fitted {
        let (bytes, out) = encode_fitted(
            &mut seq,
            &opts,
            (fit, fit_seconds, args.keep_skin, args.skin_choice == SkinChoiceArg::Exhaustive),
            &bar,
            &what(),
        )?;
        fitted_out = Some(out);
        bytes
    } else {
        encode_read(&seq, (rest, sampler.as_ref().map(|s| &s.0)), frames, &opts, &bar, &args.input)?
    };
    bar.finish_and_clear();
    let encode_seconds = encoding.elapsed().as_secs_f64();
    write_file(&args.output, &bytes).with_context(|| format!("writing {}", args.output.display()))?;
    let seconds = started.elapsed().as_secs_f64();
    if let Some(f) = fitted_out.as_mut() {
        f.fit_share = f.fit_seconds / seconds.max(f64::MIN_POSITIVE);
    }
    let s = summary(&Reader::open(bytes.as_slice()).context("re-reading what was written")?);
    if let (Some(f), false) = (&fitted_out, quiet || args.json) {
        eprintln!(
            "fitted skin: {} bones, RMS error {:.3}% of the diagonal (worst {:.2}%), {:.2} s ({:.0}% of the encode); {}: {}",
            f.bones,
            100.0 * f.rms_error,
            100.0 * f.max_error,
            f.fit_seconds,
            100.0 * f.fit_share,
            if f.used { "used" } else { "not used, encoded without it" },
            f.reason
        );
    }
    if args.json {
        let out = EncodeOutput {
            output: args.output.display().to_string(),
            bytes: s.file_bytes,
            frames: s.header.frame_count,
            vertices: s.header.vertex_count,
            positions_bits_per_vertex_frame: s.positions_bits_per_vertex_frame,
            skin_bytes: s.pose_bytes + s.bind_bytes.iter().sum::<u64>(),
            seconds,
            encode_seconds,
            fitted_skin: fitted_out,
        };
        println!("{}", serde_json::to_string_pretty(&out).context("writing JSON")?);
    } else if !quiet {
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

/// The encoder's options from `encode`'s flags (everything but the input, the output and the
/// skin fit). `eval --sweep` encodes with `encode`'s defaults through this too.
pub fn encode_options(args: &EncodeArgs) -> Result<EncodeOptions, Exit> {
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
    let skin = match args.skin {
        SkinArg::BackPropagated => Some(SkinPlacement::BackPropagated),
        SkinArg::Centroid => Some(SkinPlacement::Centroid),
        SkinArg::None => None,
    };
    let derived_topology = match args.derived_topology {
        DerivedArg::Always => DerivedTopology::Always,
        DerivedArg::Never => DerivedTopology::Never,
        DerivedArg::WhenCheaper => DerivedTopology::WhenCheaper,
        DerivedArg::PerBand => DerivedTopology::PerBand,
    };
    let mut opts = EncodeOptions {
        keyframe_interval: args.keyframe_interval,
        coarse_grid,
        surface_grid: !args.off_surface_grid,
        motion,
        order,
        skin,
        derived_topology,
        ..Default::default()
    };
    if args.frame_index {
        opts.chunk_flags &= !pmcodec_container::format::FLAG_BANDS;
    }
    opts.build.branching = args.branching;
    opts.build.anchors = parse_anchors(&args.level_anchors)?;
    opts.base.poses = parse_poses(&args.base_poses).map_err(|e| Exit(2, e))?;
    opts.base.weights = match args.base_weights {
        WeightsArg::None => VertexWeights::None,
        WeightsArg::Tertiles => VertexWeights::Tertiles,
        WeightsArg::Smooth => VertexWeights::Smooth,
    };
    opts.recluster = args.recluster.options()?;
    opts.skinned_recluster_every = args.skinned_recluster_every.unwrap_or(1);
    opts.quantization = match (args.max_error, args.quant_bits) {
        (_, Some(b)) => QuantizationChoice::Bits(b),
        (Some(e), None) => QuantizationChoice::MaxError(e),
        (None, None) => QuantizationChoice::MaxError(1e-4),
    };
    Ok(opts)
}

/// A glTF input opened to be posed frame by frame: the welded rig and the animation to
/// sample (as `input::load` chooses it); `None` for other input.
fn open_rig(path: &Path, args: &InputArgs) -> Result<Option<(RiggedMesh, Option<usize>)>, Exit> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if ext != "glb" && ext != "gltf" {
        return Ok(None);
    }
    let bad = |e: pmcodec_mesh::MeshError| Exit(EXIT_BAD_INPUT, anyhow::Error::new(e).context(format!("reading {}", path.display())));
    let mut rig = RiggedMesh::from_path_with(path, &InputLimits::default()).map_err(bad)?;
    rig.weld();
    let animation = match &args.animation {
        Some(a) => Some(
            rig.find_animation(&match a.parse::<usize>() {
                Ok(i) => AnimationSelector::Index(i),
                Err(_) => AnimationSelector::Name(a.clone()),
            })
            .map_err(bad)?,
        ),
        None => (!rig.animations.is_empty()).then_some(0),
    };
    Ok(Some((rig, animation)))
}

/// The sampler of `rig`'s `animation` at the input's frame rate and the sequence's head (frame
/// 0, the skin and every frame's name), under the default input limits.
fn posed<'a>(
    rig: &'a RiggedMesh,
    animation: Option<usize>,
    path: &Path,
    args: &InputArgs,
) -> Result<(FrameSampler<'a>, pmcodec_mesh::Sequence), Exit> {
    let bad = |e: pmcodec_mesh::MeshError| Exit(EXIT_BAD_INPUT, anyhow::Error::new(e).context(format!("reading {}", path.display())));
    let sampler = rig.sampler(animation, args.fps, &InputLimits::default()).map_err(bad)?;
    let head = sampler.head().map_err(bad)?;
    Ok((sampler, head))
}

/// Encodes `seq`, whose frames after the first `rest` reads while the encoder works (OBJ
/// input) or the sampler poses as the encoder asks for them (glTF input, against the bounds of
/// a posing pass of their own: no frame is held beyond the few being encoded), or which holds
/// every frame.
fn encode_read(
    seq: &pmcodec_mesh::Sequence,
    (rest, sampler): (Option<pmcodec_mesh::obj::ObjFrames>, Option<&FrameSampler>),
    frames: usize,
    opts: &EncodeOptions,
    bar: &indicatif::ProgressBar,
    input: &Path,
) -> Result<Vec<u8>, Exit> {
    let what = || format!("encoding {}", input.display());
    if let Some(sampler) = sampler {
        let bounds = || sampler.bounds().map_err(ContainerError::from);
        let progress = |_| {
            bar.inc(1);
            ControlFlow::Continue(())
        };
        return encode_posed(seq, frames, sampler.frames(1), bounds, opts, progress)
            .map(|(bytes, _)| bytes)
            .map_err(|e| container_error(e, what()));
    }
    Ok(match rest {
        Some(rest) => encode_stream(seq, frames, rest, opts, |_| {
            bar.inc(1);
            ControlFlow::Continue(())
        })
        .map_err(|e| match e {
            StreamError::Input(e) => Exit(EXIT_BAD_INPUT, anyhow::Error::new(e).context(format!("reading {}", input.display()))),
            StreamError::Encode(e) => container_error(e, what()),
        })?,
        None => encode(seq, opts, |_| bar.inc(1)).map_err(|e| container_error(e, what()))?,
    })
}

/// Encodes `seq` with its fitted skin, or without it when the skin does not pay for its bytes
/// (unless `keep`, from --keep-skin); returns the file kept and what `--json` says of the fit.
/// Whether it pays is told before the encode by [`skin_trial`] (`exhaustive` false), or by
/// encoding with it and, where that does not clearly pay, without it too.
fn encode_fitted(
    seq: &mut pmcodec_mesh::Sequence,
    opts: &EncodeOptions,
    (fit, fit_seconds, keep, exhaustive): (pmcodec_mesh::skin_fit::FitReport, f64, bool, bool),
    bar: &indicatif::ProgressBar,
    what: &str,
) -> Result<(Vec<u8>, FittedSkinOutput), Exit> {
    let mut trial = None;
    if !(keep || exhaustive) {
        let t = skin_trial(seq, opts).map_err(|e| container_error(e, what))?;
        if !t.pays() {
            let reason = format!(
                "a trial over {} of {} frames: skinning saved about {} bytes of the input vertices' residuals for {} bytes of \
                 bones and {} of their weights",
                t.frames_coded,
                t.frames,
                t.plain_bytes.saturating_sub(t.skinned_bytes),
                t.pose_bytes,
                t.bind_bytes
            );
            seq.skin = None;
            let bytes = encode(seq, opts, |_| bar.inc(1)).map_err(|e| container_error(e, what))?;
            return Ok((bytes, FittedSkinOutput::of(&fit, fit_seconds, (false, reason), Some(t))));
        }
        trial = Some(t);
    }
    let (mut bytes, report) = encode_with_report(seq, opts, |_| {
        bar.inc(1);
        ControlFlow::Continue(())
    })
    .map_err(|e| container_error(e, what))?;
    // Whether the fitted skin paid for its pose and bind chunks: the position bytes it
    // saved against what those chunks cost. The encoder estimates both predictions' bits
    // (an Elias gamma code of the residuals); their ratio scales the stored position bytes
    // to what the plain prediction would have stored. A fitted skin that does not pay is
    // dropped and the file encoded again without it.
    let s = summary(&Reader::open(bytes.as_slice()).context("re-reading what was encoded")?);
    let skin_bytes = s.pose_bytes + s.bind_bytes.iter().sum::<u64>();
    let positions: u64 = s.positions_bytes.iter().sum();
    let ratio = report.plain_bits as f64 / report.stored_bits.max(1) as f64;
    let saved = (positions as f64 * (ratio - 1.0)).max(0.0).round() as u64;
    let mut reason = format!(
        "skinning predicted {} of {} bands and saved about {saved} bytes of residuals for {skin_bytes} bytes of bones and weights",
        report.skinned_bands, report.bands
    );
    let bytes_with_skin = bytes.len() as u64;
    // The estimate is about: within a quarter of the skin's cost either way (the horse at
    // 12 bits estimated 121,212 saved for 119,550 and was 0.4% larger), the plain file is
    // encoded too and the smaller kept. After a trial that said the skin pays, it is kept.
    let mut used = trial.is_some() || saved as f64 > 1.25 * skin_bytes as f64;
    if keep && !used {
        reason.push_str("; kept as --keep-skin asks");
        used = true;
    }
    if !used {
        let skin = seq.skin.take();
        let plain = encode(seq, opts, |_| bar.inc(1)).map_err(|e| container_error(e, what))?;
        if saved as f64 > 0.75 * skin_bytes as f64 && plain.len() >= bytes.len() {
            used = true;
        } else {
            reason.push_str(&format!("; {} bytes without the skin, {bytes_with_skin} with it", plain.len()));
            bytes = plain;
            // The skeleton's levels (coarse levels merging joints) trade a full client's bytes
            // for a coarse client's; where the skin loses with them it may still pay without
            // them (samba-60: 972,387 B with them, 923,560 without, 926,190 without the skin).
            if let (Some(skin), Some(coarse)) = (skin, opts.skinned_coarse.filter(|c| c.joints > 0.0)) {
                seq.skin = Some(skin);
                let flat = EncodeOptions { skinned_coarse: Some(SkinnedCoarse { joints: 0.0, ..coarse }), ..opts.clone() };
                let every = encode(seq, &flat, |_| bar.inc(1)).map_err(|e| container_error(e, what))?;
                if every.len() < bytes.len() {
                    reason.push_str(&format!(", {} with it and every joint at every level: kept so", every.len()));
                    bytes = every;
                    used = true;
                } else {
                    seq.skin = None;
                }
            }
        }
    }
    let out = FittedSkinOutput {
        bytes_with_skin: Some(bytes_with_skin),
        pose_bytes: s.pose_bytes,
        bind_bytes: s.bind_bytes.iter().sum(),
        positions_bytes_with_skin: positions,
        encoder: Some(report),
        ..FittedSkinOutput::of(&fit, fit_seconds, (used, reason), trial)
    };
    Ok((bytes, out))
}

/// The exit code of a container error: what the file holds is bad input; a failing disk is a
/// failure of the work.
pub(crate) fn container_exit(e: &ContainerError) -> u8 {
    match e {
        ContainerError::Io(_) | ContainerError::Cancelled => EXIT_FAILURE,
        _ => EXIT_BAD_INPUT,
    }
}

/// `e` with its exit code and `what` (the file, and the frame where there is one) as context.
/// The message is flattened: the library's messages already include their sources, which
/// anyhow's chain would print a second time.
pub(crate) fn container_error(e: ContainerError, what: impl std::fmt::Display) -> Exit {
    Exit(container_exit(&e), anyhow::Error::msg(e.to_string()).context(what.to_string()))
}

pub(crate) fn open(path: &Path) -> Result<Reader<FileSource>, Exit> {
    // A file that cannot be opened is bad input too (named wrong, or not there).
    let src = FileSource::open(path).map_err(|e| Exit(EXIT_BAD_INPUT, anyhow!(e)))?;
    Reader::open(src).map_err(|e| container_error(e, format!("reading {}", path.display())))
}
