//! Structure-aware damage to glTF inputs, through everything a GLB meets: the loader, the
//! encoder and the decoders. The JSON chunk is parsed and one to three of its values changed
//! (a number set to a boundary, an array cut short or lengthened, a key removed, a string
//! changed), the file reassembled, loaded, encoded and played (`testing::exercise`) under
//! `catch_unwind`: a panic, or an input that takes over 20 s, is written to OUT_DIR. Seeds: a
//! generated skinned character, a textured cloth written as a GLB, and any GLB given. For long
//! local runs, not CI. With `GLTF_WRITE=1` every damaged input is written to OUT_DIR as well (for
//! the command line's other paths, such as `pmcodec lod`).
//! `cargo run --release -p pmcodec-container --features test-support --example gltf_mutate -- N OUT_DIR [X.glb ...]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::testing::{Rng, exercise, keep_failure, panic_message};
use pmcodec_container::{EncodeOptions, QuantizationChoice, encode};
use pmcodec_mesh::gltf_input::{GltfOptions, load_gltf_bytes};
use pmcodec_mesh::samples::{self, CharacterOptions};
use serde_json::Value;
use std::time::Instant;

/// The JSON and BIN chunks of a GLB.
fn split(glb: &[u8]) -> (Value, Vec<u8>) {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = serde_json::from_slice(&glb[20..20 + json_len]).expect("json chunk");
    let rest = &glb[20 + json_len..];
    let bin = if rest.len() >= 8 { rest[8..8 + u32::from_le_bytes(rest[..4].try_into().unwrap()) as usize].to_vec() } else { vec![] };
    (json, bin)
}

/// Every path to a value in `v` (object keys and array indices).
fn paths(v: &Value, at: &mut Vec<Value>, out: &mut Vec<Vec<Value>>) {
    out.push(at.clone());
    match v {
        Value::Object(m) => m.iter().for_each(|(k, x)| {
            at.push(Value::String(k.clone()));
            paths(x, at, out);
            at.pop();
        }),
        Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| {
            at.push(Value::from(i));
            paths(x, at, out);
            at.pop();
        }),
        _ => {}
    }
}

fn at_mut<'a>(v: &'a mut Value, path: &[Value]) -> Option<&'a mut Value> {
    path.iter().try_fold(v, |v, k| match k {
        Value::String(s) => v.get_mut(s.as_str()),
        Value::Number(n) => v.get_mut(n.as_u64()? as usize),
        _ => None,
    })
}

fn damage(doc: &mut Value, rng: &mut Rng) {
    let mut all = Vec::new();
    paths(doc, &mut Vec::new(), &mut all);
    let path = &all[rng.below(all.len())];
    let Some(v) = at_mut(doc, path) else { return };
    match v {
        Value::Number(n) => {
            // Integers stay integers (indices, counts, offsets: what the loader must check),
            // floats stay floats (positions, weights, times, factors).
            *v = match (n.as_i64(), rng.below(8)) {
                (Some(_), 0) => Value::from(0),
                (Some(_), 1) => Value::from(u32::MAX),
                (Some(_), 2) => Value::from(1u64 << 40),
                (Some(x), 3) => Value::from(x + 1),
                (Some(x), 4) => Value::from(x - 1),
                (Some(x), 5) => Value::from(x * 2 + 1),
                (Some(x), 6) => Value::from(x / 3),
                (Some(x), _) => Value::from(x + rng.below(1000) as i64),
                (None, k) => {
                    let x = n.as_f64().unwrap_or(0.0);
                    Value::from([0.0, -x, x * 1e30, -1e38, 1e-40, x + 1.0, 3.4e38, x * 0.5][k])
                }
            };
        }
        Value::Array(a) if !a.is_empty() => match rng.below(3) {
            0 => a.truncate(rng.below(a.len())),
            1 => {
                let c = a[rng.below(a.len())].clone();
                a.push(c);
            }
            _ => a.reverse(),
        },
        Value::Object(m) if !m.is_empty() && rng.chance(3) => {
            let k = m.keys().nth(rng.below(m.len())).cloned().unwrap();
            m.remove(&k);
        }
        Value::String(s) => *s = ["", "SCALAR", "VEC4", "MAT4", "STEP", "CUBICSPLINE", "weights", "image/png"][rng.below(8)].to_string(),
        Value::Bool(b) => *b = !*b,
        _ => {}
    }
}

