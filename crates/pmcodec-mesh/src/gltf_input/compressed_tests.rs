//! Draco and meshopt decoding checked accessor by accessor against other implementations.

use super::*;

fn shared_model(name: &str) -> PathBuf {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf")).join(name);
    assert!(path.is_file(), "{} is absent; these tests read the real models in ../shared/data beside the repository", path.display());
    path
}

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/compressed")).join(name)
}

/// The Parrot's Draco primitive decodes to what glTF Transform with Google's draco3dgltf
/// decodes it to (the digest `tests/draco-reference.mjs` wrote): same counts, same vertex and
/// index order, values equal to within a float rounding of the dequantisation.
#[test]
fn parrot_draco_accessors_match_the_reference_decoder() {
    let file = GltfFile::open(&shared_model("Parrot.glb"), &InputLimits::default()).unwrap();
    let text = std::fs::read_to_string(fixture("parrot-draco-reference.json")).unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    let accessors = reference["accessors"].as_object().unwrap();
    assert_eq!(accessors.len(), 3, "POSITION, TEXCOORD_0 and indices");
    for (index, digest) in accessors {
        let index: usize = index.parse().unwrap();
        let what = digest["what"].as_str().unwrap();
        let dims = digest["components"].as_u64().unwrap() as usize;
        let values: Vec<f64> = if what.ends_with("indices") {
            file.read_uints(index, dims, &[ComponentType::U16, ComponentType::U32], what).unwrap().into_iter().map(f64::from).collect()
        } else {
            file.read_floats(index, dims, ANY_NUMBER, what).unwrap().into_iter().map(f64::from).collect()
        };
        let count = digest["count"].as_u64().unwrap() as usize;
        assert_eq!(values.len(), count * dims, "{what}");
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        let step = digest["step"].as_u64().unwrap() as usize;
        for (s, sample) in digest["samples"].as_array().unwrap().iter().enumerate() {
            for (c, want) in sample.as_array().unwrap().iter().enumerate() {
                let got = values[s * step * dims + c];
                // f32 dequantisation in both decoders; they may differ in the last bit.
                assert!(
                    (got - num(want)).abs() <= 1e-5 * num(want).abs().max(1.0),
                    "{what} element {} component {c}: {got} vs {want}",
                    s * step
                );
            }
        }
        for c in 0..dims {
            let column = || values.iter().skip(c).step_by(dims).copied();
            let sum: f64 = column().sum();
            let want = num(&digest["sum"][c]);
            assert!((sum - want).abs() <= 1e-4 * want.abs().max(1.0) + 1e-3, "{what} component {c} sums to {sum}, not {want}");
            assert_eq!(column().fold(f64::INFINITY, f64::min) as f32, num(&digest["min"][c]) as f32, "{what} min {c}");
            assert_eq!(column().fold(f64::NEG_INFINITY, f64::max) as f32, num(&digest["max"][c]) as f32, "{what} max {c}");
        }
    }
}

/// The appearance reader reads attributes through the same accessor lookup, so it sees the
/// Parrot's Draco-decoded TEXCOORD_0 with no code of its own: every wedge's UV is one of the
/// decoded values, and their range is the reference decoder's.
#[test]
fn appearance_sees_draco_decoded_uvs() {
    let rig = RiggedMesh::from_path(&shared_model("Parrot.glb")).unwrap();
    let looks = rig.appearance.as_ref().expect("the Parrot's appearance is read");
    assert!(!looks.uv0.is_empty());
    let text = std::fs::read_to_string(fixture("parrot-draco-reference.json")).unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    let uv = &reference["accessors"]["1"];
    assert_eq!(uv["what"], "mesh 0 primitive 0 TEXCOORD_0");
    for c in 0..2 {
        let column = || looks.uv0.iter().map(|w| w[c]);
        let (lo, hi) = (column().fold(f32::INFINITY, f32::min), column().fold(f32::NEG_INFINITY, f32::max));
        assert_eq!(lo, uv["min"][c].as_f64().unwrap() as f32, "u/v {c} min");
        assert_eq!(hi, uv["max"][c].as_f64().unwrap() as f32, "u/v {c} max");
    }
    let file = GltfFile::open(&shared_model("Parrot.glb"), &InputLimits::default()).unwrap();
    let decoded = file.read_floats(1, 2, ANY_NUMBER, "TEXCOORD_0").unwrap();
    for (w, &vertex) in looks.wedge_vertex.iter().enumerate() {
        let source = rig.source[vertex as usize].index as usize;
        assert_eq!(looks.uv0[w], [decoded[2 * source], decoded[2 * source + 1]], "wedge {w}");
    }
}
