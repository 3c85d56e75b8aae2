//! `pmcodec play`: plays an asset from a server through the client library's streaming
//! session, as a player would, and reports per frame what it cost: triangles drawn, bytes
//! downloaded so far, and the time to apply the frame's deltas and cut it.

use crate::Exit;
use anyhow::Context;
use clap::Args;
use pmcodec_client::ClientError;
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
    let mut client = pmcodec_client::Client::new(&args.url).map_err(|e| client_error(e, format!("client for {}", args.url)))?;
    if let Some(t) = &args.token {
        client = client.with_token(t.clone());
    }
    let id = match args.asset {
        Some(id) => id,
        None => {
            let list = client.assets().await.map_err(|e| client_error(e, format!("listing the assets of {}", args.url)))?;
            list.first()
                .map(|a| a.id.clone())
                .ok_or_else(|| Exit(crate::EXIT_BAD_INPUT, anyhow::anyhow!("{} serves no assets", args.url)))?
        }
    };
    let mut session = client.session(&id, args.triangles).await.map_err(|e| client_error(e, format!("opening asset {id}")))?;
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
    let pace = match args.realtime {
        true => {
            let (pace, warning) = pacing_rate(rate).map_err(|e| Exit(crate::EXIT_BAD_INPUT, anyhow::anyhow!("asset {id}: {e}")))?;
            if let Some(w) = warning.filter(|_| !quiet) {
                eprintln!("warning: asset {id}: {w}");
            }
            Some(pace)
        }
        false => None,
    };
    let start = Instant::now();
    let mut decode_total = Duration::ZERO;
    let mut triangles_total = 0u64;
    for i in 0..frames {
        let f = i % frame_count.max(1);
        let frame = session.frame(f).await.map_err(|e| client_error(e, format!("asset {id} frame {f}")))?;
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
        if let Some(due) = pace.and_then(|rate| start.checked_add(frame_due(i, rate))) {
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

/// A client error with its exit code: what the server answered or sent is bad input (an
/// unknown asset, a refused token, a damaged container, a URL that is not one); a server
/// that fails or cannot be reached is a failure.
fn client_error(e: ClientError, what: String) -> Exit {
    let code = match &e {
        ClientError::Status { status, .. } if (400..500).contains(status) => crate::EXIT_BAD_INPUT,
        ClientError::Http(h) if h.is_builder() => crate::EXIT_BAD_INPUT,
        ClientError::Container(c) => crate::codec_cmd::container_exit(c),
        ClientError::Protocol(_) => crate::EXIT_BAD_INPUT,
        _ => crate::EXIT_FAILURE,
    };
    // Flattened: the library's messages include their sources already.
    Exit(code, anyhow::Error::msg(e.to_string()).context(what))
}

/// The slowest and fastest frame rates `--realtime` paces at: a frame every 100 s at most, a
/// thousand a second at most (no display shows more).
const MIN_PACE_FPS: f64 = 0.01;
const MAX_PACE_FPS: f64 = 1000.0;

/// The rate to pace playback at for the frame rate a server reports: a rate that is not a
/// positive number cannot be paced at (an error); one outside [`MIN_PACE_FPS`],
/// [`MAX_PACE_FPS`] is clamped into it, with a warning to show. The rate comes from the
/// server, so anything is possible (`1e-30` once made the frame time overflow a `Duration`).
fn pacing_rate(rate: f32) -> Result<(f64, Option<String>), String> {
    let r = rate as f64;
    if !(r.is_finite() && r > 0.0) {
        return Err(format!("the server reports {rate:?} frames per second; --realtime needs a positive frame rate"));
    }
    let clamped = r.clamp(MIN_PACE_FPS, MAX_PACE_FPS);
    let warning = (clamped != r).then(|| format!("the server reports {rate:?} frames per second; pacing at {clamped} instead"));
    Ok((clamped, warning))
}

/// When frame `i` (0-based) is due after the start: the end of its frame time. Saturates
/// rather than panics for a rate that was not checked by [`pacing_rate`].
fn frame_due(i: u32, rate: f64) -> Duration {
    Duration::try_from_secs_f64((i as f64 + 1.0) / rate).unwrap_or(Duration::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_frame_rates_are_refused_or_clamped() {
        // The rate that once panicked: clamped to a frame every 100 s, with a warning.
        let (r, w) = pacing_rate(1e-30).unwrap();
        assert_eq!(r, MIN_PACE_FPS);
        assert!(w.is_some_and(|w| w.contains("1e-30")));
        assert_eq!(frame_due(0, r), Duration::from_secs(100));
        let (r, w) = pacing_rate(1e9).unwrap();
        assert_eq!((r, w.is_some()), (MAX_PACE_FPS, true));
        assert_eq!(frame_due(999, r), Duration::from_secs(1));
        for bad in [0.0, -30.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let e = pacing_rate(bad).unwrap_err();
            assert!(e.contains("positive frame rate"), "{bad}: {e}");
        }
        // Sane rates pass through untouched, and frame times are exact.
        assert_eq!(pacing_rate(30.0).unwrap(), (30.0, None));
        assert_eq!(frame_due(29, 30.0), Duration::from_secs(1));
        // The conversion itself never panics, whatever it is given.
        for rate in [0.0, 1e-300, f64::MIN_POSITIVE, -1.0, f64::NAN] {
            let _ = frame_due(u32::MAX, rate);
        }
    }
}
