//! glTF input: generated files in JSON or GLB containers, embedded or external buffers, and
//! the errors malformed files get (split from gltf_input.rs, whose helpers live in common).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_mesh::gltf_input::{GltfOptions, RiggedMesh, load_gltf, load_gltf_bytes};
use pmcodec_mesh::{InputLimits, MeshError, Sequence};
use serde_json::{Value, json};

use crate::common;
use common::{Bin, TRIANGLE, animated_triangle, base64, bent_strip, glb, load, opts};
// ------------------------------------------------------------------------------------------------
// Generated files: containers and errors
// ------------------------------------------------------------------------------------------------

#[test]
fn gltf_json_with_embedded_or_external_buffers() {
    let (bin, doc) = animated_triangle("translation", "LINEAR", &[0.0, 1.0], &[0.0, 0.0, 0.0, 2.0, 0.0, 0.0]);
    let from_glb = load(&bin.glb(doc.clone()), 4.0).unwrap();

    let mut embedded = bin.document(doc.clone());
    embedded["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{}", base64(&bin.bytes)));
    let from_json = load(&serde_json::to_vec(&embedded).unwrap(), 4.0).unwrap();
    assert_eq!(from_json.frames, from_glb.frames);

    let mut external = bin.document(doc);
    external["buffers"][0]["uri"] = json!("tri%20data.bin");
    let json_bytes = serde_json::to_vec(&external).unwrap();
    let e = load(&json_bytes, 4.0).unwrap_err();
    assert!(e.to_string().contains("path") && e.to_string().contains("tri%20data.bin"), "{e}");

    let dir = std::env::temp_dir().join(format!("pmcodec-gltf-input-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("tri data.bin"), &bin.bytes).unwrap();
    std::fs::write(dir.join("tri.gltf"), &json_bytes).unwrap();
    let from_path = load_gltf(&dir.join("tri.gltf"), &opts(None, 4.0, false)).unwrap();
    assert_eq!(from_path.frames, from_glb.frames);
    // A buffer outside the file's folder is not read.
    external["buffers"][0]["uri"] = json!("../tri.bin");
    std::fs::write(dir.join("escape.gltf"), serde_json::to_vec(&external).unwrap()).unwrap();
    let e = load_gltf(&dir.join("escape.gltf"), &GltfOptions::default()).unwrap_err();
    assert!(matches!(e, MeshError::Unsupported(_)), "{e}");
    external["buffers"][0]["uri"] = json!("%ff%fe.bin");
    std::fs::write(dir.join("bad.gltf"), serde_json::to_vec(&external).unwrap()).unwrap();
    assert!(load_gltf(&dir.join("bad.gltf"), &GltfOptions::default()).is_err());
    let e = load_gltf(&dir.join("missing.glb"), &GltfOptions::default()).unwrap_err();
    assert!(matches!(e, MeshError::Io { .. }), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unsupported_features_are_named() {
    let (bin, doc) = animated_triangle("translation", "LINEAR", &[0.0, 1.0], &[0.0; 6]);
    let with = |f: &dyn Fn(&mut Value)| {
        let mut d = bin.document(doc.clone());
        f(&mut d);
        load(&glb(&d, &bin.bytes), 30.0)
    };
    // (Draco and meshopt are read: tests/compressed_gltf.rs.)
    let e = with(&|d| d["extensionsRequired"] = json!(["EXT_mesh_gpu_instancing", "EXT_made_up_compression"])).unwrap_err();
    assert!(matches!(e, MeshError::Unsupported(_)), "{e}");
    assert!(e.to_string().contains("EXT_mesh_gpu_instancing") && e.to_string().contains("EXT_made_up_compression"), "{e}");
    // Extensions that only touch materials or textures do not stop the geometry being read.
    with(&|d| d["extensionsRequired"] = json!(["KHR_texture_transform", "KHR_materials_unlit"])).unwrap();
    for (mode, name) in [(0, "POINTS"), (1, "LINES"), (2, "LINE_LOOP"), (3, "LINE_STRIP")] {
        let e = with(&|d| d["meshes"][0]["primitives"][0]["mode"] = json!(mode)).unwrap_err();
        assert!(matches!(e, MeshError::Unsupported(_)) && e.to_string().contains(name), "{e}");
    }
    let e = with(&|d| d["asset"] = json!({"version": "1.0"})).unwrap_err();
    assert!(matches!(e, MeshError::Unsupported(_)) && e.to_string().contains("1.0"), "{e}");
}

/// A skin with more than four influences keeps the four largest and renormalises them, and
/// weights that do not sum to one are renormalised: both are said, naming primitive and skin,
/// in the rig's and the sequence skin's warnings (issue 17). Sums off by 8-bit rounding are not.
#[test]
fn extra_influences_and_unnormalised_weights_are_kept_and_reported() {
    let mut bin = Bin::default();
    let pos = bin.f32(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3");
    // Vertex 0: five joints (0.3, 0.25, 0.2, 0.15 and 0.1 on joint 4); vertex 1: one joint at 0.5;
    // vertex 2: 8-bit weights 128 + 126 = 254/255, within rounding of one.
    let j0 = bin.u16(&[0, 1, 2, 3, 1, 0, 0, 0, 2, 3, 0, 0], "VEC4");
    let w0 = bin.f32(&[0.3, 0.25, 0.2, 0.15, 0.5, 0.0, 0.0, 0.0, 128.0 / 255.0, 126.0 / 255.0, 0.0, 0.0], "VEC4");
    let j1 = bin.u16(&[4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], "VEC4");
    let w1 = bin.f32(&[0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], "VEC4");
    let doc = json!({
        "scene": 0, "scenes": [{"nodes": [0, 5]}],
        "nodes": [{"children": [1, 2, 3, 4]}, {}, {}, {}, {}, {"mesh": 0, "skin": 0}],
        "skins": [{"joints": [0, 1, 2, 3, 4]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "JOINTS_0": j0, "WEIGHTS_0": w0, "JOINTS_1": j1, "WEIGHTS_1": w1}}]}]
    });
    let rig = RiggedMesh::from_bytes(&bin.glb(doc.clone())).unwrap();
    assert_eq!(rig.joints[0], [0, 1, 2, 3]);
    let w = rig.weights[0];
    assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6 && (w[0] - 0.3 / 0.9).abs() < 1e-6, "{w:?}");
    assert_eq!(rig.weights[1], [1.0, 0.0, 0.0, 0.0]);
    assert_eq!(rig.warnings.len(), 2, "{:?}", rig.warnings);
    let four = &rig.warnings[0];
    assert!(four.contains("skin 0") && four.contains("1 vertices have more than four influences (vertex 0 has 5)"), "{four}");
    assert!(four.contains("kept the four largest") && four.contains("renormalised"), "{four}");
    let sum = &rig.warnings[1];
    assert!(sum.contains("skin 0") && sum.contains("1 vertices' weights do not sum to one (vertex 1: 0.5)"), "{sum}");
    // The sequence's skin carries them on to `pmcodec encode`.
    let seq = load(&bin.glb(doc), 30.0).unwrap();
    assert_eq!(seq.skin.as_ref().map(|s| s.warnings.clone()), Some(rig.warnings.clone()));
    // The bent strip's 8-bit weights (200 of 255 alone) are renormalised too, and said so once.
    let (strip, strip_doc) = bent_strip();
    let warnings = RiggedMesh::from_bytes(&strip.glb(strip_doc)).unwrap().warnings;
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("8 vertices' weights do not sum to one (vertex 0: 0.78"), "{warnings:?}");
}

