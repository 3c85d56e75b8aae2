//! Measures a fitted skin (Le and Deng, "Smooth Skinning Decomposition with Rigid Bones", 2012)
//! the way the container will use it: positions quantized at `--quant-bits` over the
//! sequence's bounding box, the skin quantized as `pmcodec-container` stores it (bind positions
//! in half quanta, linear parts in 2^-15 quanta per bind quantum, translations in quarter
//! quanta, weights in 2^-16) and posed by the same integer linear blend skinning, and the
//! residual of every input vertex in whole quanta. Prints, per sequence, the residual's RMS and
//! the bits a simple coder would need for it: its zeroth-order entropy per coordinate and the
//! Elias gamma bits the encoder's own cost estimate charges, both for the residual itself (what
//! a keyframe codes) and for its change since the previous frame (what the container's
//! `prev + (skin_f - skin_{f-1})` prediction leaves on other frames).
//!
//! ```text
//! cargo run --release -p pmcodec-mesh --example skin_fit_residual -- \
//!     /work/shared/data/horse-gallop /work/shared/data/samba-60 /work/shared/data/cat-poses \
//!     twisting-tube waving-cloth [--bones N] [--quant-bits 12] [--iterations N]
//! ```
//!
//! An argument that names a built-in sample (`pmcodec_mesh::samples::NAMES`) is generated, any
//! other is read as a folder of OBJ frames.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::obj::load_obj_sequence;
use pmcodec_mesh::skin_fit::{FitOptions, fit_skin};
use pmcodec_mesh::{Sequence, SequenceSkin, samples};
use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

const LINEAR_BITS: u32 = 15;
const TRANSLATION_BITS: u32 = 2;

fn main() {
    let mut inputs = Vec::new();
    let mut opts = FitOptions::default();
    let mut bits = 12u32;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--bones" => opts.bones = Some(args.next().expect("--bones N").parse().expect("a number")),
            "--iterations" => opts.iterations = args.next().expect("--iterations N").parse().expect("a number"),
            "--quant-bits" => bits = args.next().expect("--quant-bits N").parse().expect("a number"),
            _ => inputs.push(a),
        }
    }
    println!(
        "{:<14} {:>6} {:>4} {:>5} {:>7} | {:>7} {:>6} {:>6} | {:>7} {:>6} {:>6} | {:>6} {:>6}",
        "sequence", "verts", "frm", "bones", "fit s", "key rms", "H", "gamma", "dlt rms", "H", "gamma", "pl H", "pl gam"
    );
    for input in inputs {
        let seq = match samples::by_name(&input) {
            Some(s) => s,
            None => load_obj_sequence(Path::new(&input), 30.0).expect("an OBJ folder or a sample name"),
        };
        let t = Instant::now();
        let (skin, report) = fit_skin(&seq, &opts).expect("fit");
        let seconds = t.elapsed().as_secs_f64();
        let m = measure(&seq, &skin, bits);
        let name = Path::new(&input).file_name().map_or(input.clone(), |n| n.to_string_lossy().into_owned());
        println!(
            "{:<14} {:>6} {:>4} {:>5} {:>7.2} | {:>7.2} {:>6.2} {:>6.2} | {:>7.2} {:>6.2} {:>6.2} | {:>6.2} {:>6.2}",
            name,
            seq.vertex_count(),
            seq.frame_count(),
            report.bones,
            seconds,
            m.key.rms,
            m.key.entropy,
            m.key.gamma,
            m.delta.rms,
            m.delta.entropy,
            m.delta.gamma,
            m.plain.entropy,
            m.plain.gamma
        );
    }
    println!("rms in quanta; H = entropy, gamma = Elias gamma bits, both per coordinate; key = residual");
    println!("under the skin (frames 1..), dlt = its change from the previous frame, pl = the change of");
    println!("the quantized positions themselves (previous-frame prediction, no skin) for comparison.");
}

#[derive(Default)]
struct Stats {
    rms: f64,
    entropy: f64,
    gamma: f64,
}

