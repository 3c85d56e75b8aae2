//! Input limits: every reader stops at the first vertex, triangle or frame past its
//! [`InputLimits`], while it parses, with an error that names the limit and the file and line
//! (or the primitive, or the animation).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::MeshError;
use pmcodec_mesh::gltf_input::{GltfOptions, load_gltf};
use pmcodec_mesh::obj::{load_obj_files_with, parse_obj, parse_obj_with, read_obj_with};
use pmcodec_mesh::{InputLimits, obj};
use std::fmt::Write;
use std::path::{Path, PathBuf};

fn limited(max_vertices: usize, max_triangles: usize, max_frames: usize, max_positions: usize) -> InputLimits {
    InputLimits { max_vertices, max_triangles, max_frames, max_positions }
}

/// A strip of `n` vertices (n - 2 triangles) as OBJ text.
fn strip(n: usize) -> String {
    let mut s = String::new();
    for i in 0..n {
        writeln!(s, "v {} {} 0", i / 2, i % 2).unwrap();
    }
    for i in 1..n - 1 {
        writeln!(s, "f {} {} {}", i, i + 1, i + 2).unwrap();
    }
    s
}

fn limit_of(e: &MeshError) -> (&str, &'static str) {
    match e {
        MeshError::LimitExceeded { at, limit, .. } => (at.as_str(), limit),
        other => panic!("expected a limit error, got {other}"),
    }
}

/// The report's case, scaled to the default limit: OBJ text of one vertex more than the
/// default vertex limit (the server's zip of 10-million-vertex frames) stops at that vertex.
#[test]
fn an_obj_past_the_default_vertex_limit_stops_at_that_vertex() {
    let max = InputLimits::default().max_vertices;
    let text = "v 0 0 0\n".repeat(max + 1);
    let e = parse_obj(&text, Path::new("huge.obj")).expect_err("more vertices than the default limit");
    assert_eq!(limit_of(&e), (format!("huge.obj:{}", max + 1).as_str(), "max_vertices"));
    assert!(e.to_string().contains(&format!("max_vertices = {max}")), "{e}");
}

#[test]
fn obj_vertices_triangles_and_polygons_stop_at_their_line() {
    let l = limited(10, 5, 10, 1000);
    // 11 vertices: line 11 is the first past the limit.
    let e = parse_obj_with(&strip(11), Path::new("a.obj"), &l, 1).unwrap_err();
    assert_eq!(limit_of(&e), ("a.obj:11", "max_vertices"));
    // 8 vertices, 6 triangles: the sixth face (line 8 + 6) is past the limit.
    let e = parse_obj_with(&strip(8), Path::new("a.obj"), &l, 1).unwrap_err();
    assert_eq!(limit_of(&e), ("a.obj:14", "max_triangles"));
    // One polygon that fans into 7 triangles.
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4 1 2 3 4 1\n";
    let e = parse_obj_with(text, Path::new("p.obj"), &l, 1).unwrap_err();
    assert_eq!(limit_of(&e), ("p.obj:5", "max_triangles"));
    // Within the limits it parses.
    assert_eq!(parse_obj_with(&strip(7), Path::new("a.obj"), &l, 1).unwrap().triangles.len(), 5);
}

#[test]
fn the_positions_limit_is_shared_by_the_frames_of_a_sequence() {
    let l = limited(100, 100, 10, 30);
    // 4 frames of 8 vertices are 32 positions: each frame may have 7.
    let e = parse_obj_with(&strip(8), Path::new("f1.obj"), &l, 4).unwrap_err();
    assert_eq!(limit_of(&e), ("f1.obj:8", "max_positions"));
    assert!(e.to_string().contains("4 frames of more than 7 vertices"), "{e}");
    assert!(parse_obj_with(&strip(7), Path::new("f1.obj"), &l, 4).is_ok());
}

struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("pmcodec-limits-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn obj_sequences_check_the_frame_count_before_reading_any_file() {
    let dir = TempDir::new("frames");
    // Files that do not exist: a reader that opened one would fail with an I/O error instead.
    let paths: Vec<PathBuf> = (0..4).map(|i| dir.0.join(format!("f{i}.obj"))).collect();
    let e = load_obj_files_with(&paths, 30.0, &limited(100, 100, 3, 1000)).unwrap_err();
    assert_eq!(limit_of(&e).1, "max_frames");
    assert!(e.to_string().contains("4 frames"), "{e}");

    for p in &paths {
        std::fs::write(p, strip(8)).unwrap();
    }
    let e = load_obj_files_with(&paths, 30.0, &limited(100, 100, 10, 28)).unwrap_err();
    let at = format!("{}:8", paths[0].display());
    assert_eq!(limit_of(&e), (at.as_str(), "max_positions"));
    let seq = load_obj_files_with(&paths, 30.0, &limited(100, 100, 10, 32)).unwrap();
    assert_eq!((seq.frame_count(), seq.vertex_count()), (4, 8));
    let e = obj::load_obj_sequence_with(&dir.0, 30.0, &limited(100, 100, 2, 1000)).unwrap_err();
    assert_eq!(limit_of(&e).1, "max_frames");
}

#[test]
fn files_are_read_a_line_at_a_time_with_the_same_locations() {
    let dir = TempDir::new("lines");
    let path = dir.0.join("a.obj");
    std::fs::write(&path, strip(11)).unwrap();
    let e = read_obj_with(&path, &limited(10, 100, 1, 1000), 1).unwrap_err();
    assert_eq!(limit_of(&e), (format!("{}:11", path.display()).as_str(), "max_vertices"));
    // An index past the last vertex is only known at the end, but is reported at its line.
    std::fs::write(&path, "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\nf 1 2 9\r\nf 3 2 1\r\n").unwrap();
    let e = read_obj_with(&path, &InputLimits::default(), 1).unwrap_err().to_string();
    assert!(e.contains(&format!("{}:5:", path.display())) && e.contains("vertex 9"), "{e}");
    std::fs::write(&path, b"v 0 0 0\nv 1 \xff 0\n").unwrap();
    let e = read_obj_with(&path, &InputLimits::default(), 1).unwrap_err().to_string();
    assert!(e.contains(&format!("{}:2:", path.display())) && e.contains("UTF-8"), "{e}");
}

/// A real file from ../shared/data/gltf; the test fails with a message when it is absent.
fn data(name: &str) -> PathBuf {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf")).join(name);
    assert!(path.is_file(), "{} is absent; these tests read the real models in ../shared/data beside the repository", path.display());
    path
}

#[test]
fn gltf_vertices_triangles_frames_and_positions_are_limited() {
    let fox = data("Fox.glb");
    let load = |limits: InputLimits, frame_rate: f32| load_gltf(&fox, &GltfOptions { frame_rate, limits, ..Default::default() });
    let base = load(InputLimits::default(), 30.0).expect("the fox loads under the default limits");
    let (n, t, f) = (base.vertex_count(), base.triangles.len(), base.frame_count());

    let e = load(limited(1000, 1 << 20, 1000, 1 << 30), 30.0).unwrap_err();
    assert_eq!(limit_of(&e), ("mesh 0 primitive 0 POSITION", "max_vertices"));
    let e = load(limited(1 << 20, t - 1, 1000, 1 << 30), 30.0).unwrap_err();
    assert_eq!(limit_of(&e), ("mesh 0 primitive 0 indices", "max_triangles"));
    // The first animation at 30 frames per second has f frames; at 1000 it has about 33x as many.
    let e = load(limited(1 << 20, 1 << 20, f, 1 << 30), 1000.0).unwrap_err();
    assert_eq!(limit_of(&e).1, "max_frames");
    assert!(e.to_string().contains("1000 frames per second"), "{e}");
    let e = load(limited(1 << 20, 1 << 20, 1 << 20, f * n - 1), 30.0).unwrap_err();
    assert_eq!(limit_of(&e).1, "max_positions");
    let exact = load(limited(1 << 20, t, f, f * n), 30.0).expect("limits equal to the file's sizes are met");
    assert_eq!(exact.frames, base.frames);
}
