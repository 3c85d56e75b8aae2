//! Writers: OBJ and GLB round trips, the GLB container layout, empty meshes, and no half files
//! on failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_mesh::TriMesh;
use pmcodec_mesh::write::{glb_bytes, vertex_normals, write_atomic, write_glb, write_mesh_file, write_obj};
use std::path::{Path, PathBuf};

fn tetra() -> TriMesh {
    TriMesh {
        positions: vec![Vec3::ZERO, Vec3::new(1.5, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.1, 0.2, -2.25)],
        triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
    }
}

/// Coordinates that a lossy formatter would not bring back bit for bit.
fn awkward() -> TriMesh {
    TriMesh {
        positions: vec![
            Vec3::new(0.1, -0.2, 1.0 / 3.0),
            Vec3::new(1e-30, -0.0, 16_777_217.0),
            Vec3::new(f32::MIN_POSITIVE, 1.0e-45, -3.4e38),
            Vec3::new(123_456.79, -9.876_543e-7, 2.0f32.sqrt()),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// A reader written for the test: `v x y z` and 1-based `f a b c`, nothing else accepted, so
/// the test checks what the writer emits and not what a lenient parser forgives.
fn parse_obj_by_hand(text: &str) -> TriMesh {
    let mut m = TriMesh::default();
    for line in text.lines() {
        let words: Vec<&str> = line.split(' ').collect();
        match words.as_slice() {
            ["v", x, y, z] => m.positions.push(Vec3::new(x.parse().unwrap(), y.parse().unwrap(), z.parse().unwrap())),
            ["f", a, b, c] => {
                let i = |s: &str| s.parse::<u32>().unwrap().checked_sub(1).expect("1-based");
                m.triangles.push([i(a), i(b), i(c)]);
            }
            [first, ..] if first.starts_with('#') => {}
            _ => panic!("unexpected OBJ line {line:?}"),
        }
    }
    m
}

fn obj_text(m: &TriMesh) -> String {
    let mut buf = Vec::new();
    write_obj(&mut buf, m).unwrap();
    String::from_utf8(buf).unwrap()
}

#[test]
fn obj_round_trips_bit_for_bit() {
    for m in [tetra(), awkward()] {
        let back = parse_obj_by_hand(&obj_text(&m));
        let bits = |m: &TriMesh| m.positions.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&m));
        assert_eq!(back.triangles, m.triangles);
    }
}

#[test]
fn obj_faces_are_one_based() {
    let text = obj_text(&tetra());
    assert!(text.lines().any(|l| l == "f 1 3 2"), "{text}");
    assert!(text.lines().all(|l| !l.starts_with("f ") || !l.split(' ').any(|w| w == "0")));
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 4);
}

#[test]
fn obj_of_an_empty_mesh_is_just_a_comment() {
    assert_eq!(obj_text(&TriMesh::default()), "# pmcodec: 0 vertices, 0 triangles\n");
    let points = TriMesh { positions: vec![Vec3::ONE], triangles: vec![] };
    assert_eq!(parse_obj_by_hand(&obj_text(&points)), points);
}

/// The parsed document, the BIN chunk, and the mesh read back through the `gltf` crate.
fn read_glb(bytes: &[u8]) -> (gltf::Gltf, TriMesh) {
    let g = gltf::Gltf::from_slice(bytes).expect("a valid GLB");
    let Some(mesh) = g.meshes().next() else {
        return (g, TriMesh::default());
    };
    let blob = g.blob.clone().expect("a BIN chunk");
    let prim = mesh.primitives().next().expect("a primitive");
    let reader = prim.reader(|_| Some(&blob[..]));
    let positions = reader.read_positions().expect("positions").map(Vec3::from_array).collect();
    let idx: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    let triangles = idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    (g, TriMesh { positions, triangles })
}

#[test]
fn glb_round_trips_through_the_gltf_crate() {
    for m in [tetra(), awkward()] {
        let (g, back) = read_glb(&glb_bytes(&m));
        assert_eq!(back, m);
        assert_eq!(g.scenes().count(), 1);
        assert_eq!(g.nodes().count(), 1);
        assert_eq!(g.meshes().count(), 1);
        assert_eq!(g.default_scene().map(|s| s.nodes().count()), Some(1));
        assert_eq!(g.as_json().asset.generator.as_deref(), Some("pmcodec"));
        let prim = g.meshes().next().unwrap().primitives().next().unwrap();
        assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
        let pos = prim.get(&gltf::Semantic::Positions).unwrap();
        assert_eq!((pos.data_type(), pos.dimensions()), (gltf::accessor::DataType::F32, gltf::accessor::Dimensions::Vec3));
        let idx = prim.indices().unwrap();
        assert_eq!(idx.data_type(), gltf::accessor::DataType::U16);
        assert_eq!(idx.count(), m.triangles.len() * 3);
    }
}

