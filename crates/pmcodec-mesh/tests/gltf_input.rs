//! glTF input on the real skinned and morph-target files, and on small generated files that pin
//! down interpolation, skinning, morphing and error reporting.

use glam::Vec3;
use pmcodec_mesh::gltf_input::{AnimationSelector, GltfOptions, load_gltf, load_gltf_bytes};
use pmcodec_mesh::{MeshError, Sequence};
use std::path::PathBuf;

fn data(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf")).join(name);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIP: {} is absent", p.display());
        None
    }
}

fn bbox_diag(frame: &[Vec3]) -> f32 {
    let (lo, hi) = pmcodec_mesh::bounds_of(frame).expect("points");
    (hi - lo).length()
}

fn check_animated(seq: &Sequence, min_frames: usize) {
    seq.validate().expect("valid");
    assert!(seq.frame_count() >= min_frames, "{} frames", seq.frame_count());
    let rest = bbox_diag(&seq.frames[0]);
    for f in &seq.frames {
        assert!(f.iter().all(|p| p.is_finite()));
        // A broken skinning transform blows the mesh up or collapses it.
        let d = bbox_diag(f);
        assert!(d < 3.0 * rest && d > rest / 3.0, "diag {d} vs {rest}");
    }
    let moved = seq.frames[0].iter().zip(&seq.frames[seq.frame_count() / 2]).filter(|(a, b)| (**a - **b).length() > 1e-4 * rest).count();
    assert!(moved > seq.vertex_count() / 10, "only {moved} vertices move");
    assert_eq!(seq.source.len(), seq.vertex_count());
}

#[test]
fn fox_is_skinned_welded_and_animated() {
    let Some(path) = data("Fox.glb") else { return };
    let seq = load_gltf(&path, &GltfOptions::default()).expect("load");
    assert_eq!(seq.triangles.len(), 576);
    assert!(seq.vertex_count() < 1728 / 2, "welded to {} vertices", seq.vertex_count());
    check_animated(&seq, 10);
    // Each animation by name and by index; a wrong name lists the names.
    let walk = load_gltf(&path, &GltfOptions { animation: Some(AnimationSelector::Name("Walk".into())), ..Default::default() }).expect("Walk");
    let by_index = load_gltf(&path, &GltfOptions { animation: Some(AnimationSelector::Index(2)), ..Default::default() }).expect("index 2");
    assert_eq!(walk.frames, by_index.frames, "Walk is animation 2 (Run, Survey, Walk)");
    let e = load_gltf(&path, &GltfOptions { animation: Some(AnimationSelector::Name("Fly".into())), ..Default::default() }).unwrap_err();
    assert!(e.to_string().contains("Survey") && e.to_string().contains("Run"), "{e}");
    let unwelded = load_gltf(&path, &GltfOptions { weld: false, ..Default::default() }).expect("unwelded");
    assert_eq!(unwelded.vertex_count(), 1728);
    assert!(unwelded.source.iter().all(|s| (s.index as usize) < 1728));
}

#[test]
fn robot_merges_primitives_with_skin_and_morphs() {
    let Some(path) = data("RobotExpressive.glb") else { return };
    let seq = load_gltf(&path, &GltfOptions::default()).expect("load");
    let prims: std::collections::BTreeSet<u32> = seq.source.iter().map(|s| s.primitive).collect();
    assert!(prims.len() >= 10, "{} primitives merged", prims.len());
    check_animated(&seq, 5);
}

#[test]
fn draco_compressed_parrot_is_named_unsupported() {
    let Some(path) = data("Parrot.glb") else { return };
    let e = load_gltf(&path, &GltfOptions::default()).unwrap_err();
    assert!(matches!(e, MeshError::Unsupported(_)) && e.to_string().contains("KHR_draco_mesh_compression"), "{e}");
}

#[test]
fn morph_target_animals() {
    {
        let (name, targets) = ("Horse.glb", 15);
        let Some(path) = data(name) else { return };
        let seq = load_gltf(&path, &GltfOptions::default()).expect("load");
        check_animated(&seq, 10);
        assert_eq!(seq.morph_displacement.len(), seq.vertex_count(), "{name} ({targets} targets)");
        assert!(seq.morph_displacement.iter().any(|&d| d > 0.0));
    }
}

// ---- generated files ----