#[test]
fn broken_files_give_errors_that_say_what_is_wrong() {
    let (bin, doc) = bent_strip();
    let with = |f: &dyn Fn(&mut Value)| {
        let mut d = bin.document(doc.clone());
        f(&mut d);
        load(&glb(&d, &bin.bytes), 30.0)
    };
    let expect = |result: Result<Sequence, MeshError>, words: &[&str]| {
        let e = result.expect_err("should fail").to_string();
        for w in words {
            assert!(e.contains(w), "{e:?} lacks {w:?}");
        }
    };
    with(&|_| {}).unwrap();
    expect(with(&|d| d["meshes"][1]["primitives"][0]["attributes"] = json!({})), &["no POSITION"]);
    expect(with(&|d| d["accessors"][0]["count"] = json!(80)), &["accessor 0", "past the end"]);
    expect(with(&|d| d["accessors"][0]["byteOffset"] = json!(400)), &["accessor 0"]);
    expect(with(&|d| d["bufferViews"][0]["byteLength"] = json!(100000)), &["bufferView 0", "outside buffer"]);
    expect(with(&|d| d["bufferViews"][0]["byteStride"] = json!(4)), &["byteStride"]);
    expect(with(&|d| d["accessors"][1]["componentType"] = json!(5126)), &["JOINTS_0"]);
    expect(with(&|d| d["animations"][0]["channels"][0]["target"]["node"] = json!(99)), &["node 99"]);
    expect(with(&|d| d["animations"][0]["channels"][0]["sampler"] = json!(7)), &["sampler 7"]);
    expect(with(&|d| d["nodes"][1]["children"] = json!([0])), &["cycle"]);
    expect(with(&|d| d["nodes"][2]["children"] = json!([3])), &["child of both"]);
    expect(with(&|d| d["nodes"][2]["skin"] = json!(4)), &["skin 4"]);
    expect(with(&|d| d["nodes"][3]["mesh"] = json!(9)), &["mesh 9"]);
    expect(with(&|d| d["skins"][0]["joints"] = json!([0])), &["skin 0", "joint 1"]);
    // Finite but huge transforms overflow while posing: reported by validation, not hidden.
    let e = with(&|d| d["nodes"][1]["scale"] = json!([3e38, 3e38, 3e38])).unwrap_err();
    assert!(matches!(e, MeshError::NonFinite { .. }), "{e}");

    // Index out of range, NaN position: a triangle file with indices.
    let mut tri = Bin::default();
    let pos = tri.f32(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, f32::NAN, 0.0, 5.0, 5.0, 5.0], "VEC3");
    let idx = tri.u16(&[0, 1, 2, 0, 1, 7], "SCALAR");
    let bad_index = tri.glb(json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}]}));
    expect(load(&bad_index, 30.0), &["index 7", "out of range"]);
    let mut tri = Bin::default();
    let pos = tri.f32(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, f32::NAN, 0.0], "VEC3");
    let nan = tri.glb(json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]}));
    expect(load(&nan, 30.0), &["primitive 0 vertex 2", "finite"]);
    let mut tri = Bin::default();
    let pos = tri.f32(&TRIANGLE, "VEC3");
    let idx = tri.f32(&[0.0, 1.0, 2.0], "SCALAR");
    let float_indices = tri.glb(json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}]}));
    expect(load(&float_indices, 30.0), &["indices"]);

    // An empty accessor is an empty mesh, not an underflow.
    let mut empty = bin.document(doc.clone());
    empty["accessors"][0]["count"] = json!(0);
    empty["accessors"][4]["count"] = json!(0);
    assert!(load(&glb(&empty, &bin.bytes), 30.0).is_err());
    assert!(load(b"not a gltf", 30.0).is_err());
    assert!(load(&[], 30.0).is_err());
    assert!(load(b"glTF", 30.0).is_err());
}

