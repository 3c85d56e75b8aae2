//! OBJ sequences with texture coordinates, normals and materials: the first frame's records
//! become the sequence's appearance; bad records are clear errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::appearance::AlphaMode;
use pmcodec_mesh::obj::{load_obj_sequence, parse_obj_appearance};
use pmcodec_mesh::{InputLimits, samples};
use std::fmt::Write;
use std::path::{Path, PathBuf};

struct TempDir(PathBuf);
impl TempDir {
    fn new(name: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!("pmcodec-obj-appearance-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("temp dir");
        TempDir(p)
    }
}
impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Writes the textured cloth as an OBJ sequence: frame 0 with `vt`, `mtllib` and `usemtl`,
/// later frames with positions and faces only.
fn write_textured_sequence(dir: &Path, frames: u32) -> pmcodec_mesh::Sequence {
    let seq = samples::textured_cloth(9, 6, frames, 16);
    let a = seq.appearance.as_ref().expect("appearance");
    std::fs::write(
        dir.join("cloth.mtl"),
        "# two materials\nnewmtl checker\nKd 1 1 1\nmap_Kd -s 1 1 1 tex/checker.png\n\nnewmtl orange\nKd 1 0.45 0.1\nd 0.9\n",
    )
    .unwrap();
    std::fs::create_dir_all(dir.join("tex")).unwrap();
    std::fs::write(dir.join("tex/checker.png"), &a.images[0].bytes).unwrap();
    for (f, frame) in seq.frames.iter().enumerate() {
        let mut s = String::new();
        if f == 0 {
            s.push_str("mtllib cloth.mtl\n");
        }
        for p in frame {
            writeln!(s, "v {} {} {}", p.x, p.y, p.z).unwrap();
        }
        if f == 0 {
            for uv in &a.uv0 {
                writeln!(s, "vt {} {}", uv[0], 1.0 - uv[1]).unwrap();
            }
        }
        let mut current = u32::MAX;
        for (t, tri) in seq.triangles.iter().enumerate() {
            if f == 0 && a.triangle_material[t] != current {
                current = a.triangle_material[t];
                writeln!(s, "usemtl {}", ["checker", "orange"][current as usize]).unwrap();
            }
            if f == 0 {
                let w = a.corner_wedges[t];
                writeln!(s, "f {}/{} {}/{} {}/{}", tri[0] + 1, w[0] + 1, tri[1] + 1, w[1] + 1, tri[2] + 1, w[2] + 1).unwrap();
            } else {
                writeln!(s, "f {} {} {}", tri[0] + 1, tri[1] + 1, tri[2] + 1).unwrap();
            }
        }
        std::fs::write(dir.join(format!("cloth{f}.obj")), s).unwrap();
    }
    seq
}

#[test]
fn first_frame_gives_uvs_materials_and_textures() {
    let dir = TempDir::new("ok");
    let want = write_textured_sequence(&dir.0, 3);
    let seq = load_obj_sequence(&dir.0, 30.0).expect("reads");
    assert_eq!(seq.frame_count(), 3);
    let got = seq.appearance.as_ref().expect("appearance");
    let a = want.appearance.as_ref().unwrap();
    assert_eq!(got.wedge_count(), a.wedge_count());
    // Every corner's UV and material survive (wedges may be numbered differently).
    for t in 0..seq.triangles.len() {
        assert_eq!(got.triangle_material[t], a.triangle_material[t], "triangle {t}");
        for i in 0..3 {
            let (g, w) = (got.uv0[got.corner_wedges[t][i] as usize], a.uv0[a.corner_wedges[t][i] as usize]);
            assert!((g[0] - w[0]).abs() < 1e-5 && (g[1] - w[1]).abs() < 1e-5, "triangle {t} corner {i}: {g:?} vs {w:?}");
        }
    }
    assert!(got.normals.is_empty() && got.colors.is_empty());
    assert_eq!(got.materials.len(), 2);
    assert_eq!(got.materials[0].name.as_deref(), Some("checker"));
    assert_eq!(got.materials[0].base_color_texture.map(|r| r.texture), Some(0));
    assert_eq!(got.materials[1].base_color_factor, [1.0, 0.45, 0.1, 0.9]);
    assert_eq!(got.materials[1].alpha_mode, AlphaMode::Blend);
    assert_eq!(got.images.len(), 1);
    assert_eq!(got.images[0].bytes, a.images[0].bytes);
    assert_eq!(got.images[0].mime_type, "image/png");
}

#[test]
fn normals_give_wedges_and_faces_without_them_are_flat() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 2\nvn 0 1 0\nf 1//1 2//1 3//1\nf 2//2 4//2 3//2\nf 1 3 2\n";
    let frame = parse_obj_appearance(text, Path::new("n.obj"), &InputLimits::default(), 1).expect("parses");
    assert_eq!(frame.attributes.normals.len(), 2);
    let dir = TempDir::new("normals");
    std::fs::write(dir.0.join("n.obj"), text).unwrap();
    let seq = load_obj_sequence(&dir.0.join("n.obj"), 30.0).expect("reads");
    let a = seq.appearance.expect("appearance");
    // Vertices 1 and 2 (0-based) carry two normals: two wedges each; the third face, without
    // normals, gets three wedges of its own with its face normal (0, 0, -1).
    assert_eq!(a.wedge_count(), 3 + 3 + 3);
    assert_eq!(a.normals[a.corner_wedges[0][0] as usize], [0.0, 0.0, 1.0]);
    assert_eq!(a.normals[a.corner_wedges[2][0] as usize], [0.0, 0.0, -1.0]);
    assert!(a.materials.is_empty() && a.uv0.is_empty());
}