/// Builds a GLB from a JSON document and one binary buffer.
fn glb(json: serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(&json).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + j.len() + 8 + b.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// One triangle on a node animated by `channel` (a translation or rotation sampler) and a
/// morph target that moves vertex 2 by +1 in z, with morph weights animated 0 -> 1.
fn animated_triangle(path: &str, interpolation: &str, times: &[f32], values: &[f32], mode: u32, required: &[&str]) -> Vec<u8> {
    let mut bin = f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]); // positions @0 (36)
    bin.extend(f32s(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])); // morph deltas @36 (36)
    let t_off = bin.len();
    bin.extend(f32s(times));
    let v_off = bin.len();
    bin.extend(f32s(values));
    let w_off = bin.len();
    bin.extend(f32s(&[0.0, 1.0])); // weights at times[0], times[last]
    let wt_off = bin.len();
    bin.extend(f32s(&[times[0], *times.last().unwrap()]));
    let comps = if path == "rotation" { "VEC4" } else { "VEC3" };
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsRequired": required,
        "extensionsUsed": required,
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "targets": [{"POSITION": 1}], "mode": mode}], "weights": [0.0]}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 36},
            {"buffer": 0, "byteOffset": t_off, "byteLength": times.len() * 4},
            {"buffer": 0, "byteOffset": v_off, "byteLength": values.len() * 4},
            {"buffer": 0, "byteOffset": w_off, "byteLength": 8},
            {"buffer": 0, "byteOffset": wt_off, "byteLength": 8}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [0,0,1]},
            {"bufferView": 2, "componentType": 5126, "count": times.len(), "type": "SCALAR", "min": [times[0]], "max": [*times.last().unwrap()]},
            {"bufferView": 3, "componentType": 5126, "count": values.len() / if comps == "VEC4" {4} else {3}, "type": comps},
            {"bufferView": 4, "componentType": 5126, "count": 2, "type": "SCALAR"},
            {"bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [times[0]], "max": [*times.last().unwrap()]}
        ],
        "animations": [{"name": "move", "channels": [
            {"sampler": 0, "target": {"node": 0, "path": path}},
            {"sampler": 1, "target": {"node": 0, "path": "weights"}}
        ], "samplers": [
            {"input": 2, "output": 3, "interpolation": interpolation},
            {"input": 5, "output": 4, "interpolation": "LINEAR"}
        ]}]
    });
    glb(json, &bin)
}

fn load(bytes: &[u8], fps: f32) -> Result<Sequence, MeshError> {
    load_gltf_bytes(bytes, &GltfOptions { frame_rate: fps, weld: false, ..Default::default() })
}

