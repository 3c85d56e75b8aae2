//! `pmcodec play`: plays an asset from a server through the client library's streaming
//! session, as a player would, and reports per frame what it cost: triangles drawn, bytes
//! downloaded so far, and the time to apply the frame's deltas and cut it.

use crate::Exit;
use anyhow::Context;
use clap::Args;
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct PlayArgs {
    /// The server's root URL, e.g. http://127.0.0.1:8080.
    pub url: String,
    /// Asset id [default: the first asset the server lists].
    #[arg(long)]
    pub asset: Option<String>,
    /// Triangle budget of the cut drawn each frame.
    #[arg(long, default_value_t = 2000)]
    pub triangles: u32,
    /// Frames to play [default: the whole sequence once].
    #[arg(long)]
    pub frames: Option<u32>,
    /// Pace playback at the asset's frame rate instead of as fast as possible.
    #[arg(long)]
    pub realtime: bool,
    /// Bearer token for servers that guard reads.
    #[arg(long, env = "PMCODEC_READ_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// One JSON object per frame, then a summary object, instead of a table.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: PlayArgs, quiet: bool) -> Result<(), Exit> {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().context("starting the async runtime")?;
    rt.block_on(play(args, quiet))
}

async fn play(args: PlayArgs, quiet: bool) -> Result<(), Exit> {
    let mut client = pmcodec_client::Client::new(&args.url).with_context(|| format!("client for {}", args.url))?;
    if let Some(t) = &args.token {
        client = client.with_token(t.clone());
    }
    let id = match args.asset {
        Some(id) => id,
        None => {
            let list = client.assets().await.with_context(|| format!("listing the assets of {}", args.url))?;
            list.first()
                .map(|a| a.id.clone())
                .ok_or_else(|| Exit(crate::EXIT_BAD_INPUT, anyhow::anyhow!("{} serves no assets", args.url)))?
        }
    };
    let mut session = client.session(&id, args.triangles).await.with_context(|| format!("opening asset {id}"))?;
    let (frame_count, file_bytes, rate) = (session.info.summary.frames, session.info.summary.bytes, session.info.summary.frame_rate);
    let frames = args.frames.unwrap_or(frame_count);
    if !quiet && !args.json {
        println!(
            "asset {id}: {frame_count} frames at {rate} fps, {file_bytes} bytes; budget {} triangles (reading levels >= {})",
            args.triangles,
            session.level()
        );
        println!("{:>6} {:>9} {:>12} {:>10}", "frame", "triangles", "downloaded", "decode ms");
    }
    let start = Instant::now();
    let mut decode_total = Duration::ZERO;
    let mut triangles_total = 0u64;
    for i in 0..frames {
        let f = i % frame_count.max(1);
        let frame = session.frame(f).await.with_context(|| format!("asset {id} frame {f}"))?;
        decode_total += frame.decode_time;
        triangles_total += frame.mesh.triangles.len() as u64;
        if args.json {
            println!(
                "{}",
                serde_json::json!({"frame": f, "triangles": frame.mesh.triangles.len(), "vertices": frame.mesh.positions.len(),
                    "bytes_downloaded": frame.bytes_downloaded, "decode_ms": frame.decode_time.as_secs_f64() * 1e3})
            );
        } else if !quiet {
            println!(
                "{f:>6} {:>9} {:>12} {:>10.3}",
                frame.mesh.triangles.len(),
                frame.bytes_downloaded,
                frame.decode_time.as_secs_f64() * 1e3
            );
        }
        if args.realtime && rate > 0.0 {
            let due = start + Duration::from_secs_f64((i + 1) as f64 / rate as f64);
            tokio::time::sleep_until(due.into()).await;
        }
    }
    let downloaded = session.bytes_downloaded();
    let share = downloaded as f64 / file_bytes.max(1) as f64;
    let mean_ms = decode_total.as_secs_f64() * 1e3 / frames.max(1) as f64;
    if args.json {
        println!(
            "{}",
            serde_json::json!({"asset": id, "frames": frames, "budget": args.triangles, "level": session.level(),
                "mean_triangles": triangles_total as f64 / frames.max(1) as f64, "bytes_downloaded": downloaded,
                "file_bytes": file_bytes, "share_of_file": share, "mean_decode_ms": mean_ms,
                "wall_seconds": start.elapsed().as_secs_f64()})
        );
    } else if !quiet {
        println!(
            "played {frames} frames in {:.2} s: {downloaded} bytes downloaded ({:.1}% of the {file_bytes}-byte file), mean decode {mean_ms:.3} ms/frame",
            start.elapsed().as_secs_f64(),
            share * 100.0
        );
    }
    Ok(())
}