#[test]
fn bad_appearance_input_is_named() {
    let cases: [(&str, &str, Option<&str>, &[&str]); 6] = [
        (
            "nomtl",
            "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
            None,
            &["missing.mtl", "material library named at", "t.obj:1"],
        ),
        (
            "unknown",
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl b\nf 1 2 3\n",
            Some("newmtl a\nKd 1 0 0\n"),
            &["t.obj:5", "\"b\"", "no such material in m.mtl"],
        ),
        (
            "notex",
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
            Some("newmtl a\nmap_Kd gone.png\n"),
            &["gone.png", "m.mtl:2", "texture"],
        ),
        (
            "vtrange",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
            None,
            &["t.obj:5", "texture coordinate (vt) 2 but the file has 1"],
        ),
        ("vtnan", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 NaN\nf 1/1 2/1 3/1\n", None, &["t.obj:4", "not a finite number"]),
        ("nolib", "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n", None, &["t.obj:4", "no material library"]),
    ];
    for (name, obj, mtl, wants) in cases {
        let dir = TempDir::new(name);
        std::fs::write(dir.0.join("t.obj"), obj).unwrap();
        if let Some(mtl) = mtl {
            std::fs::write(dir.0.join("m.mtl"), mtl).unwrap();
        }
        let e = load_obj_sequence(&dir.0.join("t.obj"), 30.0).expect_err(name).to_string();
        for want in wants {
            assert!(e.contains(want), "{name}: {e:?} lacks {want:?}");
        }
    }
    // An image that is neither PNG nor JPEG.
    let dir = TempDir::new("notimage");
    std::fs::write(dir.0.join("t.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    std::fs::write(dir.0.join("m.mtl"), "newmtl a\nmap_Kd x.png\n").unwrap();
    std::fs::write(dir.0.join("x.png"), "GIF89a").unwrap();
    let e = load_obj_sequence(&dir.0.join("t.obj"), 30.0).unwrap_err().to_string();
    assert!(e.contains("x.png") && e.contains("neither a PNG nor a JPEG"), "{e}");
}
