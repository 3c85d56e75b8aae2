//! `pmcodec`: the command line over the pmcodec libraries. Each subcommand lives in its own
//! module and only parses arguments, calls a library, and reports.

mod codec_cmd;
mod decode_cmd;
mod decode_rig;
mod eval_cmd;
mod eval_sweep;
mod info_cmd;
mod input;
mod lod_cmd;
mod play_cmd;
mod serve_cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "pmcodec", version, about = "Progressive multiresolution meshes for deforming surfaces")]
struct Cli {
    /// Print nothing but errors (no progress bars, no summaries).
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Encode an OBJ sequence or an animated glTF/GLB into a .pmc container.
    Encode(codec_cmd::EncodeArgs),
    /// Decode a frame (or every frame) of a .pmc at a triangle budget, level or error bound.
    Decode(decode_cmd::DecodeArgs),
    /// Describe a .pmc: counts, levels, sizes per band, bits per vertex per frame.
    Info(info_cmd::InfoArgs),
    /// Check every checksum and replay every frame of a .pmc.
    Verify(info_cmd::VerifyArgs),
    /// Per-frame surface distance of approximations to the original frames.
    Eval(eval_cmd::EvalArgs),
    /// Serve assets (or the built-in samples) and the viewer over HTTP.
    Serve(serve_cmd::ServeArgs),
    /// Play an asset from a server through a streaming session at a triangle budget, printing
    /// per-frame triangles, bytes downloaded and decode time.
    Play(play_cmd::PlayArgs),
    /// Write a built-in sample animation as an OBJ sequence.
    Sample(SampleArgs),
    /// Deformation-aware LODs of a skinned/morph glTF, with geomorph tables, as one GLB.
    Lod(lod_cmd::LodArgs),
}

#[derive(clap::Args)]
struct SampleArgs {
    /// One of: twisting-tube, waving-cloth.
    name: String,
    /// Folder to write frame-NNNN.obj files into.
    #[arg(short, long)]
    output: std::path::PathBuf,
    /// Only the first N frames.
    #[arg(long)]
    frames: Option<usize>,
}

fn sample(args: SampleArgs) -> Result<(), Exit> {
    use anyhow::Context;
    let mut seq = pmcodec_mesh::samples::by_name(&args.name)
        .ok_or_else(|| Exit(2, anyhow::anyhow!("no sample {:?}; the samples are {:?}", args.name, pmcodec_mesh::samples::NAMES)))?;
    if let Some(n) = args.frames {
        seq.frames.truncate(n.max(1));
    }
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    for f in 0..seq.frame_count() {
        let path = args.output.join(format!("frame-{f:04}.obj"));
        let mesh = seq.frame_mesh(f).context("frame")?;
        pmcodec_mesh::write::write_mesh_file(&path, &mesh).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// Exit codes: 0 success, 1 failure of the work itself, 2 bad usage (clap's own), 3 bad input.
pub const EXIT_FAILURE: u8 = 1;
pub const EXIT_BAD_INPUT: u8 = 3;

/// An error that carries the exit code it should produce.
#[derive(Debug)]
pub struct Exit(pub u8, pub anyhow::Error);

impl<E: Into<anyhow::Error>> From<E> for Exit {
    fn from(e: E) -> Self {
        Exit(EXIT_FAILURE, e.into())
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_env("PMCODEC_LOG").unwrap_or_else(|_| {
            // The server logs every request at info; other commands stay quiet.
            let serving = matches!(cli.command, Command::Serve(_));
            tracing_subscriber::EnvFilter::new(if cli.quiet {
                "error"
            } else if serving {
                "info"
            } else {
                "warn"
            })
        }))
        .with_writer(std::io::stderr)
        // Colour codes only for a person at a terminal, not in log files and collectors.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let result = match cli.command {
        Command::Encode(args) => codec_cmd::encode_cmd(args, cli.quiet),
        Command::Play(args) => play_cmd::run(args, cli.quiet),
        Command::Decode(args) => decode_cmd::decode_cmd(args, cli.quiet),
        Command::Info(args) => info_cmd::info_cmd(args),
        Command::Verify(args) => info_cmd::verify_cmd(args, cli.quiet),
        Command::Eval(args) => eval_cmd::run(args, cli.quiet),
        Command::Serve(args) => serve_cmd::run(args, cli.quiet),
        Command::Sample(args) => sample(args),
        Command::Lod(args) => lod_cmd::run(args, cli.quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Exit(code, e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(code)
        }
    }
}

/// A progress bar that hides itself under `--quiet` or when stderr is not a terminal.
pub fn progress(len: u64, what: &str, quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>10} [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}
