//! `pmcodec eval --sweep`: quality at every budget (issue 15). At N vertex budgets log-spaced
//! from 1% to 50% of the input's vertices, and at the container's levels in that range, the
//! container's cut as a client gets it (each frame
//! decoded and cut by the file's split order, so budgets between levels are partial cuts)
//! beside *direct* (plain QEM of every frame, Garland & Heckbert 1997) and *first-frame static*
//! (Kircher & Garland figure 11's baselines), each with its mean RMS, the ratios, and drift
//! (last quarter of the measured frames against the first). Budgets at which some method's cut
//! has no triangles (a mesh of many small parts collapses them to points) are left out and named.

use crate::eval_cmd::EvalArgs;
use crate::{EXIT_BAD_INPUT, Exit, progress};
use anyhow::Context;
use clap::Parser;
use pmcodec_eval::plot::{Plot, Reference, Series};
use pmcodec_eval::{ApproxOptions, Method, SampleOptions, SurfaceIndex};
use pmcodec_hierarchy::CutTarget;
use pmcodec_mesh::{Sequence, TriMesh};
use rayon::prelude::*;
use serde::Serialize;

/// The fewest vertices a budget of the sweep asks for: below this a level is a handful of
/// vertices and its distance says nothing about the method.
const MIN_BUDGET: u32 = 8;

/// `n` budgets log-spaced from 1% to 50% of `vertices` (at least [`MIN_BUDGET`]), increasing
/// and distinct; fewer than `n` when a small mesh rounds two to one count.
pub fn budgets(vertices: u32, n: usize) -> Vec<u32> {
    let mut out: Vec<u32> = (0..n)
        .map(|i| {
            let t = if n > 1 { i as f64 / (n - 1) as f64 } else { 1.0 };
            let share = 0.01 * 50f64.powf(t);
            ((vertices as f64 * share).round() as u32).max(MIN_BUDGET).min(vertices)
        })
        .collect();
    out.dedup();
    out
}

/// `k` frames of `frames` spread evenly, always frame 0 and the last: drift compares the start
/// of the sequence with its end, not with its first few frames.
pub fn spread_frames(frames: usize, k: usize) -> Vec<usize> {
    if frames == 0 {
        return Vec::new();
    }
    if k >= frames {
        return (0..frames).collect();
    }
    let mut out: Vec<usize> =
        (0..k.max(1)).map(|i| if k > 1 { (i as f64 * (frames - 1) as f64 / (k - 1) as f64).round() as usize } else { 0 }).collect();
    out.dedup();
    out
}

#[derive(Serialize, Clone, Copy, Default)]
struct Cell {
    mean_rms: f64,
    first_quarter_rms: f64,
    last_quarter_rms: f64,
    frame0_rms: f64,
}

#[derive(Serialize)]
struct Row {
    /// Percent of the input's vertices.
    budget_percent: f64,
    vertices: u32,
    /// The container level of exactly this many nodes, if the budget is one (levels within the
    /// swept range are measured besides the N budgets: the frame-0 bar is at each level).
    level: Option<usize>,
    /// Whether this is one of the N swept budgets (a level can be one too).
    swept: bool,
    container: Cell,
    direct: Cell,
    #[serde(rename = "static")]
    static_: Cell,
    container_over_direct: f64,
    container_over_static: f64,
    static_over_direct: f64,
    /// Frame 0 alone: the container's cut over plain QEM of frame 0.
    frame0_container_over_direct: f64,
    /// The container's last-quarter mean over its first-quarter mean.
    container_drift: f64,
}

#[derive(Serialize)]
struct SweepReport {
    input: String,
    vertices: usize,
    frames_measured: Vec<usize>,
    rows: Vec<Row>,
    /// Budgets (vertices) left out: some approximation there has no triangles.
    left_out: Vec<u32>,
    worst_container_over_direct: f64,
    worst_container_over_static: f64,
    worst_frame0_container_over_direct: f64,
    /// Frame 0 alone at the container's levels (the bar: within 1.05x of plain QEM).
    worst_frame0_at_levels: f64,
    worst_container_drift: f64,
}

fn cell(rms: &[f64]) -> Cell {
    let mean = |x: &[f64]| if x.is_empty() { 0.0 } else { x.iter().sum::<f64>() / x.len() as f64 };
    let q = (rms.len() / 4).max(1).min(rms.len());
    Cell {
        mean_rms: mean(rms),
        first_quarter_rms: mean(&rms[..q]),
        last_quarter_rms: mean(&rms[rms.len() - q..]),
        frame0_rms: rms.first().copied().unwrap_or(0.0),
    }
}

/// `encode`'s flags at their defaults: the in-memory container is what `pmcodec encode IN -o
/// OUT` writes.
#[derive(Parser)]
struct DefaultEncode {
    #[command(flatten)]
    args: crate::codec_cmd::EncodeArgs,
}