#[test]
fn sparse_accessors_substitute_values() {
    // Morph deltas given sparsely: only vertex 2 moves, by +1 in z.
    let mut bin = Bin::default();
    let pos = bin.f32(&TRIANGLE, "VEC3");
    let sparse_indices = bin.u16(&[2], "SCALAR");
    let sparse_values = bin.f32(&[0.0, 0.0, 1.0], "VEC3");
    let sparse_target = json!({"componentType": 5126, "count": 3, "type": "VEC3", "sparse": {
        "count": 1,
        "indices": {"bufferView": bin.accessors[sparse_indices]["bufferView"], "componentType": 5123},
        "values": {"bufferView": bin.accessors[sparse_values]["bufferView"]}
    }});
    bin.accessors.push(sparse_target);
    let target = bin.accessors.len() - 1;
    let doc = json!({
        "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "weights": [1.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "targets": [{"POSITION": target}]}]}]
    });
    let seq = load(&bin.glb(doc.clone()), 30.0).unwrap();
    assert_eq!(seq.frames[0][2], Vec3::new(0.0, 1.0, 1.0));
    assert_eq!(seq.frames[0][1], Vec3::new(1.0, 0.0, 0.0));
    // A sparse index beyond the accessor is an error.
    let bad = bin.document(doc);
    let view = bin.accessors[sparse_indices]["bufferView"].as_u64().unwrap() as usize;
    let mut bytes = bin.bytes.clone();
    let at = bin.views[view]["byteOffset"].as_u64().unwrap() as usize;
    bytes[at] = 9;
    let e = load(&glb(&bad, &bytes), 30.0).unwrap_err();
    assert!(e.to_string().contains("sparse index 9"), "{e}");
    // More sparse values than elements is an error too.
    let mut bad = bad;
    bad["accessors"][target]["sparse"]["count"] = json!(4);
    let e = load(&glb(&bad, &bin.bytes), 30.0).unwrap_err();
    assert!(e.to_string().contains("4 sparse values for 3 elements"), "{e}");
}

