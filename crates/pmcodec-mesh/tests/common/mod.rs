//! Helpers the glTF input tests share: the real models' paths, and generated glTF files (binary
//! data with its views and accessors, the GLB container, base64 for data URIs). The GLB is
//! assembled here by hand rather than by the crate's writer, so that the reader is tested
//! against an independent encoding of the format (glTF 2.0, "Binary glTF Layout").
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::gltf_input::{AnimationSelector, GltfOptions, load_gltf_bytes};
use pmcodec_mesh::{MeshError, Sequence};
use serde_json::{Value, json};
use std::path::PathBuf;

/// A real file from ../shared/data/gltf; the test fails with a message when it is absent.
pub fn data(name: &str) -> PathBuf {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf")).join(name);
    assert!(path.is_file(), "{} is absent; these tests read the real models in ../shared/data beside the repository", path.display());
    path
}

/// Binary data for generated files: each `add` appends one tightly packed accessor.
#[derive(Default)]
pub struct Bin {
    pub bytes: Vec<u8>,
    pub views: Vec<Value>,
    pub accessors: Vec<Value>,
}

impl Bin {
    /// Appends `data` as a buffer view on a 4-byte boundary.
    pub fn view(&mut self, data: &[u8]) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()}));
        self.bytes.extend_from_slice(data);
        self.views.len() - 1
    }
    pub fn add(&mut self, data: &[u8], count: usize, ty: &str, component: u32, normalized: bool) -> usize {
        let view = self.view(data);
        let mut acc = json!({"bufferView": view, "componentType": component, "count": count, "type": ty});
        if normalized {
            acc["normalized"] = json!(true);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }
    pub fn f32(&mut self, v: &[f32], ty: &str) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.add(&bytes, v.len() / dims(ty), ty, 5126, false)
    }
    pub fn u16(&mut self, v: &[u16], ty: &str) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.add(&bytes, v.len() / dims(ty), ty, 5123, false)
    }
    pub fn u8(&mut self, v: &[u8], ty: &str, normalized: bool) -> usize {
        self.add(v, v.len() / dims(ty), ty, 5121, normalized)
    }
    pub fn i16_normalized(&mut self, v: &[i16], ty: &str) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.add(&bytes, v.len() / dims(ty), ty, 5122, true)
    }
    /// `doc` (scenes, nodes, meshes, ...) completed with asset, buffer, views and accessors.
    pub fn document(&self, mut doc: Value) -> Value {
        doc["asset"] = json!({"version": "2.0"});
        doc["buffers"] = json!([{"byteLength": self.bytes.len()}]);
        doc["bufferViews"] = Value::Array(self.views.clone());
        doc["accessors"] = Value::Array(self.accessors.clone());
        doc
    }
    pub fn glb(&self, doc: Value) -> Vec<u8> {
        glb(&self.document(doc), &self.bytes)
    }
}

/// Components per element of an accessor type.
pub fn dims(ty: &str) -> usize {
    match ty {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        "MAT4" => 16,
        _ => panic!("{ty}"),
    }
}

/// A GLB of `doc` and `bin`: header, JSON chunk (space padded), BIN chunk (zero padded).
pub fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(doc).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + j.len() + 8 + b.len()) as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&b);
    out
}

/// Standard base64 (RFC 4648 §4, padded), for `data:` URIs.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let n = chunk.iter().enumerate().fold(0u32, |acc, (i, &b)| acc | (u32::from(b) << (16 - 8 * i)));
        for i in 0..4 {
            out.push(if i <= chunk.len() { ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char } else { '=' });
        }
    }
    out
}

pub const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

// ---- generated animated files and their loading (gltf_input.rs, gltf_errors.rs) ----------------

pub fn opts(animation: Option<AnimationSelector>, frame_rate: f32, weld: bool) -> GltfOptions {
    GltfOptions { animation, frame_rate, weld, ..Default::default() }
}