fn stats(values: &[i64]) -> Stats {
    if values.is_empty() {
        return Stats::default();
    }
    let n = values.len() as f64;
    let mut counts: HashMap<i64, u64> = HashMap::new();
    let (mut sum2, mut gamma) = (0.0, 0.0);
    for &v in values {
        *counts.entry(v).or_default() += 1;
        sum2 += (v * v) as f64;
        let z = ((v << 1) ^ (v >> 63)) as u64;
        gamma += (2 * (64 - z.leading_zeros()) + 1) as f64;
    }
    let entropy = counts.values().map(|&c| -(c as f64 / n) * (c as f64 / n).log2()).sum();
    Stats { rms: (sum2 / n).sqrt(), entropy, gamma: gamma / n }
}

struct Measured {
    key: Stats,
    delta: Stats,
    plain: Stats,
}

/// The skin quantized and posed as `pmcodec-container`'s `skin::lbs` poses it (bind positions
/// at half a quantum, the scale of rigid bones), residuals against the quantized frames.
fn measure(seq: &Sequence, skin: &SequenceSkin, bits: u32) -> Measured {
    let (lo, hi) = seq.bounds().expect("bounds");
    let step = ((hi - lo).max_element() / ((1u32 << bits) - 1) as f32) as f64;
    let bstep = (step / 2.0) as f32 as f64;
    let lo = lo.as_dvec3();
    let n = seq.vertex_count();
    let bind: Vec<[i64; 3]> = skin.rest.iter().map(|p| (p.as_dvec3() / bstep).round().to_array().map(|x| x as i64)).collect();
    let weights: Vec<[i64; 4]> = skin.weights.iter().map(|w| w.map(|x| (x as f64 * 65536.0).round() as i64)).collect();
    let scale = bstep / step * (1u64 << LINEAR_BITS) as f64;
    let tscale = (1u64 << TRANSLATION_BITS) as f64 / step;
    let mut key = Vec::new();
    let mut delta = Vec::new();
    let mut plain = Vec::new();
    let mut before: Vec<[i64; 3]> = Vec::new();
    let mut before_q: Vec<[i64; 3]> = Vec::new();
    for (f, frame) in seq.frames.iter().enumerate() {
        let palette: Vec<[i64; 12]> = skin.matrices[f]
            .iter()
            .map(|m| {
                std::array::from_fn(|i| {
                    if i % 4 == 3 { ((m[i] as f64 - lo[i / 4]) * tscale).round() as i64 } else { (m[i] as f64 * scale).round() as i64 }
                })
            })
            .collect();
        let mut now = Vec::with_capacity(n);
        let mut now_q = Vec::with_capacity(n);
        for v in 0..n {
            let mut acc = [0i64; 3];
            for k in 0..4 {
                let w = weights[v][k];
                if w == 0 {
                    continue;
                }
                let m = &palette[skin.joints[v][k] as usize];
                for a in 0..3 {
                    let dot = m[4 * a] * bind[v][0] + m[4 * a + 1] * bind[v][1] + m[4 * a + 2] * bind[v][2];
                    acc[a] += w * ((dot >> (LINEAR_BITS - TRANSLATION_BITS)) + m[4 * a + 3]);
                }
            }
            let posed = acc.map(|x| (x + (1 << (15 + TRANSLATION_BITS))) >> (16 + TRANSLATION_BITS));
            let q = ((frame[v].as_dvec3() - lo) / step).round().to_array().map(|x| x as i64);
            let r = [0, 1, 2].map(|a| q[a] - posed[a]);
            if f > 0 {
                key.extend_from_slice(&r);
                delta.extend((0..3).map(|a| r[a] - before[v][a]));
                plain.extend((0..3).map(|a| q[a] - before_q[v][a]));
            }
            now.push(r);
            now_q.push(q);
        }
        before = now;
        before_q = now_q;
    }
    Measured { key: stats(&key), delta: stats(&delta), plain: stats(&plain) }
}