#[test]
fn oversized_requests_are_refused_or_handled_in_linear_time() {
    // 200 000 empty morph targets on a 1000-vertex mesh would expand to 2e8 deltas: refused
    // before anything that size is allocated.
    let mut bin = Bin::default();
    let pts: Vec<f32> = (0..3000).map(|i| i as f32).collect();
    let pos = bin.f32(&pts, "VEC3");
    let targets = vec![json!({}); 200_000];
    let bytes = bin.glb(json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "targets": targets}]}]}));
    let start = std::time::Instant::now();
    assert!(matches!(load(&bytes, 30.0), Err(MeshError::TooLarge { .. })));
    // An accessor without a bufferView may not claim billions of (zero) elements: as POSITION,
    // the vertex limit refuses it on its declared count; as anything else, the element bound.
    let mut doc = bin.document(json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]}));
    doc["accessors"][0] = json!({"componentType": 5126, "count": 4_000_000_000u64, "type": "VEC3"});
    assert!(matches!(load(&glb(&doc, &bin.bytes), 30.0), Err(MeshError::LimitExceeded { limit: "max_vertices", .. })));
    let no_limits = InputLimits { max_vertices: usize::MAX, ..Default::default() };
    let e = load_gltf_bytes(&glb(&doc, &bin.bytes), &GltfOptions { limits: no_limits, ..Default::default() });
    assert!(matches!(e, Err(MeshError::TooLarge { .. })), "{e:?}");

    // A chain of 100 000 nodes with the mesh at the bottom: fine, and not quadratic.
    let mut tri = Bin::default();
    let pos = tri.f32(&TRIANGLE, "VEC3");
    let depth = 100_000;
    let mut nodes: Vec<Value> = (1..depth).map(|i| json!({"children": [i]})).collect();
    nodes.push(json!({"mesh": 0, "translation": [1.0, 0.0, 0.0]}));
    let chain = tri.glb(json!({"scenes": [{"nodes": [0]}], "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]}));
    let seq = load(&chain, 30.0).unwrap();
    assert_eq!(seq.frames[0][0], Vec3::new(1.0, 0.0, 0.0));
    // The same chain closed into a loop is a cycle, reported as such.
    let mut doc: Value = tri.document(json!({"scenes": [{"nodes": [0]}], "nodes": [], "meshes": [
        {"primitives": [{"attributes": {"POSITION": pos}}]}]}));
    let mut nodes: Vec<Value> = (1..depth).map(|i| json!({"children": [i]})).collect();
    nodes.push(json!({"mesh": 0, "children": [0]}));
    doc["nodes"] = Value::Array(nodes);
    let e = load(&glb(&doc, &tri.bytes), 30.0).unwrap_err();
    assert!(e.to_string().contains("cycle"), "{e}");
    assert!(start.elapsed().as_secs() < 20, "took {:?}", start.elapsed());
}

#[test]
fn corrupted_bytes_never_panic() {
    // Every truncation and every flipped byte of a small skinned, animated GLB either loads or
    // gives an error; none may panic.
    let (bin, doc) = bent_strip();
    let bytes = bin.glb(doc);
    for cut in (0..bytes.len()).step_by(7) {
        let _ = load(&bytes[..cut], 30.0);
    }
    for at in 0..bytes.len() {
        for flip in [0xFF, 0x01, 0x80] {
            let mut b = bytes.clone();
            b[at] ^= flip;
            let _ = load_gltf_bytes(&b, &GltfOptions { frame_rate: 5.0, ..Default::default() });
        }
    }
    // The GLB length field itself smaller than the header.
    let mut b = bytes.clone();
    b[8..12].copy_from_slice(&4u32.to_le_bytes());
    assert!(load(&b, 30.0).is_err());
}