/// Loads, encodes and plays a GLB: the first error, as text.
fn run(glb: &[u8]) -> Result<(), String> {
    let seq = load_gltf_bytes(glb, &GltfOptions { frame_rate: 10.0, ..Default::default() }).map_err(|e| e.to_string())?;
    let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(10), ..Default::default() };
    let bytes = encode(&seq, &opts, |_| {}).map_err(|e| e.to_string())?;
    exercise(&bytes).map_err(|e| format!("decoding what was encoded: {e}"))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(500);
    let out = std::path::PathBuf::from(args.get(2).cloned().unwrap_or_else(|| "gltf-out".into()));
    std::fs::create_dir_all(&out).expect("out dir");
    let character = CharacterOptions { parts: 2, limbs: 2, chain: 2, segments: 5, rings: 3, seconds: 0.5, ..Default::default() };
    let mut seeds = vec![("character".to_string(), samples::skinned_character(&character).expect("character"))];
    for p in args.iter().skip(3) {
        seeds.push((p.clone(), std::fs::read(p).expect("read")));
    }
    std::panic::set_hook(Box::new(|_| {}));
    let write_all = std::env::var("GLTF_WRITE").is_ok_and(|v| v == "1");
    for (k, (name, glb)) in seeds.iter().enumerate() {
        run(glb).unwrap_or_else(|e| panic!("{name} does not go through before damage: {e}"));
        let (doc, bin) = split(glb);
        let (mut ok, mut errors, mut decode_errors, mut panics) = (0, 0, 0, 0);
        let mut seen = std::collections::BTreeMap::<String, usize>::new();
        for i in 0..n {
            let mut rng = Rng::new((k as u64 + 7) << 32 | i);
            let mut d = doc.clone();
            for _ in 0..1 + rng.below(3) {
                damage(&mut d, &mut rng);
            }
            let Ok(file) = pmcodec_mesh::glb::assemble(&d, bin.clone()) else { continue };
            if write_all {
                std::fs::write(out.join(format!("m-{k}-{i}.glb")), &file).expect("write");
            }
            let t = Instant::now();
            let result = std::panic::catch_unwind(|| run(&file));
            let took = t.elapsed().as_secs_f64();
            match result {
                Ok(Ok(())) => ok += 1,
                Ok(Err(e)) => {
                    errors += 1;
                    decode_errors += e.starts_with("decoding what was encoded") as usize;
                    if e.starts_with("decoding what was encoded") {
                        keep_failure(&out, "decode", &format!("{k}-{i}.glb"), &file, &e);
                    }
                    let key: String = e.chars().take(50).collect();
                    *seen.entry(key).or_insert(0) += 1;
                }
                Err(p) => {
                    panics += 1;
                    keep_failure(&out, "panic", &format!("{k}-{i}.glb"), &file, &panic_message(p.as_ref()));
                }
            }
            if took > 20.0 {
                keep_failure(&out, "slow", &format!("{k}-{i}.glb"), &file, &format!("{took:.1} s"));
            }
        }
        println!("{name}: {n} damaged inputs: {ok} encoded and played, {errors} errors ({decode_errors} after encoding), {panics} panics");
        let mut common: Vec<_> = seen.into_iter().collect();
        common.sort_by_key(|c| std::cmp::Reverse(c.1));
        for (e, c) in common.iter().take(8) {
            println!("    {c:5}  {e}");
        }
    }
}
