//! Development probe: decode and seek speed on a sequence at 12-bit quantization, in CPU time
//! of this process (the build machine is shared, so wall time overstates it), for profiling.
//! `cargo run --release -p pmcodec-container --example speed -- DIR|FILE.pmc [passes]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{Decoder, EncodeOptions, Motion, QuantizationChoice, Reader, encode};

/// CPU seconds (user + system) this process has used, from /proc (10 ms ticks).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = after.split_whitespace().map(|x| x.parse().unwrap_or(0.0)).collect();
    // Fields 14 and 15 of the line (utime, stime) are 12 and 13 after the command name.
    (f.get(11).copied().unwrap_or(0.0) + f.get(12).copied().unwrap_or(0.0)) / 100.0
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let passes: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(50);
    // A .pmc file is decoded as it is (for instruction counts of decoding alone); a folder is
    // encoded first at 12 bits.
    let bytes = if args[1].ends_with(".pmc") {
        std::fs::read(&args[1]).expect("read")
    } else {
        let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
        // PMCODEC_MOTION=affine: band 0 predicted by affine motion.
        let motion = if std::env::var("PMCODEC_MOTION").as_deref() == Ok("affine") { Motion::Affine } else { Motion::Mean };
        let opts = EncodeOptions { quantization: QuantizationChoice::Bits(12), motion, ..Default::default() };
        encode(&seq, &opts, |_| {}).expect("encode")
    };
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let n = reader.header().frame_count;
    let (t, c) = (std::time::Instant::now(), cpu_seconds());
    for _ in 0..passes {
        let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
        for f in 0..n {
            d.seek(f).expect("frame");
        }
    }
    let frames = (passes as u32 * n) as f64;
    let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
    println!("playback: {:.3} ms/frame CPU ({:.0} frames/s), {:.3} ms/frame wall", cpu * 1e3 / frames, frames / cpu, wall * 1e3 / frames);
    // Random seeks with one open decoder, then with one that keeps its keyframes (warmed up
    // by a first pass over the same seeks, so every keyframe is kept).
    let seeks = passes as u32 * 10;
    for keep in [0, 8] {
        let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
        d.keep_keyframes(keep);
        let targets = (0..seeks).map(|i| (i.wrapping_mul(2654435761) >> 8) % n);
        if keep > 0 {
            targets.clone().for_each(|f| d.seek(f).expect("seek"));
        }
        let (t, c) = (std::time::Instant::now(), cpu_seconds());
        targets.for_each(|f| d.seek(f).expect("seek"));
        let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        let what = if keep > 0 { format!("keeping {keep} keyframes") } else { "keeping no keyframes".into() };
        println!("random seek, open decoder {what}: {:.3} ms CPU, {:.3} ms wall", cpu * 1e3 / seeks as f64, wall * 1e3 / seeks as f64);
    }
}
