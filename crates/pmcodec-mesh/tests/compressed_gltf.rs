//! Draco- and meshopt-compressed glTF read natively: the Draco Parrot of ../shared/data, the
//! Fox compressed with Draco by glTF Transform and with meshopt by gltfpack (tests/compressed/,
//! made by make-fixtures.sh) against the uncompressed Fox, and truncated, corrupt and oversized
//! compressed data.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_mesh::gltf_input::{GltfOptions, RiggedMesh, load_gltf, load_gltf_bytes};
use pmcodec_mesh::{InputLimits, MeshError, Sequence};
use serde_json::{Value, json};
use std::path::PathBuf;

/// A real file from ../shared/data/gltf; the test fails with a message when it is absent.
fn data(name: &str) -> PathBuf {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf")).join(name);
    assert!(path.is_file(), "{} is absent; these tests read the real models in ../shared/data beside the repository", path.display());
    path
}

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/compressed")).join(name)
}

/// A GLB's JSON document and BIN chunk.
fn split(glb: &[u8]) -> (Value, Vec<u8>) {
    let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    let json_len = word(12);
    let doc = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    let bin = glb[bin_at + 8..bin_at + 8 + word(bin_at)].to_vec();
    (doc, bin)
}

fn join(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut text = serde_json::to_vec(doc).unwrap();
    text.resize(text.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + text.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend((text.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(text);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

fn edited(glb: &[u8], edit: impl Fn(&mut Value)) -> Vec<u8> {
    let (mut doc, bin) = split(glb);
    edit(&mut doc);
    join(&doc, &bin)
}

/// Deterministic pseudo-random numbers (xorshift64*), so a failing case can be replayed.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

// ------------------------------------------------------------------------------------------------
// Draco: the Parrot
// ------------------------------------------------------------------------------------------------

/// The Parrot reads from its Draco GLB with no conversion: every triangle, its twelve morph
/// targets on the right vertices (they are plain accessors indexed like the decoded vertices,
/// so a wrong vertex order would tear the bird apart when it flaps), and its animation.
/// (Accessor-level agreement with Google's decoder: `parrot_draco_accessors_match_the_reference_decoder`.)
#[test]
fn the_draco_parrot_reads_directly() {
    let rig = RiggedMesh::from_path(&data("Parrot.glb")).unwrap();
    assert_eq!(rig.instances.len(), 1);
    assert_eq!(rig.instances[0].morph_targets.len(), 12);
    // 1878 indices; the file has a few degenerate triangles, which the reader drops.
    assert!((600..=626).contains(&rig.triangles.len()), "{} triangles", rig.triangles.len());
    let seq = load_gltf(&data("Parrot.glb"), &GltfOptions::default()).unwrap();
    assert!(seq.frames.len() > 30, "{} frames", seq.frames.len());
    // Morph targets on the right vertices keep the animated bird's longest edge within a few
    // per mille of its length at rest (measured: 43.39 to 43.51 against 43.44); deltas on the
    // wrong vertices (hundreds of units summed over the targets) stretch edges across the body.
    let rest = &seq.frames[0];
    let longest = |frame: &[Vec3]| {
        seq.triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (frame[a as usize] - frame[b as usize]).length())
            .fold(0.0f32, f32::max)
    };
    let at_rest = longest(rest);
    for (f, frame) in seq.frames.iter().enumerate() {
        let l = longest(frame);
        assert!((l - at_rest).abs() <= 0.02 * at_rest, "frame {f}: longest edge {l}, {at_rest} at rest");
    }
}

/// The Parrot's bytes with `edit` applied to its Draco stream (bufferView 0) only.
fn parrot_with_stream(edit: impl Fn(&mut [u8])) -> Vec<u8> {
    let glb = std::fs::read(data("Parrot.glb")).unwrap();
    let (doc, mut bin) = split(&glb);
    let view = &doc["bufferViews"]
        [doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"].as_u64().unwrap() as usize];
    let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let len = view["byteLength"].as_u64().unwrap() as usize;
    edit(&mut bin[start..start + len]);
    join(&doc, &bin)
}

#[test]
fn truncated_or_inconsistent_draco_data_is_named() {
    let glb = std::fs::read(data("Parrot.glb")).unwrap();
    let named = |e: &MeshError| {
        let m = e.to_string();
        assert!(m.contains("mesh 0 primitive 0 (KHR_draco_mesh_compression)"), "{m}");
        m
    };
    // The stream cut short.
    let cut = edited(&glb, |d| d["bufferViews"][0]["byteLength"] = json!(4000));
    let m = named(&load_gltf_bytes(&cut, &GltfOptions::default()).unwrap_err());
    assert!(m.contains("does not decode"), "{m}");
    // Accessors that claim more vertices or indices than the stream holds.
    for (accessor, count) in [(0, 2_000_000), (1, 1046), (2, 1881)] {
        let lie = edited(&glb, |d| d["accessors"][accessor]["count"] = json!(count));
        named(&load_gltf_bytes(&lie, &GltfOptions::default()).unwrap_err());
    }
    // A Draco attribute id the stream does not have, a glTF attribute the primitive lacks.
    let ext = "/meshes/0/primitives/0/extensions/KHR_draco_mesh_compression/attributes";
    let m =
        named(&load_gltf_bytes(&edited(&glb, |d| *d.pointer_mut(ext).unwrap() = json!({"POSITION": 7})), &Default::default()).unwrap_err());
    assert!(m.contains("POSITION maps to Draco attribute 7"), "{m}");
    let m =
        load_gltf_bytes(&edited(&glb, |d| d.pointer_mut(ext).unwrap()["NORMAL"] = json!(2)), &Default::default()).unwrap_err().to_string();
    assert!(m.contains("NORMAL") && m.contains("does not have"), "{m}");
    // Morph targets over an edgebreaker stream would land on the wrong vertices.
    let e = load_gltf_bytes(&parrot_with_stream(|s| s[8] = 1), &Default::default()).unwrap_err();
    assert!(matches!(e, MeshError::Unsupported(_)) && named(&e).contains("edgebreaker"), "{e}");
}

/// The input limits hold before anything is decoded: the accessors' declared counts are
/// checked, and the decoder is held to them.
#[test]
fn draco_decoding_respects_the_input_limits() {
    let glb = std::fs::read(data("Parrot.glb")).unwrap();
    let small = InputLimits { max_vertices: 1000, ..Default::default() };
    let e = RiggedMesh::from_bytes_with(&glb, &small).unwrap_err();
    assert!(matches!(e, MeshError::LimitExceeded { limit: "max_vertices", .. }), "{e}");
    assert!(e.to_string().contains("KHR_draco_mesh_compression"), "{e}");
    let few = InputLimits { max_triangles: 600, ..Default::default() };
    let e = RiggedMesh::from_bytes_with(&glb, &few).unwrap_err();
    assert!(matches!(e, MeshError::LimitExceeded { limit: "max_triangles", .. }), "{e}");
    // A count past the limits is refused by the count alone.
    let huge = edited(&glb, |d| d["accessors"][0]["count"] = json!(3_000_000_000u64));
    let e = load_gltf_bytes(&huge, &Default::default()).unwrap_err();
    assert!(matches!(e, MeshError::LimitExceeded { .. }), "{e}");
}

/// What a corrupted file must give: an error, or a sequence that passes validation.
fn error_or_valid(result: Result<Sequence, MeshError>, case: &str) {
    if let Ok(seq) = result {
        seq.validate().unwrap_or_else(|e| panic!("{case}: an invalid sequence came back: {e}"));
        assert!(seq.frames.iter().flatten().all(|p| p.is_finite()), "{case}");
    }
}

/// Flips one to four seeded random bits in `range` of a GLB's BIN chunk, `cases` times: every
/// read must give an error or a valid mesh, never a panic. Returns how many were errors.
fn flip_bits(glb: &[u8], range: std::ops::Range<usize>, seed: u64, cases: usize) -> usize {
    let (doc, bin) = split(glb);
    let opts = GltfOptions { frame_rate: 4.0, ..Default::default() };
    let mut rng = Rng(seed);
    let mut errors = 0;
    for case in 0..cases {
        let mut bin = bin.clone();
        for _ in 0..1 + rng.below(4) {
            let at = range.start + rng.below(range.len());
            bin[at] ^= 1 << rng.below(8);
        }
        let result = load_gltf_bytes(&join(&doc, &bin), &opts);
        errors += usize::from(result.is_err());
        error_or_valid(result, &format!("seed {seed:#x} case {case}"));
    }
    errors
}

/// The bytes of a Draco primitive's stream inside the BIN chunk.
fn draco_stream_range(glb: &[u8]) -> std::ops::Range<usize> {
    let (doc, _) = split(glb);
    let view = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"].as_u64().unwrap() as usize;
    let view = &doc["bufferViews"][view];
    let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    start..start + view["byteLength"].as_u64().unwrap() as usize
}

/// Seeded bit flips in the Draco streams of the Parrot (sequential connectivity) and of the
/// Draco Fox (edgebreaker): an error or a valid mesh, never a panic. (Run locally with 5,000
/// cases each: no panic.)
#[test]
fn flipped_draco_bits_give_an_error_or_a_valid_mesh() {
    for (glb, seed) in
        [(std::fs::read(data("Parrot.glb")).unwrap(), 0x5EED_D5AC0), (std::fs::read(fixture("fox-draco.glb")).unwrap(), 0xF0C5)]
    {
        let errors = flip_bits(&glb, draco_stream_range(&glb), seed, 100);
        // Most flips are caught (the rest land in data that decodes to other valid values).
        assert!(errors > 0, "no flip was detected");
    }
}

/// For each triangle of `a`, the triangle of `b` whose corners are closest (in order up to
/// rotation), the rotation, and the largest corner distance.
fn closest_triangles(a: &[Vec3], a_tris: &[[u32; 3]], b: &[Vec3], b_tris: &[[u32; 3]]) -> Vec<(usize, usize, f32)> {
    let corners = |p: &[Vec3], t: &[u32; 3]| t.map(|i| p[i as usize]);
    let b_corners: Vec<[Vec3; 3]> = b_tris.iter().map(|t| corners(b, t)).collect();
    a_tris
        .iter()
        .map(|t| {
            let x = corners(a, t);
            let mut best = (0, 0, f32::INFINITY);
            for (j, y) in b_corners.iter().enumerate() {
                for r in 0..3 {
                    let d = (0..3).map(|k| (x[k] - y[(k + r) % 3]).length()).fold(0.0f32, f32::max);
                    if d < best.2 {
                        best = (j, r, d);
                    }
                }
            }
            best
        })
        .collect()
}

/// Largest distance from a triangle of `a` to the closest triangle of `b`: the two surfaces
/// agree to that.
fn surface_distance(a: &[Vec3], a_tris: &[[u32; 3]], b: &[Vec3], b_tris: &[[u32; 3]]) -> f32 {
    closest_triangles(a, a_tris, b, b_tris).iter().map(|c| c.2).fold(0.0, f32::max)
}

/// The Fox Draco-compressed by glTF Transform (edgebreaker, which reorders vertices and
/// triangles; tests/draco-fixture.mjs) reads back to the plain Fox: every attribute the
/// extension maps, compared corner by corner with the matching corner of the source: positions
/// within 14-bit quantisation, UVs within 12 bits, normals within 10-bit octahedral error,
/// COLOR_0 (added from the positions) within 8 bits, and JOINTS_0/WEIGHTS_0 through the posed
/// running fox.
#[test]
fn draco_fox_equals_its_uncompressed_source_in_every_attribute() {
    let source_rig = RiggedMesh::from_path(&data("Fox.glb")).unwrap();
    let rig = RiggedMesh::from_path(&fixture("fox-draco.glb")).unwrap();
    assert_eq!(rig.triangles.len(), 576);
    // Bind space, where the attributes were quantised.
    let (lo, hi) = pmcodec_mesh::bounds_of(&source_rig.positions).unwrap();
    let step = (hi - lo).max_element() / 16383.0;
    let matches = closest_triangles(&rig.positions, &rig.triangles, &source_rig.positions, &source_rig.triangles);
    let worst = matches.iter().map(|m| m.2).fold(0.0, f32::max);
    assert!(worst <= 2.0 * step, "bind pose {worst} from the source (quantisation step {step})");
    let (looks, source_looks) = (rig.appearance.as_ref().unwrap(), source_rig.appearance.as_ref().unwrap());
    assert!(!looks.uv0.is_empty() && !looks.normals.is_empty() && !looks.colors.is_empty());
    let (mut uv_error, mut normal_error, mut color_error) = (0.0f32, 0.0f32, 0.0f32);
    for (t, &(s, r, _)) in matches.iter().enumerate() {
        for k in 0..3 {
            let (w, sw) = (looks.corner_wedges[t][k] as usize, source_looks.corner_wedges[s][(k + r) % 3] as usize);
            let (uv, suv) = (looks.uv0[w], source_looks.uv0[sw]);
            uv_error = uv_error.max((uv[0] - suv[0]).abs().max((uv[1] - suv[1]).abs()));
            normal_error = normal_error.max((Vec3::from(looks.normals[w]) - Vec3::from(source_looks.normals[sw])).length());
            // COLOR_0 is the bind-space position scaled to the unit cube.
            let p = rig.positions[looks.wedge_vertex[w] as usize];
            let want = (p - lo) / (hi - lo);
            let c = looks.colors[w];
            color_error = color_error.max((Vec3::new(c[0], c[1], c[2]) - want).abs().max_element()).max((c[3] - 1.0).abs());
        }
    }
    eprintln!("Draco Fox vs Fox: positions {worst} (step {step}), UVs {uv_error}, normals {normal_error}, colours {color_error}");
    assert!(uv_error <= 2.0 / 4095.0, "UVs differ by {uv_error}");
    assert!(normal_error <= 0.01, "normals differ by {normal_error}");
    assert!(color_error <= 2.0 / 255.0, "colours differ by {color_error}");
    // The skin: the first half second of the first animation, posed.
    let seq = load_gltf(&fixture("fox-draco.glb"), &GltfOptions::default()).unwrap();
    let source = load_gltf(&data("Fox.glb"), &GltfOptions::default()).unwrap();
    assert_eq!(seq.frames.len(), 16);
    let extent = {
        let (lo, hi) = pmcodec_mesh::bounds_of(&source.frames[0]).unwrap();
        (hi - lo).max_element()
    };
    for f in 0..seq.frames.len() {
        let d = surface_distance(&seq.frames[f], &seq.triangles, &source.frames[f], &source.triangles);
        assert!(d <= 1e-3 * extent, "frame {f}: {d} from the source (extent {extent})");
    }
}

// ------------------------------------------------------------------------------------------------
// meshopt: the Fox through gltfpack
// ------------------------------------------------------------------------------------------------

/// gltfpack's Fox (quantised 14-bit positions, 8-bit octahedral normals and skin weights,
/// 12-bit quaternion rotations, exponent-filtered scales, meshopt vertex and index codecs)
/// reads back to the uncompressed Fox: the same 576 triangles in the rest pose within the
/// position quantisation, and the same running fox through its first animation within what the
/// quantised weights and rotations move it.
#[test]
fn meshopt_fox_equals_its_uncompressed_source() {
    let source = load_gltf(&data("Fox.glb"), &GltfOptions::default()).unwrap();
    let source_rest = RiggedMesh::from_path(&data("Fox.glb")).unwrap().to_sequence(None, 30.0).unwrap();
    let (lo, hi) = pmcodec_mesh::bounds_of(&source_rest.frames[0]).unwrap();
    let extent = (hi - lo).max_element();
    // One step of 14-bit quantisation over the largest extent (gltfpack quantises all axes on one grid).
    let step = extent / 16383.0;
    let mut decoded = Vec::new();
    for name in ["fox-meshopt-ext.glb", "fox-meshopt-khr.glb"] {
        let rest = RiggedMesh::from_path(&fixture(name)).unwrap().to_sequence(None, 30.0).unwrap();
        assert_eq!(rest.triangles.len(), 576, "{name}");
        let rest_gap = surface_distance(&rest.frames[0], &rest.triangles, &source_rest.frames[0], &source_rest.triangles);
        assert!(rest_gap <= 2.0 * step, "{name}: rest pose {rest_gap} from the source (quantisation step {step})");
        let seq = load_gltf(&fixture(name), &GltfOptions::default()).unwrap();
        // gltfpack resamples the clip at 30 Hz and rounds its end up to a whole frame.
        assert!(
            seq.frames.len().abs_diff(source.frames.len()) <= 1,
            "{name}: {} frames, the source {}",
            seq.frames.len(),
            source.frames.len()
        );
        let mut worst = 0.0f32;
        for f in 0..seq.frames.len().min(source.frames.len()) {
            // Measured: at most 0.0007 of an extent of 1.53 (8-bit weights, 12-bit rotations).
            let d = surface_distance(&seq.frames[f], &seq.triangles, &source.frames[f], &source.triangles);
            worst = worst.max(d);
            assert!(d <= 1e-3 * extent, "{name} frame {f}: {d} from the source (extent {extent})");
        }
        eprintln!("{name} vs Fox: rest pose {rest_gap} (step {step}), animated frames up to {worst} (extent {extent})");
        decoded.push(seq);
    }
    // Both extension names carry the same quantised data.
    assert_eq!(decoded[0].frames, decoded[1].frames);
}

#[test]
fn truncated_or_oversized_meshopt_data_is_named() {
    let glb = std::fs::read(fixture("fox-meshopt-ext.glb")).unwrap();
    let ext = |view: usize| format!("/bufferViews/{view}/extensions/EXT_meshopt_compression");
    let fail = |edit: &dyn Fn(&mut Value)| load_gltf_bytes(&edited(&glb, edit), &Default::default()).unwrap_err();
    for view in [0, 1, 4, 8] {
        let e = fail(&|d| {
            let len = d.pointer(&format!("{}/byteLength", ext(view))).unwrap().as_u64().unwrap();
            *d.pointer_mut(&format!("{}/byteLength", ext(view))).unwrap() = json!(len / 2);
        });
        assert!(e.to_string().contains(&format!("bufferView {view} (EXT_meshopt_compression)")), "{e}");
    }
    // A count no file could need is refused before anything is allocated.
    let e = fail(&|d| {
        *d.pointer_mut(&format!("{}/count", ext(0))).unwrap() = json!(1u64 << 40);
        d["bufferViews"][0]["byteLength"] = json!(8u64 << 40);
    });
    assert!(matches!(e, MeshError::TooLarge { .. }) && e.to_string().contains("bufferView 0"), "{e}");
    // A count that does not fill the view, a stride the codec cannot have, a filter that does
    // not fit, an unknown mode, a range outside the buffer.
    for (key, value) in [
        ("count", json!(1000)),
        ("byteStride", json!(6)),
        ("filter", json!("QUATERNION")),
        ("mode", json!("SPARSE")),
        ("byteOffset", json!(1u64 << 33)),
    ] {
        let e = fail(&|d| *d.pointer_mut(&format!("{}/{key}", ext(1))).unwrap() = value.clone());
        assert!(e.to_string().contains("bufferView 1 (EXT_meshopt_compression)"), "{key}: {e}");
    }
}

/// Seeded bit flips in the compressed buffer (every view's compressed bytes): an error or a
/// valid mesh, never a panic. (Run locally with 5,000 cases: no panic.)
#[test]
fn flipped_meshopt_bits_give_an_error_or_a_valid_mesh() {
    let glb = std::fs::read(fixture("fox-meshopt-ext.glb")).unwrap();
    let (doc, _) = split(&glb);
    let len = doc["buffers"][0]["byteLength"].as_u64().unwrap() as usize;
    assert!(flip_bits(&glb, 0..len, 0x3E5_40F7, 120) > 0, "no flip was detected");
}