/// A triangle on node 0 with one morph target (vertex 2 moves +1 in z; weight 0 by default) and
/// an animation "move" with one channel driving `path` of node 0.
pub fn animated_triangle(path: &str, interpolation: &str, times: &[f32], values: &[f32]) -> (Bin, Value) {
    let mut bin = Bin::default();
    let pos = bin.f32(&TRIANGLE, "VEC3");
    let delta = bin.f32(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], "VEC3");
    let input = bin.f32(times, "SCALAR");
    let ty = match path {
        "rotation" => "VEC4",
        "weights" => "SCALAR",
        _ => "VEC3",
    };
    let output = bin.f32(values, ty);
    let doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "targets": [{"POSITION": delta}]}], "weights": [0.0]}],
        "animations": [{"name": "move", "channels": [{"sampler": 0, "target": {"node": 0, "path": path}}],
                        "samplers": [{"input": input, "output": output, "interpolation": interpolation}]}]
    });
    (bin, doc)
}

pub fn load(bytes: &[u8], fps: f32) -> Result<Sequence, MeshError> {
    load_gltf_bytes(bytes, &opts(None, fps, false))
}

/// A strip of three quads along x (vertices at x = 0, 1, 2, 3; y = 0 or 0.1) as a TRIANGLE_STRIP,
/// skinned to joint 0 (root, at the origin) and joint 1 (its child at x = 1). Vertices at x = 1
/// are split half and half; beyond, they follow joint 1. Joint 1 turns 90 degrees about z over
/// one second. The skinned node itself is moved by 100 in x (which glTF says to ignore), and a
/// rigid triangle hangs from joint 1 one unit further along x.
pub fn bent_strip() -> (Bin, Value) {
    let mut bin = Bin::default();
    let pos: Vec<f32> = (0..8).flat_map(|i| [(i / 2) as f32, (i % 2) as f32 * 0.1, 0.0]).collect();
    let pos = bin.f32(&pos, "VEC3");
    let joints: Vec<u16> = (0..8).flat_map(|i| if i / 2 == 0 { [0, 0, 0, 0] } else { [0, 1, 0, 0] }).collect();
    let joints = bin.u16(&joints, "VEC4");
    // Normalised u8 weights that do not sum to one (200 alone; 100 + 100): normalised on read.
    let weights: Vec<u8> = (0..8)
        .flat_map(|i| match i / 2 {
            0 => [200, 0, 0, 0],
            1 => [100, 100, 0, 0],
            _ => [0, 200, 0, 0],
        })
        .collect();
    let weights = bin.u8(&weights, "VEC4", true);
    #[rustfmt::skip]
    let ibm = bin.f32(&[
        1., 0., 0., 0.,  0., 1., 0., 0.,  0., 0., 1., 0.,  0., 0., 0., 1.,
        1., 0., 0., 0.,  0., 1., 0., 0.,  0., 0., 1., 0.,  -1., 0., 0., 1.,
    ], "MAT4");
    let rigid = bin.f32(&TRIANGLE, "VEC3");
    let times = bin.f32(&[0.0, 1.0], "SCALAR");
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let rots = bin.f32(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, s, s], "VEC4");
    let doc = json!({
        "scene": 0, "scenes": [{"nodes": [0, 2]}],
        "nodes": [
            {"children": [1]},
            {"translation": [1.0, 0.0, 0.0], "children": [3]},
            {"mesh": 0, "skin": 0, "translation": [100.0, 0.0, 0.0]},
            {"mesh": 1, "translation": [1.0, 0.0, 0.0]}
        ],
        "skins": [{"joints": [0, 1], "inverseBindMatrices": ibm}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": pos, "JOINTS_0": joints, "WEIGHTS_0": weights}, "mode": 5}]},
            {"primitives": [{"attributes": {"POSITION": rigid}}]}
        ],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}],
                        "samplers": [{"input": times, "output": rots, "interpolation": "LINEAR"}]}]
    });
    (bin, doc)
}