/// A fan of `n` triangles over `n + 2` vertices.
fn fan(n: u32) -> TriMesh {
    TriMesh {
        positions: (0..n + 2).map(|i| Vec3::new((i % 97) as f32, (i / 97) as f32, (i % 5) as f32)).collect(),
        triangles: (0..n).map(|i| [0, i + 1, i + 2]).collect(),
    }
}

#[test]
fn glb_indices_are_16_bit_up_to_65535_vertices() {
    // 65,535 vertices: the largest index is 65,534 (65,535 is glTF's primitive restart value).
    for (n, want) in [(65_533u32, gltf::accessor::DataType::U16), (65_534, gltf::accessor::DataType::U32)] {
        let m = fan(n);
        let (g, back) = read_glb(&glb_bytes(&m));
        assert_eq!(back, m, "{} vertices", m.positions.len());
        let prim = g.meshes().next().unwrap().primitives().next().unwrap();
        assert_eq!(prim.indices().unwrap().data_type(), want, "{} vertices", m.positions.len());
    }
}

#[test]
fn glb_position_min_max_are_the_bounds() {
    let m = tetra();
    let (g, _) = read_glb(&glb_bytes(&m));
    let prim = g.meshes().next().unwrap().primitives().next().unwrap();
    let bb = prim.bounding_box();
    assert_eq!(bb.min, [0.0, 0.0, -2.25]);
    assert_eq!(bb.max, [1.5, 1.0, 0.0]);
    // And exactly the f32 bounds for values without a short decimal form.
    let a = awkward();
    let (g, _) = read_glb(&glb_bytes(&a));
    let bb = g.meshes().next().unwrap().primitives().next().unwrap().bounding_box();
    let (lo, hi) = a.bounds().unwrap();
    assert_eq!((bb.min, bb.max), (lo.to_array(), hi.to_array()));
}

#[test]
fn glb_normals_are_unit_area_weighted_and_zero_safe() {
    // A flat counter-clockwise quad in the XY plane, a vertex used by no face, and a face of
    // zero area on its own vertices.
    let m = TriMesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::Y,
            Vec3::splat(7.0),
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(6.0, 0.0, 0.0),
            Vec3::new(7.0, 0.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3], [5, 6, 7]],
    };
    let bytes = glb_bytes(&m);
    let g = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = g.blob.clone().unwrap();
    let prim = g.meshes().next().unwrap().primitives().next().unwrap();
    let normals: Vec<Vec3> = prim.reader(|_| Some(&blob[..])).read_normals().unwrap().map(Vec3::from_array).collect();
    assert_eq!(normals, vertex_normals(&m));
    assert_eq!(normals.len(), 8);
    for n in &normals[..4] {
        assert!((*n - Vec3::Z).length() < 1e-6, "{n}");
    }
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-6 && n.is_finite()));
    // Area weighting: a big face outweighs a small one at their shared vertex.
    let tent = TriMesh {
        positions: vec![Vec3::ZERO, Vec3::new(0.0, 10.0, 0.0), Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0)],
        triangles: vec![[0, 2, 1], [0, 1, 3]],
    };
    let n0 = vertex_normals(&tent)[0];
    // Faces: 50 units of area facing +Z, 5 facing +X: the normal is (5, 0, 50) normalised.
    assert!((n0 - Vec3::new(5.0, 0.0, 50.0).normalize()).length() < 1e-6, "{n0}");
}

/// Reads the GLB container by hand: header, chunk types, lengths, padding, view alignment.
#[test]
fn glb_container_layout_follows_the_spec() {
    let mut json_padded = 0;
    for m in [tetra(), awkward(), TriMesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], triangles: vec![[0, 1, 2]] }] {
        let b = glb_bytes(&m);
        let word = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize;
        assert_eq!(&b[0..4], b"glTF");
        assert_eq!(word(4), 2);
        assert_eq!(word(8), b.len());
        let json_len = word(12);
        assert_eq!(&b[16..20], b"JSON");
        assert_eq!(json_len % 4, 0);
        let json = std::str::from_utf8(&b[20..20 + json_len]).unwrap();
        // Padding is spaces after the closing brace, fewer than four.
        let trimmed = json.trim_end_matches(' ');
        assert!(trimmed.ends_with('}') && json.len() - trimmed.len() < 4);
        json_padded += usize::from(json.len() != trimmed.len());
        let doc: serde_json::Value = serde_json::from_str(json).unwrap();
        let bin_at = 20 + json_len;
        let bin_len = word(bin_at);
        assert_eq!(&b[bin_at + 4..bin_at + 8], b"BIN\0");
        assert_eq!(bin_len % 4, 0);
        assert_eq!(bin_at + 8 + bin_len, b.len());
        let declared = doc["buffers"][0]["byteLength"].as_u64().unwrap() as usize;
        assert!(declared <= bin_len && bin_len - declared < 4);
        assert!(b[bin_at + 8 + declared..].iter().all(|&x| x == 0));
        for view in doc["bufferViews"].as_array().unwrap() {
            let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
            assert_eq!(offset % 4, 0, "{view}");
            assert!(offset + view["byteLength"].as_u64().unwrap() as usize <= declared);
        }
    }
    // The padding path ran. (BIN data is all 4-byte elements, so it never needs padding.)
    assert!(json_padded > 0);
}

