//! Issue 15's encoder bar, measured in one run: the whole `pmcodec encode` process (OBJ
//! parsing, hierarchy, reclustering, container) per frame, beside one meshoptimizer
//! simplification of a frame (Kapoulkine's meshoptimizer, QEM after Garland & Heckbert 1997)
//! to 800 vertices, and the encoder's peak resident memory.
//!
//! Runs alternate (meshoptimizer over every frame, then one encode) so that both see the same
//! load on a shared machine; the medians are reported. Peak RSS is the encode process's own,
//! from `/usr/bin/time -f %M` (the maximum resident set size, in KiB).
//!
//! `cargo build --release -p pmcodec --bin pmcodec && cargo run --release -p pmcodec-eval --example encode_speed -- target/release/pmcodec INPUT [RUNS] [-- ENCODE FLAGS...]`
//!
//! Flags after `--` go to `pmcodec encode`: issue 19's bar is measured with a fitted skin,
//! `encode_speed target/release/pmcodec ../shared/data/horse-gallop 5 -- --fit-skin --quant-bits 12`
//! (the fit, its share of the process and whether the file kept it are printed from the
//! encoder's `--json`).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::{Command, ExitCode};
use std::time::Instant;

/// The vertex count meshoptimizer simplifies each frame to.
const VERTICES: usize = 800;

/// Simplifies `frame` to about `VERTICES` vertices: the index target is bisected once on frame
/// 0 (the vertex count a triangle target gives depends on the mesh) and reused for every frame.
fn simplify(frame: &[glam::Vec3], indices: &[u32], target: usize) -> Vec<u32> {
    let adapter = meshopt::VertexDataAdapter::new(meshopt::utilities::typed_to_bytes(frame), 12, 0).expect("adapter");
    meshopt::simplify(indices, &adapter, target, f32::MAX, meshopt::SimplifyOptions::empty(), None)
}

fn vertices_used(out: &[u32], n: usize) -> usize {
    let mut seen = vec![false; n];
    out.iter().for_each(|&v| seen[v as usize] = true);
    seen.iter().filter(|&&s| s).count()
}

fn index_target(frame: &[glam::Vec3], indices: &[u32]) -> (usize, usize) {
    let (mut lo, mut hi) = (3usize, indices.len());
    let mut best = (hi, frame.len());
    while hi - lo > 3 {
        let mid = (lo + hi) / 2 / 3 * 3;
        let got = vertices_used(&simplify(frame, indices, mid), frame.len());
        if got.abs_diff(VERTICES) < best.1.abs_diff(VERTICES) {
            best = (mid, got);
        }
        if got > VERTICES {
            hi = mid
        } else {
            lo = mid + 3
        }
        if got == VERTICES {
            break;
        }
    }
    best
}

/// The number after `"key": ` in the encoder's `--json` (a flat search: the keys looked for are
/// unique in it).
fn json_number(json: &str, key: &str) -> Option<f64> {
    let at = json.find(&format!("\"{key}\": "))? + key.len() + 4;
    json[at..].split([',', '\n', '}']).next()?.trim().parse().ok()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn run(args: &[String]) -> Result<(), String> {
    let (ours, flags) = match args.iter().position(|a| a == "--") {
        Some(i) => (&args[..i], &args[i + 1..]),
        None => (args, &args[args.len()..]),
    };
    let [bin, input, rest @ ..] = ours else {
        return Err("usage: encode_speed PMCODEC_BIN INPUT [RUNS] [-- ENCODE FLAGS...]".into());
    };
    let runs: usize = rest.first().map_or(Ok(3), |r| r.parse()).map_err(|_| "RUNS: a number")?;
    let seq = pmcodec_mesh::obj::load_obj_sequence(Path::new(input), 30.0).map_err(|e| format!("{input}: {e}"))?;
    let indices: Vec<u32> = seq.triangles.iter().flatten().copied().collect();
    let (target, got) = index_target(&seq.frames[0], &indices);
    let frames = seq.frame_count() as f64;
    let out = std::env::temp_dir().join(format!("encode_speed-{}.pmc", std::process::id()));
    let fitting = flags.iter().any(|f| f == "--fit-skin" || f.starts_with("--fit-skin="));
    let (mut enc_ms, mut opt_ms, mut rss, mut fit_ms) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut fit_json = String::new();
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        let mut kept = 0;
        for frame in &seq.frames {
            kept += simplify(frame, &indices, target).len();
        }
        opt_ms.push(t.elapsed().as_secs_f64() * 1e3 / frames);
        std::hint::black_box(kept);
        let t = Instant::now();
        let o = Command::new("/usr/bin/time")
            .args(["-f", "%M"])
            .arg(bin)
            .args(["encode", "-q", input, "-o"])
            .arg(&out)
            .args(flags)
            .args(if fitting { &["--json"][..] } else { &[] })
            .output()
            .map_err(|e| format!("/usr/bin/time {bin}: {e}"))?;
        enc_ms.push(t.elapsed().as_secs_f64() * 1e3 / frames);
        let err = String::from_utf8_lossy(&o.stderr);
        if !o.status.success() {
            return Err(format!("encode failed: {err}"));
        }
        let kib: f64 = err.lines().last().and_then(|l| l.trim().parse().ok()).ok_or_else(|| format!("no RSS from /usr/bin/time: {err}"))?;
        rss.push(kib / 1024.0);
        if fitting {
            fit_json = String::from_utf8_lossy(&o.stdout).into_owned();
            fit_ms.push(json_number(&fit_json, "fit_seconds").ok_or("no fit_seconds in the encoder's --json")? * 1e3 / frames);
        }
    }
    let bytes = std::fs::metadata(&out).map(|m| m.len()).unwrap_or(0);
    let _ = std::fs::remove_file(&out);
    let (e, m) = (median(&mut enc_ms), median(&mut opt_ms));
    println!(
        "{input}: {} frames, {} vertices, {} triangles; {runs} runs, medians",
        seq.frame_count(),
        seq.vertex_count(),
        seq.triangles.len()
    );
    println!("encode (whole process): {e:.2} ms/frame, peak RSS {:.1} MiB, {bytes} bytes", median(&mut rss));
    println!("meshoptimizer: {m:.2} ms/frame (one frame to {got} vertices, {} triangles)", target / 3);
    println!("encode / meshoptimizer: {:.2}x", e / m);
    if fitting {
        let f = median(&mut fit_ms);
        println!(
            "skin fit: {f:.2} ms/frame ({:.0}% of the encode), {} bones, kept: {} (last run)",
            100.0 * f / e,
            json_number(&fit_json, "bones").unwrap_or(0.0),
            fit_json.contains("\"used\": true")
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("encode_speed: {e}");
            ExitCode::from(3)
        }
    }
}
