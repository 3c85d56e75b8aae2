//! `pmcodec decode`: frames of a container as meshes (OBJ or GLB), at a level, a budget or an
//! error bound, textured when the file carries an appearance.

use crate::codec_cmd::{container_error, open};
use crate::{EXIT_BAD_INPUT, Exit, progress};
use anyhow::{Context, anyhow};
use clap::Args;
use pmcodec_container::{CutTarget, Decoder, Distance, FileSource, Header};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// A budget as given: a count, or a share of the full-resolution count (`25%`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    Count(u32),
    Percent(f64),
}

/// Only the syntax is checked here (clap reports it as a usage error); the range is checked
/// against the file, as bad input.
fn parse_budget(s: &str) -> Result<Budget, String> {
    let t = s.trim();
    match t.strip_suffix('%') {
        Some(p) => p.trim().parse::<f64>().map(Budget::Percent).map_err(|_| format!("{s:?}: use a count like 2000 or a share like 25%")),
        None => t.parse::<u32>().map(Budget::Count).map_err(|_| format!("{s:?}: use a count like 2000 or a share like 25%")),
    }
}

impl Budget {
    /// The count this budget allows out of `total` (rounded down: a budget is a maximum).
    fn resolve(self, flag: &str, total: u32) -> Result<u32, Exit> {
        match self {
            Budget::Count(n) => Ok(n),
            Budget::Percent(p) if p.is_finite() && p > 0.0 && p <= 100.0 => Ok((total as f64 * p / 100.0).floor() as u32),
            Budget::Percent(p) => Err(Exit(EXIT_BAD_INPUT, anyhow!("{flag} {p}%: a share must be more than 0% and at most 100%"))),
        }
    }
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
    /// At most this many triangles, or this share of the full-resolution triangles (25%). Where
    /// the coarsest cut has more, it is written with a warning (unless --quiet).
    #[arg(long, value_parser = parse_budget, value_name = "N|P%")]
    pub triangles: Option<Budget>,
    /// At most this many vertices, or this share of the input vertices (25%); as --triangles.
    #[arg(long, value_parser = parse_budget, value_name = "N|P%")]
    pub vertices: Option<Budget>,
    /// A whole level (0 = the input mesh, every input vertex in input order).
    #[arg(long)]
    pub level: Option<usize>,
    /// Refine every node whose error bound exceeds this fraction of the bounding-box diagonal
    /// (a finite number >= 0).
    #[arg(long, allow_hyphen_values = true)]
    pub max_error: Option<f64>,
    /// How --triangles and --vertices budgets are cut (proto/container.md, "Cuts", "Partial
    /// splits"): the spec's whole splits, or partial splits.
    #[arg(long, value_enum, default_value_t = crate::eval_cmd::BudgetCutArg::Whole)]
    pub budget_cut: crate::eval_cmd::BudgetCutArg,
    /// Output: .glb or .obj (a folder with --all-frames).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print what was written as JSON on stdout (per frame: vertices, triangles, and whether
    /// the coarsest cut exceeded the budget).
    #[arg(long)]
    pub json: bool,
    /// Write the file's skin as a skinned GLB to -o (.glb): the input's vertices at their bind
    /// positions with their influences, every frame's bone transforms as an animation (files
    /// with a skin: a glTF's, or one fitted by `encode --fit-skin --keep-skin`). Motion the skin
    /// does not explain is left out; --json says how much.
    #[arg(long, conflicts_with_all = ["all_frames", "frame", "triangles", "vertices", "level", "max_error"])]
    pub skinned_glb: bool,
}

/// What one decoded frame holds, for the summary and `--json`.
#[derive(Serialize)]
struct DecodedFrame {
    frame: u32,
    path: String,
    vertices: usize,
    triangles: usize,
    /// The budget asked for, when the coarsest cut the file holds exceeds it.
    over_budget: Option<OverBudget>,
}

#[derive(Clone, Copy, Serialize)]
struct OverBudget {
    /// `triangles` or `vertices`.
    of: &'static str,
    asked: u32,
    got: usize,
}