#[test]
fn linear_step_and_morph_weights() {
    let bytes = animated_triangle("translation", "LINEAR", &[0.0, 1.0], &[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], 4, &[]);
    let seq = load(&bytes, 4.0).unwrap();
    assert_eq!(seq.frame_count(), 5);
    // Halfway: translated by 1 in x, morph weight 0.5 lifts vertex 2 by 0.5.
    assert!((seq.frames[2][0] - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-5, "{:?}", seq.frames[2][0]);
    assert!((seq.frames[2][2] - Vec3::new(1.0, 1.0, 0.5)).length() < 1e-5, "{:?}", seq.frames[2][2]);
    let step = load(&animated_triangle("translation", "STEP", &[0.0, 1.0], &[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], 4, &[]), 4.0).unwrap();
    assert_eq!(step.frames[3][0], Vec3::ZERO);
    assert_eq!(step.frames[4][0], Vec3::new(2.0, 0.0, 0.0));
}

#[test]
fn cubic_spline_and_slerp() {
    // Hermite with zero tangents from 0 to 2: value at u = 0.5 is 1, at u = 0.25 is 2*(3u^2-2u^3) = 0.3125.
    let values = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, /* key 1 */ 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let seq = load(&animated_triangle("translation", "CUBICSPLINE", &[0.0, 1.0], &values, 4, &[]), 4.0).unwrap();
    assert!((seq.frames[1][0].x - 0.3125).abs() < 1e-5, "{}", seq.frames[1][0].x);
    assert!((seq.frames[2][0].x - 1.0).abs() < 1e-5);
    // Rotation from identity to 180 degrees about z: halfway is 90 degrees.
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let rot = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0];
    let seq = load(&animated_triangle("rotation", "LINEAR", &[0.0, 1.0], &rot, 4, &[]), 2.0).unwrap();
    assert!((seq.frames[1][1] - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-5, "{:?} ({h})", seq.frames[1][1]);
}

#[test]
fn unsupported_features_are_named() {
    let e = load(&animated_triangle("translation", "LINEAR", &[0.0, 1.0], &[0.0; 6], 4, &["KHR_draco_mesh_compression"]), 30.0).unwrap_err();
    assert!(matches!(e, MeshError::Unsupported(_)) && e.to_string().contains("KHR_draco_mesh_compression"), "{e}");
    let e = load(&animated_triangle("translation", "LINEAR", &[0.0, 1.0], &[0.0; 6], 0, &[]), 30.0).unwrap_err();
    assert!(e.to_string().contains("Points"), "{e}");
    assert!(load(b"not a gltf", 30.0).is_err());
    assert!(load(&[], 30.0).is_err());
}

#[test]
fn two_joint_skin_bends_a_strip() {
    // A strip of 3 quads along x; joint 1 (child of joint 0, at x = 1) turns 90 degrees about z.
    let pos: Vec<f32> = (0..8).flat_map(|i| [(i / 2) as f32, (i % 2) as f32 * 0.1, 0.0]).collect();
    let joints: Vec<u8> = (0..8).flat_map(|i| [if i / 2 >= 2 { 1u8 } else { 0 }, 0, 0, 0]).collect();
    let weights = f32s(&(0..8).flat_map(|_| [1.0, 0.0, 0.0, 0.0]).collect::<Vec<f32>>());
    let ibm = f32s(&[1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., /* joint 1 at x=1 */ 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., -1., 0., 0., 1.]);
    let idx: Vec<u8> = [0u16, 2, 1, 1, 2, 3, 2, 4, 3, 3, 4, 5, 4, 6, 5, 5, 6, 7].iter().flat_map(|i| i.to_le_bytes()).collect();
    let times = f32s(&[0.0, 1.0]);
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let rots = f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, h, h]);
    let mut bin = f32s(&pos);
    let offs: Vec<usize> = [&joints[..], &weights, &ibm, &idx, &times, &rots]
        .iter()
        .map(|part| {
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            let o = bin.len();
            bin.extend_from_slice(part);
            o
        })
        .collect();
    let json = serde_json::json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 2]}],
        "nodes": [{"children": [1]}, {"translation": [1.0, 0.0, 0.0]}, {"mesh": 0, "skin": 0}],
        "skins": [{"joints": [0, 1], "inverseBindMatrices": 3}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2}, "indices": 4}]}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 96},
            {"buffer": 0, "byteOffset": offs[0], "byteLength": 32},
            {"buffer": 0, "byteOffset": offs[1], "byteLength": 128},
            {"buffer": 0, "byteOffset": offs[2], "byteLength": 128},
            {"buffer": 0, "byteOffset": offs[3], "byteLength": 36},
            {"buffer": 0, "byteOffset": offs[4], "byteLength": 8},
            {"buffer": 0, "byteOffset": offs[5], "byteLength": 32}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [0,0,0], "max": [3,0.1,0]},
            {"bufferView": 1, "componentType": 5121, "count": 8, "type": "VEC4"},
            {"bufferView": 2, "componentType": 5126, "count": 8, "type": "VEC4"},
            {"bufferView": 3, "componentType": 5126, "count": 2, "type": "MAT4"},
            {"bufferView": 4, "componentType": 5123, "count": 18, "type": "SCALAR"},
            {"bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0.0], "max": [1.0]},
            {"bufferView": 6, "componentType": 5126, "count": 2, "type": "VEC4"}
        ],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}],
                        "samplers": [{"input": 5, "output": 6, "interpolation": "LINEAR"}]}]
    });
    let seq = load(&glb(json, &bin), 1.0).unwrap();
    assert_eq!(seq.frame_count(), 2);
    // Rest: vertex 6 at (3, 0, 0). Bent: joint 1 turned 90 degrees at x = 1: (1, 2, 0).
    assert!((seq.frames[0][6] - Vec3::new(3.0, 0.0, 0.0)).length() < 1e-5, "{:?}", seq.frames[0][6]);
    assert!((seq.frames[1][6] - Vec3::new(1.0, 2.0, 0.0)).length() < 1e-4, "{:?}", seq.frames[1][6]);
    // Joint-0 vertices do not move.
    assert_eq!(seq.frames[1][0], seq.frames[0][0]);
}
