//! `pmcodec eval`: per-frame symmetric surface distance (RMS and max, % of the frame's bounding
//! box diagonal) between approximations and the original frames, for this method and the two
//! baselines of Kircher & Garland figure 11, plus temporal coherence at a triangle budget.

use crate::codec_cmd::ReclusterArgs;
use crate::input::{self, InputArgs};
use crate::{EXIT_BAD_INPUT, Exit, progress};
use anyhow::Context;
use clap::{Args, ValueEnum};
use pmcodec_eval::{self as approx, ApproxOptions, Approximation, Method};
use pmcodec_hierarchy::CutTarget;
use rayon::prelude::*;
use serde::Serialize;
use std::path::PathBuf;

/// [`pmcodec_container::BudgetCut`] on the command line (`eval --budget-cut`, `decode
/// --budget-cut`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BudgetCutArg {
    /// Whole splits by budget priority (the spec's cut).
    Whole,
    /// Whole splits by budget priority, level-major: a budget at a level's count gets that level.
    Level,
    /// Partial splits, reveals ranked on each frame's positions.
    PartialFrame,
    /// Partial splits, reveals ranked on the keyframe's positions through its interval.
    PartialKeyframe,
    /// Partial splits, reveals ranked by the band (one per factor 2) of the frame's reveal
    /// priority, then by the keyframe's.
    PartialBanded1,
    /// The same with two bands per factor 2.
    PartialBanded2,
}

