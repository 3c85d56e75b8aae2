//! Issue 19: does `skin_trial` (band 0 coded both ways on a sample of keyframe intervals,
//! before the encode) keep or drop a fitted skin as the exhaustive choice does (the file
//! encoded with the skin, without it, and with every joint at every level, the smallest kept)?
//! Per input: the fit's and the trial's time, the trial's bytes, the three files' sizes, both
//! choices. Inputs: OBJ folders, or the generated sequences `tube` (twisting tube), `cloth`
//! (waving cloth), `parts` (rigid parts), `bend` (bending tube), `wave` (a larger, slower
//! cloth).
//! `cargo run --release -p pmcodec-container --example skin_choice -- ../shared/data/horse-gallop ../shared/data/samba-60 ../shared/data/cat-poses tube cloth parts bend wave [BITS]`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{EncodeOptions, QuantizationChoice, SkinnedCoarse, encode, skin_trial};
use pmcodec_mesh::skin_fit::{FitOptions, fit_skin};
use pmcodec_mesh::{Sequence, samples};
use std::path::Path;
use std::time::Instant;

fn input(name: &str) -> Sequence {
    match name {
        "tube" => samples::twisting_tube(24, 48, 48),
        "cloth" => samples::waving_cloth(60, 40, 48),
        "parts" => samples::rigid_parts(8, 48),
        "bend" => pmcodec_mesh::skin::bending_tube(24, 40, 48),
        "wave" => samples::waving_cloth(90, 60, 64),
        path => pmcodec_mesh::obj::load_obj_sequence(Path::new(path), 30.0).expect("OBJ folder"),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let bits: u8 = args.iter().find_map(|a| a.parse().ok()).unwrap_or(12);
    let opts = EncodeOptions { quantization: QuantizationChoice::Bits(bits), ..Default::default() };
    let mut agree = 0;
    let mut total = 0;
    for name in args.iter().filter(|a| a.parse::<u8>().is_err()) {
        let mut seq = input(name);
        seq.skin = None;
        let t = Instant::now();
        let (skin, report) = fit_skin(&seq, &FitOptions { quant_bits: bits as u32, ..Default::default() }).expect("fit");
        let fit_s = t.elapsed().as_secs_f64();
        let plain = encode(&seq, &opts, |_| {}).expect("plain").len();
        seq.skin = Some(skin);
        let t = Instant::now();
        let trial = skin_trial(&seq, &opts).expect("trial");
        let trial_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let skinned = encode(&seq, &opts, |_| {}).expect("skinned").len();
        let encode_s = t.elapsed().as_secs_f64();
        let flat_opts = EncodeOptions { skinned_coarse: Some(SkinnedCoarse { joints: 0.0, ..SkinnedCoarse::default() }), ..opts.clone() };
        let flat = encode(&seq, &flat_opts, |_| {}).expect("flat").len();
        let best_skinned = skinned.min(flat);
        let exhaustive = best_skinned < plain;
        let estimate = trial.pays();
        total += 1;
        agree += (exhaustive == estimate) as u32;
        println!(
            "{name}: {} vertices, {} frames, {} bones; fit {fit_s:.2} s, trial {trial_s:.3} s ({} frames), skinned encode {encode_s:.2} s",
            seq.vertex_count(),
            seq.frame_count(),
            report.bones,
            trial.frames_coded
        );
        println!(
            "  trial: band 0 plain {} B, skinned {} B, pose {} B, bind {} B: margin {} B ({:+.1}% of plain band 0) -> {}",
            trial.plain_bytes,
            trial.skinned_bytes,
            trial.pose_bytes,
            trial.bind_bytes,
            trial.margin(),
            100.0 * trial.margin() as f64 / trial.plain_bytes.max(1) as f64,
            if estimate { "keep" } else { "drop" }
        );
        println!(
            "  files: plain {plain} B, skinned {skinned} B, every joint at every level {flat} B: {} ({:+.1}% skinned vs plain){}",
            if exhaustive { "keep" } else { "drop" },
            100.0 * (best_skinned as f64 / plain as f64 - 1.0),
            if exhaustive == estimate { "" } else { "  DISAGREE" }
        );
    }
    println!("{agree} of {total} choices agree");
}