/// The decode target, checked against the file: every value out of range is bad input naming
/// the value and the range, as the server answers 400.
fn decode_target(args: &DecodeArgs, h: &Header) -> Result<CutTarget, Exit> {
    let bad = |e| Exit(EXIT_BAD_INPUT, e);
    Ok(match (args.triangles, args.vertices, args.level, args.max_error) {
        (Some(b), ..) => CutTarget::Triangles(b.resolve("--triangles", h.triangle_count)?),
        (_, Some(b), ..) => CutTarget::Vertices(b.resolve("--vertices", h.vertex_count)?),
        (_, _, Some(l), _) if l < h.levels() => CutTarget::Level(l),
        (_, _, Some(l), _) => return Err(bad(anyhow!("--level {l}: the file has levels 0..={}", h.top()))),
        (.., Some(e)) if e.is_finite() && e >= 0.0 => CutTarget::MaxError(Distance::DiagonalFraction(e)),
        (.., Some(e)) => return Err(bad(anyhow!("--max-error {e}: use a finite number >= 0"))),
        _ => CutTarget::Level(0),
    })
}

/// The budget a cut exceeds, if any: the coarsest cut of a frame can hold more than a small
/// budget allows (a mesh of many parts keeps a triangle or more per part).
fn over_budget(target: CutTarget, mesh: &pmcodec_mesh::TriMesh) -> Option<OverBudget> {
    match target {
        CutTarget::Triangles(n) if mesh.triangles.len() > n as usize => {
            Some(OverBudget { of: "triangles", asked: n, got: mesh.triangles.len() })
        }
        CutTarget::Vertices(n) if mesh.positions.len() > n as usize => {
            Some(OverBudget { of: "vertices", asked: n, got: mesh.positions.len() })
        }
        _ => None,
    }
}

/// Writes one frame's mesh and says what it holds.
fn write_frame(dec: &mut Decoder<&FileSource>, input: &Path, frame: u32, target: CutTarget, path: &Path) -> Result<DecodedFrame, Exit> {
    let where_ = || format!("{} frame {frame}", input.display());
    dec.seek(frame).map_err(|e| container_error(e, where_()))?;
    let mesh = if dec.appearance_info().is_some() {
        let (wedged, app) = dec.textured_mesh(target).map_err(|e| container_error(e, where_()))?;
        // An OBJ indexes positions and attributes apart: its `v` lines are the cut's nodes (at
        // level 0 the input's vertices, in their order), as in an untextured decode.
        let plain = dec.mesh(target).map_err(|e| container_error(e, where_()))?;
        write_textured(path, &plain, &wedged, &app).with_context(|| format!("writing {}", path.display()))?;
        plain
    } else {
        let mesh = dec.mesh(target).map_err(|e| container_error(e, where_()))?;
        pmcodec_mesh::write::write_mesh_file(path, &mesh).with_context(|| format!("writing {}", path.display()))?;
        mesh
    };
    Ok(DecodedFrame {
        frame,
        path: path.display().to_string(),
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        over_budget: over_budget(target, &mesh),
    })
}

/// A cut with its appearance: a textured GLB, or an OBJ with its MTL (`NAME.mtl`) and the
/// images beside it (`texture-*`, shared by the frames of a folder). `plain` is the cut's mesh
/// by node, `mesh` the same triangles with one vertex per wedge. Every file is written whole or
/// not at all; on an error the ones already written are removed.
fn write_textured(
    path: &Path,
    plain: &pmcodec_mesh::TriMesh,
    mesh: &pmcodec_mesh::TriMesh,
    app: &pmcodec_mesh::Appearance,
) -> anyhow::Result<()> {
    use pmcodec_container::appearance::export;
    use pmcodec_mesh::write::write_atomic;
    let is_obj = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if !is_obj {
        return Ok(write_atomic(path, &export::textured_glb(mesh, app)?)?);
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "mesh".into());
    let mtl_name = format!("{stem}.mtl");
    let (obj, mtl) = export::textured_obj(plain, &mesh.triangles, app, &mtl_name, "texture")?;
    let mut files: Vec<(std::path::PathBuf, Vec<u8>)> =
        (0..app.images.len()).map(|i| (dir.join(export::image_file_name(app, i, "texture")), app.images[i].bytes.clone())).collect();
    files.push((dir.join(&mtl_name), mtl.into_bytes()));
    files.push((path.to_path_buf(), obj.into_bytes()));
    let mut written = Vec::new();
    for (p, bytes) in &files {
        if let Err(e) = write_atomic(p, bytes) {
            for w in &written {
                let _ = std::fs::remove_file(w);
            }
            return Err(e.into());
        }
        written.push(p.clone());
    }
    Ok(())
}