impl From<BudgetCutArg> for pmcodec_container::BudgetCut {
    fn from(a: BudgetCutArg) -> Self {
        use pmcodec_container::{BudgetCut::*, BudgetPriorities::*};
        match a {
            BudgetCutArg::Whole => WholeSplits,
            BudgetCutArg::Level => LevelSplits,
            BudgetCutArg::PartialFrame => PartialSplits(Frame),
            BudgetCutArg::PartialKeyframe => PartialSplits(Keyframe),
            BudgetCutArg::PartialBanded1 => PartialSplits(Banded { per_octave: 1 }),
            BudgetCutArg::PartialBanded2 => PartialSplits(Banded { per_octave: 2 }),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Frame 0's clusters for every frame, positions re-solved per frame.
    Static,
    /// Every frame simplified on its own.
    Direct,
    /// This project: the hierarchy reclustered frame by frame.
    Pmcodec,
}

impl MethodArg {
    fn method(self) -> Method {
        match self {
            MethodArg::Static => Method::FirstFrameStatic,
            MethodArg::Direct => Method::Direct,
            MethodArg::Pmcodec => Method::Reclustered,
        }
    }
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// The original sequence: an OBJ folder or glob, or a glTF/GLB file.
    pub input: PathBuf,
    #[command(flatten)]
    pub input_args: InputArgs,
    /// Vertex count of every approximation (a hierarchy level is placed at exactly this size).
    #[arg(long, default_value_t = 800)]
    pub vertices: u32,
    /// Methods to compare.
    #[arg(long, value_delimiter = ',', default_values = ["static", "direct", "pmcodec"])]
    pub methods: Vec<MethodArg>,
    /// Also measure temporal coherence: the share of shown triangles that change per frame at
    /// this triangle budget.
    #[arg(long)]
    pub coherence_triangles: Option<u32>,
    /// Surface samples per mesh and direction.
    #[arg(long, default_value_t = 20_000)]
    pub samples: usize,
    /// Branching factor of the hierarchies.
    #[arg(long, default_value_t = 4)]
    pub branching: u32,
    #[command(flatten)]
    pub recluster: ReclusterArgs,
    /// Only the first N frames; with --sweep, N frames spread evenly from the first to the last
    /// (the container is still encoded from every frame).
    #[arg(long)]
    pub frames: Option<usize>,
    /// A budget sweep instead (issue 15): at N vertex budgets log-spaced from 1% to 50% of the
    /// input's vertices, the container's cut (of --pmc, or of the input encoded in memory with
    /// `encode`'s defaults) beside direct and static, with ratios and drift. --vertices,
    /// --methods and --coherence-triangles do not apply.
    #[arg(long, num_args = 0..=1, default_missing_value = "12", value_name = "N")]
    pub sweep: Option<usize>,
    /// With --sweep: also draw the ratios to direct against the budget as a PNG.
    #[arg(long, value_name = "FILE.png", requires = "sweep")]
    pub plot: Option<std::path::PathBuf>,
    /// How the container's budget cuts are made (proto/container.md, "Cuts", "Partial
    /// splits"): the spec's whole splits, or partial splits for comparison.
    #[arg(long, value_enum, default_value_t = BudgetCutArg::Whole)]
    pub budget_cut: BudgetCutArg,
    /// Also measure a .pmc container of the same sequence as a client sees it: each frame
    /// decoded (quantized positions) and cut by the file's own split order at the same vertex
    /// count (and at the coherence budget). Reported as method `container`.
    #[arg(long, value_name = "FILE.pmc")]
    pub pmc: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct MethodReport {
    method: &'static str,
    rms: Vec<f64>,
    max: Vec<f64>,
    mean_rms: f64,
    first_quarter_rms: f64,
    last_quarter_rms: f64,
    /// Per frame, the share of shown triangles the frame before did not show, triangles
    /// identified by their corner clusters' content (input vertex sets): the same for every
    /// method.
    changed_share: Option<Vec<f64>>,
    mean_changed_share: Option<f64>,
    /// The same by corner node ids, for methods whose nodes persist (not direct).
    changed_share_by_node_ids: Option<Vec<f64>>,
    mean_changed_share_by_node_ids: Option<f64>,
}

#[derive(Serialize)]
struct Report {
    input: String,
    frames: usize,
    vertices: u32,
    coherence_triangles: Option<u32>,
    methods: Vec<MethodReport>,
}

fn mean(x: &[f64]) -> f64 {
    if x.is_empty() { 0.0 } else { x.iter().sum::<f64>() / x.len() as f64 }
}

pub fn run(args: EvalArgs, quiet: bool) -> Result<(), Exit> {
    crate::codec_cmd::check_fps(&args.input_args)?;
    if let Some(n) = args.sweep {
        if !(1..=MAX_SAMPLES).contains(&args.samples) || !(2..=16).contains(&args.branching) {
            return check_args(&args, usize::MAX);
        }
        return crate::eval_sweep::run(&args, n, quiet);
    }
    let mut seq = input::load(&args.input, &args.input_args)?;
    if let Some(n) = args.frames {
        seq.frames.truncate(n.max(1));
    }
    let frames = seq.frame_count();
    check_args(&args, seq.vertex_count())?;
    let opts = ApproxOptions { branching: args.branching, recluster: args.recluster.options()?, ..Default::default() };
    let sample = pmcodec_eval::SampleOptions { samples: args.samples, ..Default::default() };
    let originals: Vec<_> = (0..frames).filter_map(|f| seq.frame_mesh(f)).collect();
    let mut reports: Vec<MethodReport> = Vec::new();
    for m in &args.methods {
        let method = m.method();
        let bar = progress(frames as u64, method.name(), quiet);
        let approximations = approx::approximate(&seq, CutTarget::Vertices(args.vertices), method, &opts, |_| bar.inc(1))
            .with_context(|| format!("building the {} approximations", method.name()))?;
        bar.finish_and_clear();
        let distances: Vec<pmcodec_eval::Distance> = originals
            .par_iter()
            .zip(&approximations)
            .map(|(orig, a)| pmcodec_eval::symmetric_relative(orig, &a.mesh, &sample))
            .collect::<Result<_, _>>()
            // What cannot be measured is the input's (or a vertex count too small for any
            // surface): bad input.
            .map_err(|e| Exit(EXIT_BAD_INPUT, anyhow::Error::new(e).context(format!("measuring the {} approximations", method.name()))))?;
        let (changed, by_nodes) = match args.coherence_triangles {
            Some(budget) => {
                let bar = progress(frames as u64, "coherence", quiet);
                let cut_frames: Vec<Approximation> = approx::approximate(&seq, CutTarget::Triangles(budget), method, &opts, |_| bar.inc(1))
                    .context("building budget cuts")?;
                bar.finish_and_clear();
                (Some(approx::changed_share(&cut_frames)), approx::changed_share_by_nodes(&cut_frames))
            }
            None => (None, None),
        };
        reports.push(method_report(method.name(), &distances, changed, by_nodes));
    }
    // What a client gets leads: the container's stateless cut (issue 15).
    if let Some(path) = &args.pmc {
        reports.insert(0, container_report(path, &args, &originals, &sample, quiet)?);
    }
    let report = Report {
        input: args.input.display().to_string(),
        frames,
        vertices: args.vertices,
        coherence_triangles: args.coherence_triangles,
        methods: reports,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report).context("writing JSON")?);
    } else {
        print_table(&report);
    }
    Ok(())
}

/// The most surface samples per mesh and direction: each costs a point and a distance query,
/// so the bound keeps a run within memory and minutes (the default is 20,000).
const MAX_SAMPLES: usize = 10_000_000;

/// Values out of range are bad input (exit 3) naming the value and the range, before any work
/// (`--vertices 0` once never returned).
fn check_args(args: &EvalArgs, input_vertices: usize) -> Result<(), Exit> {
    let bad = |msg: String| Err(Exit(EXIT_BAD_INPUT, anyhow::anyhow!(msg)));
    if args.vertices == 0 || args.vertices as usize > input_vertices {
        return bad(format!("--vertices {}: the input has {input_vertices} vertices; use 1..={input_vertices}", args.vertices));
    }
    if !(1..=MAX_SAMPLES).contains(&args.samples) {
        return bad(format!("--samples {}: use 1..={MAX_SAMPLES}", args.samples));
    }
    if !(2..=16).contains(&args.branching) {
        return bad(format!("--branching {}: use 2..=16", args.branching));
    }
    Ok(())
}

/// A method's report from its per-frame distances and coherence shares.
fn method_report(
    method: &'static str,
    distances: &[pmcodec_eval::Distance],
    changed: Option<Vec<f64>>,
    by_nodes: Option<Vec<f64>>,
) -> MethodReport {
    let rms: Vec<f64> = distances.iter().map(|d| d.rms).collect();
    let max: Vec<f64> = distances.iter().map(|d| d.max).collect();
    let q = (rms.len() / 4).max(1);
    MethodReport {
        method,
        mean_rms: mean(&rms),
        first_quarter_rms: mean(&rms[..q.min(rms.len())]),
        last_quarter_rms: mean(&rms[rms.len().saturating_sub(q)..]),
        mean_changed_share: changed.as_ref().map(|c| mean(&c[1.min(c.len())..])),
        changed_share: changed,
        mean_changed_share_by_node_ids: by_nodes.as_ref().map(|c| mean(&c[1.min(c.len())..])),
        changed_share_by_node_ids: by_nodes,
        rms,
        max,
    }
}

/// The `container` method: the .pmc at `path`, decoded frame by frame and cut as clients cut it.
fn container_report(
    path: &std::path::Path,
    args: &EvalArgs,
    originals: &[pmcodec_mesh::TriMesh],
    sample: &pmcodec_eval::SampleOptions,
    quiet: bool,
) -> Result<MethodReport, Exit> {
    use crate::codec_cmd::container_error;
    use pmcodec_container::Decoder;
    let reader = crate::codec_cmd::open(path)?;
    let h = reader.header();
    let frames = originals.len();
    let vertices = originals.first().map_or(0, |m| m.positions.len());
    if h.vertex_count as usize != vertices || (h.frame_count as usize) < frames {
        return Err(Exit(
            crate::EXIT_BAD_INPUT,
            anyhow::anyhow!(
                "{}: {} vertices and {} frames, but the input has {vertices} vertices and {frames} frames: not an encoding of it",
                path.display(),
                h.vertex_count,
                h.frame_count
            ),
        ));
    }
    let mut d = Decoder::new(reader.borrowed(), 0).map_err(|e| container_error(e, format!("reading {}", path.display())))?;
    d.set_budget_cut(args.budget_cut.into()).map_err(|e| container_error(e, format!("reading {}", path.display())))?;
    let bar = progress(frames as u64, "container", quiet);
    let mut meshes = Vec::with_capacity(frames);
    let mut keys: Vec<Vec<[u64; 3]>> = Vec::new();
    let mut node_keys: Vec<Vec<[u64; 3]>> = Vec::new();
    for f in 0..frames {
        let at = || format!("{} frame {f}", path.display());
        d.seek(f as u32).map_err(|e| container_error(e, at()))?;
        meshes.push(d.mesh(CutTarget::Vertices(args.vertices)).map_err(|e| container_error(e, at()))?);
        if let Some(budget) = args.coherence_triangles {
            let (corners, node_of) = d.cut_clusters(CutTarget::Triangles(budget)).map_err(|e| container_error(e, at()))?;
            keys.push(pmcodec_eval::cluster_keys(&node_of, &corners));
            node_keys.push(pmcodec_eval::node_keys(&corners));
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let distances: Vec<pmcodec_eval::Distance> = originals
        .par_iter()
        .zip(&meshes)
        .map(|(orig, m)| pmcodec_eval::symmetric_relative(orig, m, sample))
        .collect::<Result<_, _>>()
        .map_err(|e| Exit(EXIT_BAD_INPUT, anyhow::Error::new(e).context(format!("measuring the cuts of {}", path.display()))))?;
    // The share of each frame's shown triangles the frame before did not show, by cluster
    // content as for every method, and by the corners' node ids (persistent within the file).
    let share = |k: &[Vec<[u64; 3]>]| pmcodec_eval::changed_share_of(&k.iter().map(Vec::as_slice).collect::<Vec<_>>());
    let changed = args.coherence_triangles.map(|_| share(&keys));
    let by_nodes = args.coherence_triangles.map(|_| share(&node_keys));
    Ok(method_report("container", &distances, changed, by_nodes))
}

fn print_table(r: &Report) {
    println!("{}: {} frames, {} vertices; distances in % of the bounding-box diagonal", r.input, r.frames, r.vertices);
    print!("{:>6}", "frame");
    for m in &r.methods {
        print!(" {:>10} {:>10}", format!("{}_rms", m.method), format!("{}_max", m.method));
    }
    println!();
    for f in 0..r.frames {
        print!("{f:>6}");
        for m in &r.methods {
            print!(" {:>10.4} {:>10.4}", m.rms[f], m.max[f]);
        }
        println!();
    }
    println!();
    for m in &r.methods {
        print!(
            "{:>8}: mean RMS {:.4}%  first quarter {:.4}%  last quarter {:.4}%",
            m.method, m.mean_rms, m.first_quarter_rms, m.last_quarter_rms
        );
        if let Some(c) = m.mean_changed_share {
            print!(
                "  changed triangles per frame at {} triangles: {:.2}% by cluster content",
                r.coherence_triangles.unwrap_or(0),
                100.0 * c
            );
            match m.mean_changed_share_by_node_ids {
                Some(n) => print!(" ({:.2}% by node ids)", 100.0 * n),
                None => print!(" (no persistent node ids)"),
            }
        }
        println!();
    }
    let find = |name: &str| r.methods.iter().find(|m| m.method == name);
    if let (Some(p), Some(d)) = (find("pmcodec"), find("direct")) {
        println!("pmcodec / direct mean RMS: {:.3}", p.mean_rms / d.mean_rms);
    }
    if let (Some(p), Some(s)) = (find("pmcodec"), find("static")) {
        println!("pmcodec below static: {:.1}%", 100.0 * (1.0 - p.mean_rms / s.mean_rms));
    }
    if let (Some(c), Some(p)) = (find("container"), find("pmcodec")) {
        println!("container / pmcodec mean RMS: {:.3} (quantization, coarse grids and the file's split order)", c.mean_rms / p.mean_rms);
    }
}