/// The container's bytes: the file of `--pmc`, or the sequence encoded in memory with
/// `encode`'s defaults (and this command's branching and reclustering flags).
fn container_bytes(args: &EvalArgs, seq: &Sequence, quiet: bool) -> Result<Vec<u8>, Exit> {
    if let Some(path) = &args.pmc {
        return std::fs::read(path).with_context(|| format!("reading {}", path.display())).map_err(|e| Exit(EXIT_BAD_INPUT, e));
    }
    let parsed = DefaultEncode::try_parse_from([std::ffi::OsStr::new("encode"), args.input.as_os_str(), "-o".as_ref(), "-".as_ref()])
        .map_err(|e| Exit(2, anyhow::anyhow!("encode's default flags: {e}")))?;
    let mut opts = crate::codec_cmd::encode_options(&parsed.args)?;
    opts.build.branching = args.branching;
    opts.recluster = args.recluster.options()?;
    let bar = progress(seq.frame_count() as u64, "encode", quiet);
    let bytes = pmcodec_container::encode(seq, &opts, |_| bar.inc(1))
        .map_err(|e| crate::codec_cmd::container_error(e, format!("encoding {}", args.input.display())))?;
    bar.finish_and_clear();
    Ok(bytes)
}

/// The container's level sizes, finest first (empty if the bytes are no container: reading them
/// again reports that).
fn container_levels(bytes: &[u8]) -> Vec<u32> {
    pmcodec_container::Reader::open(bytes).map(|r| r.header().level_sizes.clone()).unwrap_or_default()
}

/// The container's cuts, `out[i][j]` = frame `frames[i]` at `sizes[j]` vertices, as a client
/// decodes them.
fn container_meshes(args: &EvalArgs, bytes: &[u8], seq: &Sequence, frames: &[usize], sizes: &[u32]) -> Result<Vec<Vec<TriMesh>>, Exit> {
    use crate::codec_cmd::container_error;
    let name = args.pmc.as_ref().map_or_else(|| "the encoded container".to_string(), |p| p.display().to_string());
    let reader = pmcodec_container::Reader::open(bytes).map_err(|e| container_error(e, format!("reading {name}")))?;
    let h = reader.header();
    if h.vertex_count as usize != seq.vertex_count() || (h.frame_count as usize) < seq.frame_count() {
        return Err(Exit(
            EXIT_BAD_INPUT,
            anyhow::anyhow!(
                "{name}: {} vertices and {} frames, but the input has {} vertices and {} frames: not an encoding of it",
                h.vertex_count,
                h.frame_count,
                seq.vertex_count(),
                seq.frame_count()
            ),
        ));
    }
    let mut d = pmcodec_container::Decoder::new(reader, 0).map_err(|e| container_error(e, format!("reading {name}")))?;
    d.set_budget_cut(args.budget_cut.into()).map_err(|e| container_error(e, format!("reading {name}")))?;
    let mut out = Vec::with_capacity(frames.len());
    for &f in frames {
        let at = || format!("{name} frame {f}");
        d.seek(f as u32).map_err(|e| container_error(e, at()))?;
        let row =
            sizes.iter().map(|&n| d.mesh(CutTarget::Vertices(n))).collect::<Result<Vec<_>, _>>().map_err(|e| container_error(e, at()))?;
        out.push(row);
    }
    Ok(out)
}

/// Approximations of the measured frames at the sweep's budgets, `[frame][budget]`.
type Cuts = Vec<Vec<TriMesh>>;

/// The budgets at which every method's approximation of every measured frame has a surface,
/// and the approximations at those budgets (`[frame][budget]`). A mesh of many small parts
/// (RobotExpressive: 19) collapses each part to a point before a sweep's 1%, so its coarsest
/// cuts have no triangles and no distance to measure: those budgets are left out with a
/// warning naming them, rather than failing the sweep; none left is an error.
fn drop_surfaceless(sizes: &[u32], container: Cuts, methods: &mut [Cuts], quiet: bool) -> Result<(Vec<u32>, Cuts, Vec<u32>), Exit> {
    let all = std::iter::once(&container).chain(methods.iter());
    let keep: Vec<bool> =
        (0..sizes.len()).map(|j| all.clone().all(|m| m.iter().all(|row| row.get(j).is_some_and(|t| !t.triangles.is_empty())))).collect();
    let dropped: Vec<u32> = sizes.iter().zip(&keep).filter(|(_, k)| !**k).map(|(&s, _)| s).collect();
    if dropped.len() == sizes.len() {
        return Err(Exit(
            EXIT_BAD_INPUT,
            anyhow::anyhow!("no budget of the sweep ({sizes:?} vertices) has a surface to measure in every method"),
        ));
    }
    if !dropped.is_empty() && !quiet {
        eprintln!(
            "warning: budgets of {dropped:?} vertices left out: some approximation there has no triangles (parts collapsed to points)"
        );
    }
    let filter = |rows: Cuts| -> Cuts {
        rows.into_iter().map(|row| row.into_iter().zip(&keep).filter(|(_, k)| **k).map(|(m, _)| m).collect()).collect()
    };
    for m in methods.iter_mut() {
        *m = filter(std::mem::take(m));
    }
    let kept = sizes.iter().zip(&keep).filter(|(_, k)| **k).map(|(&s, _)| s).collect();
    Ok((kept, filter(container), dropped))
}