#[test]
fn empty_meshes_give_a_valid_glb_with_an_empty_node() {
    let no_triangles = TriMesh { positions: vec![Vec3::ONE, Vec3::X], triangles: vec![] };
    for m in [TriMesh::default(), no_triangles] {
        let bytes = glb_bytes(&m);
        assert_eq!(bytes.len() % 4, 0);
        let (g, back) = read_glb(&bytes);
        assert!(g.blob.is_none());
        assert_eq!((g.meshes().count(), g.buffers().count(), g.accessors().count()), (0, 0, 0));
        assert_eq!(g.scenes().count(), 1);
        let scene = g.default_scene().expect("a default scene");
        let nodes: Vec<_> = scene.nodes().collect();
        assert!(nodes.len() == 1 && nodes[0].mesh().is_none() && nodes[0].children().count() == 0);
        assert_eq!(back, TriMesh::default());
    }
}

#[test]
fn write_glb_writes_the_same_bytes() {
    let mut out = Vec::new();
    write_glb(&mut out, &tetra()).unwrap();
    assert_eq!(out, glb_bytes(&tetra()));
}

/// A fresh folder per test, removed at the end.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("pmcodec-write-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn entries(&self) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(&self.0).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn mesh_files_are_chosen_by_extension() {
    let dir = TempDir::new("ext");
    let m = tetra();
    write_mesh_file(&dir.0.join("a.obj"), &m).unwrap();
    write_mesh_file(&dir.0.join("b.GLB"), &m).unwrap();
    assert_eq!(parse_obj_by_hand(&std::fs::read_to_string(dir.0.join("a.obj")).unwrap()), m);
    assert_eq!(read_glb(&std::fs::read(dir.0.join("b.GLB")).unwrap()).1, m);
    assert_eq!(dir.entries(), ["a.obj", "b.GLB"]);

    let err = write_mesh_file(&dir.0.join("c.stl"), &m).unwrap_err().to_string();
    assert!(err.contains("unknown extension") && err.contains(".stl"), "{err}");
    let err = write_mesh_file(&dir.0.join("noext"), &m).unwrap_err().to_string();
    assert!(err.contains("no extension"), "{err}");
    assert_eq!(dir.entries(), ["a.obj", "b.GLB"]);
}

#[test]
fn a_failed_write_leaves_no_file_and_no_temporary() {
    let dir = TempDir::new("fail");
    // The rename fails: the target is a non-empty directory. The temporary file was created and
    // written by then, so this checks that it is cleaned up.
    let blocked = dir.0.join("blocked.obj");
    std::fs::create_dir(&blocked).unwrap();
    std::fs::write(blocked.join("keep"), b"x").unwrap();
    assert!(write_mesh_file(&blocked, &tetra()).is_err());
    assert_eq!(dir.entries(), ["blocked.obj"]);
    assert!(blocked.join("keep").exists());
    // The folder does not exist: nothing can be created at all.
    assert!(write_mesh_file(&dir.0.join("missing").join("t.obj"), &tetra()).is_err());
    assert_eq!(dir.entries(), ["blocked.obj"]);
    // A path that names no file.
    assert!(write_atomic(Path::new("/"), b"x").is_err());
}

#[test]
fn a_rewrite_replaces_the_file_whole() {
    let dir = TempDir::new("replace");
    let path = dir.0.join("f.obj");
    write_mesh_file(&path, &tetra()).unwrap();
    write_mesh_file(&path, &awkward()).unwrap();
    assert_eq!(parse_obj_by_hand(&std::fs::read_to_string(&path).unwrap()), awkward());
    assert_eq!(dir.entries(), ["f.obj"]);
    // Concurrent writers of one path each produce a whole file; the last rename wins.
    std::thread::scope(|s| {
        for _ in 0..8 {
            s.spawn(|| write_mesh_file(&path, &tetra()).unwrap());
        }
    });
    assert_eq!(parse_obj_by_hand(&std::fs::read_to_string(&path).unwrap()), tetra());
    assert_eq!(dir.entries(), ["f.obj"]);
}