pub fn decode_cmd(args: DecodeArgs, quiet: bool) -> Result<(), Exit> {
    // The output's format is known before anything is decoded: a wrong name is a usage error.
    if !args.all_frames {
        let ext = args.output.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        if !matches!(ext.as_deref(), Some("glb" | "obj")) {
            return Err(Exit(2, anyhow!("-o {}: name a .glb or .obj file (or a folder with --all-frames)", args.output.display())));
        }
    }
    let reader = open(&args.input)?;
    let h = reader.header();
    if args.skinned_glb {
        if !args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb")) {
            return Err(Exit(2, anyhow!("--skinned-glb -o {}: name a .glb file", args.output.display())));
        }
        let mut dec = Decoder::new(reader.borrowed(), 0).map_err(|e| container_error(e, format!("reading {}", args.input.display())))?;
        let out = crate::decode_rig::decode_rig(&mut dec, &args.input, &args.output, quiet)?;
        if args.json {
            println!("{}", serde_json::to_string_pretty(&out).context("writing JSON")?);
        } else if !quiet {
            eprintln!(
                "{}: {} vertices, {} bones, {} frames; the rig misses the decoded frames by {:.4}% of the diagonal (RMS), {:.4}% at most",
                out.path,
                out.vertices,
                out.bones,
                out.frames,
                out.rms_error * 100.0,
                out.max_error * 100.0
            );
        }
        return Ok(());
    }
    let target = decode_target(&args, h)?;
    if !args.all_frames && args.frame >= h.frame_count {
        return Err(Exit(
            EXIT_BAD_INPUT,
            anyhow!(
                "--frame {}: {} has {} frames (0..={})",
                args.frame,
                args.input.display(),
                h.frame_count,
                h.frame_count.saturating_sub(1)
            ),
        ));
    }
    // A level-limited decode reads only the bands it needs.
    let min_level = match target {
        CutTarget::Level(l) => l,
        _ => 0,
    };
    let mut dec =
        Decoder::new(reader.borrowed(), min_level).map_err(|e| container_error(e, format!("reading {}", args.input.display())))?;
    dec.set_budget_cut(args.budget_cut.into()).map_err(|e| container_error(e, format!("reading {}", args.input.display())))?;
    let written = if args.all_frames {
        decode_all(&mut dec, &args, target, quiet)?
    } else {
        vec![write_frame(&mut dec, &args.input, args.frame, target, &args.output)?]
    };
    // A budget is "at most": say so where the coarsest cut could not keep it (unless --quiet;
    // --json says it too).
    let over: Vec<(u32, OverBudget)> = written.iter().filter_map(|w| w.over_budget.map(|o| (w.frame, o))).collect();
    match over.as_slice() {
        _ if quiet => {}
        [] => {}
        [(f, o)] => eprintln!(
            "warning: frame {f}: the coarsest cut the file holds has {} {}, more than the {} asked for; wrote it",
            o.got, o.of, o.asked
        ),
        [(_, o), ..] => eprintln!(
            "warning: {} frames: their coarsest cuts hold more than the {} {} asked for (up to {}); wrote them",
            over.len(),
            o.asked,
            o.of,
            over.iter().map(|(_, o)| o.got).max().unwrap_or(o.got)
        ),
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&written).context("writing JSON")?);
    } else if !quiet && !args.all_frames {
        for w in &written {
            eprintln!("{}: frame {}, {} vertices, {} triangles", w.path, w.frame, w.vertices, w.triangles);
        }
    }
    Ok(())
}

/// Every frame into the output folder; on any error the files written so far (and the folder,
/// when this created it) are removed, so a failed decode leaves nothing behind.
fn decode_all(dec: &mut Decoder<&FileSource>, args: &DecodeArgs, target: CutTarget, quiet: bool) -> Result<Vec<DecodedFrame>, Exit> {
    let created = !args.output.exists();
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let frames = dec.reader().header().frame_count;
    let width = frames.to_string().len().max(4);
    let bar = progress(frames as u64, "decode", quiet);
    let mut written = Vec::with_capacity(frames as usize);
    for f in 0..frames {
        let path = args.output.join(format!("frame-{f:0width$}.obj"));
        match write_frame(dec, &args.input, f, target, &path) {
            Ok(w) => written.push(w),
            Err(e) => {
                bar.finish_and_clear();
                for w in &written {
                    let _ = std::fs::remove_file(&w.path);
                }
                if created {
                    let _ = std::fs::remove_dir(&args.output);
                }
                return Err(e);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(written)
}