/// Per budget, per measured frame: the relative symmetric RMS of each approximation against the
/// original frame (the original's surface index built once per frame). `out[j][i]`.
fn distances(
    originals: &[(TriMesh, SurfaceIndex)],
    approx: &[Vec<TriMesh>],
    sample: &SampleOptions,
    what: &str,
) -> Result<Vec<Vec<f64>>, Exit> {
    let budgets = approx.first().map_or(0, Vec::len);
    let per_frame: Vec<Vec<f64>> = originals
        .iter()
        .zip(approx)
        .map(|((orig, index), row)| {
            row.par_iter()
                .map(|m| pmcodec_eval::symmetric_relative_indexed(orig, index, m, sample).map(|d| d.rms))
                .collect::<Result<Vec<f64>, _>>()
        })
        .collect::<Result<_, _>>()
        .map_err(|e| Exit(EXIT_BAD_INPUT, anyhow::Error::new(e).context(format!("measuring the {what} approximations"))))?;
    Ok((0..budgets).map(|j| per_frame.iter().map(|r| r[j]).collect()).collect())
}

pub fn run(args: &EvalArgs, n: usize, quiet: bool) -> Result<(), Exit> {
    if !(2..=64).contains(&n) {
        return Err(Exit(EXIT_BAD_INPUT, anyhow::anyhow!("--sweep {n}: use 2..=64 budgets")));
    }
    let seq = crate::input::load(&args.input, &args.input_args)?;
    let vertices = seq.vertex_count();
    let swept = budgets(vertices as u32, n);
    let frames = spread_frames(seq.frame_count(), args.frames.unwrap_or(usize::MAX));
    let sample = SampleOptions { samples: args.samples, ..Default::default() };
    let opts = ApproxOptions { branching: args.branching, recluster: args.recluster.options()?, ..Default::default() };

    let bytes = container_bytes(args, &seq, quiet)?;
    let levels = container_levels(&bytes);
    let mut sizes = swept.clone();
    let (lo, hi) = (sizes.first().copied().unwrap_or(0), sizes.last().copied().unwrap_or(0));
    sizes.extend(levels.iter().copied().filter(|&l| l >= lo && l <= hi));
    sizes.sort_unstable();
    sizes.dedup();
    let container = container_meshes(args, &bytes, &seq, &frames, &sizes)?;
    drop(bytes);
    let mut by_method = Vec::new();
    for method in [Method::Direct, Method::FirstFrameStatic] {
        let bar = progress(frames.len() as u64, method.name(), quiet);
        let m = pmcodec_eval::approximate_sizes(&seq, &frames, &sizes, method, &opts, |_| bar.inc(1))
            .with_context(|| format!("building the {} approximations", method.name()))?;
        bar.finish_and_clear();
        by_method.push(m);
    }
    let (sizes, container, left_out) = drop_surfaceless(&sizes, container, &mut by_method, quiet)?;
    let originals: Vec<(TriMesh, SurfaceIndex)> = frames
        .iter()
        .filter_map(|&f| seq.frame_mesh(f))
        .map(|m| SurfaceIndex::new(&m).map(|i| (m, i)))
        .collect::<Result<_, _>>()
        .map_err(|e| Exit(EXIT_BAD_INPUT, anyhow::Error::new(e).context("indexing the input frames")))?;
    let bar = progress(3, "measure", quiet);
    let c = distances(&originals, &container, &sample, "container")?;
    bar.inc(1);
    let d = distances(&originals, &by_method[0], &sample, "direct")?;
    bar.inc(1);
    let s = distances(&originals, &by_method[1], &sample, "static")?;
    bar.finish_and_clear();

    let rows: Vec<Row> = sizes
        .iter()
        .enumerate()
        .map(|(j, &v)| {
            let (container, direct, static_) = (cell(&c[j]), cell(&d[j]), cell(&s[j]));
            Row {
                budget_percent: 100.0 * v as f64 / vertices as f64,
                vertices: v,
                level: levels.iter().position(|&l| l == v),
                swept: swept.contains(&v),
                container_over_direct: container.mean_rms / direct.mean_rms,
                container_over_static: container.mean_rms / static_.mean_rms,
                static_over_direct: static_.mean_rms / direct.mean_rms,
                frame0_container_over_direct: container.frame0_rms / direct.frame0_rms,
                container_drift: container.last_quarter_rms / container.first_quarter_rms,
                container,
                direct,
                static_,
            }
        })
        .collect();
    let worst = |f: fn(&Row) -> f64| rows.iter().map(f).fold(f64::NAN, f64::max);
    let report = SweepReport {
        input: args.input.display().to_string(),
        vertices,
        frames_measured: frames,
        left_out,
        worst_container_over_direct: worst(|r| r.container_over_direct),
        worst_container_over_static: worst(|r| r.container_over_static),
        worst_frame0_container_over_direct: worst(|r| r.frame0_container_over_direct),
        worst_container_drift: worst(|r| r.container_drift),
        worst_frame0_at_levels: rows.iter().filter(|r| r.level.is_some()).map(|r| r.frame0_container_over_direct).fold(f64::NAN, f64::max),
        rows,
    };
    if let Some(path) = &args.plot {
        let png = pmcodec_eval::plot::render_png(&plot_of(&report)).context("drawing the plot")?;
        pmcodec_container::write_file(path, &png).with_context(|| format!("writing {}", path.display()))?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report).context("writing JSON")?);
    } else {
        print_sweep(&report);
    }
    Ok(())
}

