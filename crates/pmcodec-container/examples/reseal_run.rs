//! A stable-Rust run of the resealed fuzz target's mutations (`pmcodec_container::testing`) on
//! seeds the committed corpus lacks: a skinned glTF character, a textured cloth (grown charts,
//! Rice residuals), a fitted tube, and any `.pmc` files given. Each mutated file goes through
//! [`exercise`] under `catch_unwind`: a panic, or a file that takes over a second, is written
//! to OUT_DIR for the regression corpus. For long local runs, not CI.
//! With `RESEAL_WRITE=1`, every mutated file goes to OUT_DIR with its outcome in OUT_DIR/outcomes.txt, as
//! tests/resealed has them, for the TypeScript decoder (`PMC_RESEALED_DIR=OUT_DIR`, web/test/resealed.test.ts).
//! `cargo run --release -p pmcodec-container --features test-support --example reseal_run -- N OUT_DIR [X.pmc ...]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::testing::{Rng, Unsealed, exercise, keep_failure, mutate, panic_message, variant};
use pmcodec_container::{EncodeOptions, encode};
use pmcodec_mesh::samples::{self, CharacterOptions};
use pmcodec_mesh::skin_fit::{FitOptions, fit_skin};
use std::time::Instant;

fn seeds() -> Vec<(String, Vec<u8>)> {
    let character = CharacterOptions { parts: 3, limbs: 2, chain: 2, segments: 6, rings: 4, seconds: 0.5, ..Default::default() };
    let glb = samples::skinned_character(&character).expect("character");
    let seq = pmcodec_mesh::gltf_input::load_gltf_bytes(&glb, &Default::default()).expect("load");
    let mut tube = samples::twisting_tube(8, 10, 6);
    tube.skin = Some(fit_skin(&tube, &FitOptions { bones: Some(4), ..Default::default() }).expect("fit").0);
    let opts = |k| EncodeOptions { keyframe_interval: k, ..Default::default() };
    vec![
        ("skinned character".into(), encode(&seq, &opts(4), |_| {}).expect("encode")),
        ("textured cloth".into(), encode(&samples::textured_cloth(10, 7, 6, 8), &opts(3), |_| {}).expect("encode")),
        ("fitted tube".into(), encode(&tube, &opts(4), |_| {}).expect("encode")),
    ]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("time") {
        // `reseal_run time X.pmc ...`: how long each file takes to exercise, and what it gives.
        for p in &args[2..] {
            let bytes = std::fs::read(p).expect("read");
            let t = Instant::now();
            let r = exercise(&bytes);
            println!("{p}: {:.3} s, {:?}", t.elapsed().as_secs_f64(), r.err().map(|e| e.to_string()));
        }
        return;
    }
    let n: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let out = std::path::PathBuf::from(args.get(2).cloned().unwrap_or_else(|| "reseal-out".into()));
    std::fs::create_dir_all(&out).expect("out dir");
    let mut all = seeds();
    for p in args.iter().skip(3) {
        all.push((p.clone(), std::fs::read(p).expect("read")));
    }
    std::panic::set_hook(Box::new(|_| {}));
    let write_all = std::env::var("RESEAL_WRITE").is_ok_and(|v| v == "1");
    let mut outcomes = String::from("# reseal_run's mutations: NAME OUTCOME\n");
    for (k, (name, bytes)) in all.iter().enumerate() {
        exercise(bytes).unwrap_or_else(|e| panic!("{name} does not play before damage: {e}"));
        let base = Unsealed::open(bytes).expect("open");
        let (mut refused, mut panics, mut slow) = (std::collections::BTreeMap::new(), 0, 0);
        for i in 0..n {
            let mut rng = Rng::new((k as u64 + 100) << 32 | i);
            let mut u = base.clone();
            mutate(&mut u, &mut rng);
            let file = u.seal();
            if file.len() > 1 << 24 {
                let raw: usize = u.chunks.iter().map(|c| c.raw.len()).sum();
                eprintln!(
                    "#{k}-{i}: {} B sealed: header {} trailing {} chunks {} raw {raw}",
                    file.len(),
                    u.header.len(),
                    u.trailing.len(),
                    u.chunks.len()
                );
            }
            let t = Instant::now();
            let result = std::panic::catch_unwind(|| exercise(&file));
            let took = t.elapsed().as_secs_f64();
            let mut record = |o: &'static str| {
                *refused.entry(o).or_insert(0) += 1;
                if write_all {
                    let name = format!("m-{k}-{i}.pmc");
                    std::fs::write(out.join(&name), &file).expect("write");
                    outcomes.push_str(&format!("{name} {o}\n"));
                }
            };
            match result {
                Ok(Ok(())) => record("ok"),
                Ok(Err(e)) => record(variant(&e)),
                Err(p) => {
                    panics += 1;
                    keep_failure(&out, "panic", &format!("{k}-{i}.pmc"), &file, &panic_message(p.as_ref()));
                }
            }
            if took > 1.0 {
                slow += 1;
                keep_failure(&out, "slow", &format!("{k}-{i}.pmc"), &file, &format!("{took:.1} s"));
            }
        }
        println!("{name} ({} B): {n} mutations, {panics} panics, {slow} slow; {refused:?}", bytes.len());
    }
    if write_all {
        std::fs::write(out.join("outcomes.txt"), outcomes).expect("write outcomes.txt");
    }
}
