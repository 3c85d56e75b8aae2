//! `pmcodec encode` of a skinned glTF poses its frames as the encoder asks for them (issue 17,
//! "Encode cost"): the file is the one the whole sequence, sampled first, encodes to, with
//! frame 0's clusters kept (the default for a glTF's own skin) or reclustered as asked.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::EncodeOptions;
use pmcodec_mesh::gltf_input::{GltfOptions, load_gltf};
use pmcodec_mesh::samples::{CharacterOptions, skinned_character};
use std::path::PathBuf;
use std::process::Command;

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pmcodec-encode-gltf-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn a_skinned_glb_encodes_as_its_whole_sequence_does() {
    let dir = temp("same");
    let opts = CharacterOptions { parts: 5, limbs: 2, chain: 3, segments: 6, rings: 4, seconds: 1.0, keys_per_second: 6.0, seed: 9 };
    let glb = dir.join("character.glb");
    std::fs::write(&glb, skinned_character(&opts).unwrap()).unwrap();
    let pmc = dir.join("character.pmc");
    let out = Command::new(env!("CARGO_BIN_EXE_pmcodec"))
        .args(["encode", "-q", "--fps", "20", "--quant-bits", "12"])
        .arg(&glb)
        .arg("-o")
        .arg(&pmc)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let seq = load_gltf(&glb, &GltfOptions { frame_rate: 20.0, ..Default::default() }).unwrap();
    assert_eq!(seq.frame_count(), 21);
    // A glTF's own skin keeps frame 0's clusters unless asked otherwise.
    let eopts = pmcodec_container::EncodeOptions {
        quantization: pmcodec_container::QuantizationChoice::Bits(12),
        skinned_recluster_every: u32::MAX,
        ..Default::default()
    };
    let want = pmcodec_container::encode(&seq, &eopts, |_| {}).unwrap();
    assert_eq!(std::fs::read(&pmc).unwrap(), want);
    let every = dir.join("every.pmc");
    let out = Command::new(env!("CARGO_BIN_EXE_pmcodec"))
        .args(["encode", "-q", "--fps", "20", "--quant-bits", "12", "--skinned-recluster-every", "1"])
        .arg(&glb)
        .arg("-o")
        .arg(&every)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let reclustered = pmcodec_container::encode(&seq, &EncodeOptions { skinned_recluster_every: 1, ..eopts }, |_| {}).unwrap();
    assert_eq!(std::fs::read(&every).unwrap(), reclustered);
    assert_ne!(reclustered, want, "reclustering every frame changes the file");

    // An animation the file does not have is bad input, and nothing is written.
    let missing = dir.join("missing.pmc");
    let out = Command::new(env!("CARGO_BIN_EXE_pmcodec"))
        .args(["encode", "-q", "--animation", "7"])
        .arg(&glb)
        .arg("-o")
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("generated"), "the error lists the file's animations");
    assert!(!missing.exists());
    let _ = std::fs::remove_dir_all(&dir);
}