fn plot_of(r: &SweepReport) -> Plot {
    let name = std::path::Path::new(&r.input).file_name().map_or_else(|| r.input.clone(), |n| n.to_string_lossy().into_owned());
    let curve = |label: &str, color, f: fn(&Row) -> f64| Series {
        label: label.into(),
        color,
        points: r.rows.iter().map(|row| (row.budget_percent, f(row))).collect(),
    };
    Plot {
        title: format!("{name}: {} vertices, {} frames measured", r.vertices, r.frames_measured.len()),
        x_label: "budget (% of the input vertices)".into(),
        y_label: "mean rms / direct".into(),
        series: vec![
            curve("container / direct", [200, 40, 40], |row| row.container_over_direct),
            curve("static / direct", [40, 90, 200], |row| row.static_over_direct),
            curve("container / direct, frame 0", [230, 150, 30], |row| row.frame0_container_over_direct),
        ],
        references: vec![
            Reference { y: 1.0, label: "direct".into(), color: [90, 90, 90] },
            Reference { y: 1.15, label: "bar 1.15".into(), color: [150, 0, 150] },
        ],
    }
}

fn print_sweep(r: &SweepReport) {
    println!(
        "{}: {} vertices, frames {:?}; mean RMS in % of the bounding-box diagonal; c = container's cut, d = direct, s = static",
        r.input, r.vertices, r.frames_measured
    );
    println!(
        "{:>7} {:>8} {:>5} {:>10} {:>10} {:>10} {:>7} {:>7} {:>7} {:>9} {:>9}",
        "budget", "vertices", "level", "container", "direct", "static", "c/d", "c/s", "s/d", "f0 c/d", "c drift"
    );
    for row in &r.rows {
        println!(
            "{:>6.2}% {:>8} {:>5} {:>10.4} {:>10.4} {:>10.4} {:>7.3} {:>7.3} {:>7.3} {:>9.3} {:>9.3}",
            row.budget_percent,
            row.vertices,
            row.level.map_or_else(String::new, |l| format!("L{l}")),
            row.container.mean_rms,
            row.direct.mean_rms,
            row.static_.mean_rms,
            row.container_over_direct,
            row.container_over_static,
            row.static_over_direct,
            row.frame0_container_over_direct,
            row.container_drift
        );
    }
    println!(
        "worst: container/direct {:.3} (bar 1.15), container/static {:.3} (bar < 1), frame 0 container/direct {:.3} (at the levels {:.3}, bar 1.05), drift {:.3} (bar 1.10)",
        r.worst_container_over_direct,
        r.worst_container_over_static,
        r.worst_frame0_container_over_direct,
        r.worst_frame0_at_levels,
        r.worst_container_drift
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_are_log_spaced_and_distinct() {
        let b = budgets(100_000, 12);
        assert_eq!(b.len(), 12);
        assert_eq!((b[0], b[11]), (1000, 50_000));
        assert!(b.windows(2).all(|w| w[1] > w[0]));
        // A small mesh: the floor and rounding merge budgets.
        let small = budgets(100, 12);
        assert!(small.len() < 12 && small[0] == MIN_BUDGET && *small.last().unwrap_or(&0) == 50, "{small:?}");
    }

    #[test]
    fn frames_spread_to_the_end() {
        assert_eq!(spread_frames(48, 4), vec![0, 16, 31, 47]);
        assert_eq!(spread_frames(3, 10), vec![0, 1, 2]);
        assert_eq!(spread_frames(10, 1), vec![0]);
    }
}
