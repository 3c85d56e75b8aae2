//! The GLB writer with an appearance: what the glTF reader gets back from it (UVs, colours,
//! materials, textures, images, one primitive per material), its normals, and its errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_mesh::appearance::{Appearance, Image, Material, Texture, TextureRef, TextureTransform};
use pmcodec_mesh::gltf_input::{GltfOptions, RiggedMesh, load_gltf};
use pmcodec_mesh::write::{glb_bytes, glb_bytes_with};
use pmcodec_mesh::{Sequence, TriMesh};
use std::path::PathBuf;

fn data(name: &str) -> PathBuf {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf")).join(name);
    assert!(path.is_file(), "{} is absent; these tests read the real models in ../shared/data beside the repository", path.display());
    path
}

fn rest(name: &str) -> Sequence {
    let seq = load_gltf(&data(name), &GltfOptions { frame_rate: 1.0, ..Default::default() }).expect(name);
    Sequence { frames: seq.frames[..1].to_vec(), ..seq }
}

/// Per triangle (in material order, then file order), its material and per corner its
/// position and UV, for comparing a mesh with what was read back.
fn corners(positions: &[Vec3], triangles: &[[u32; 3]], app: &Appearance) -> Vec<(u32, [[u32; 5]; 3])> {
    let mut out: Vec<(u32, [[u32; 5]; 3])> = triangles
        .iter()
        .zip(&app.corner_wedges)
        .enumerate()
        .map(|(t, (tri, cw))| {
            let corner = |i: usize| {
                let p = positions[tri[i] as usize].to_array().map(f32::to_bits);
                let uv = app.uv0.get(cw[i] as usize).map_or([0; 2], |u| u.map(f32::to_bits));
                [p[0], p[1], p[2], uv[0], uv[1]]
            };
            (app.material_of(t), [corner(0), corner(1), corner(2)])
        })
        .collect();
    out.sort_by_key(|c| c.0);
    out
}

#[test]
fn textured_fox_and_three_material_robot_round_trip() {
    for name in ["Fox.glb", "RobotExpressive.glb", "Horse.glb"] {
        let seq = rest(name);
        let app = seq.appearance.as_ref().unwrap();
        let mesh = seq.frame_mesh(0).unwrap();
        let bytes = glb_bytes_with(&mesh, Some(app)).unwrap();
        let back = RiggedMesh::from_bytes(&bytes).unwrap();
        let got = back.appearance.as_ref().unwrap();
        // Everything a material says, and the images byte for byte.
        assert_eq!(got.materials, app.materials, "{name}");
        assert_eq!(got.textures, app.textures, "{name}");
        assert_eq!(got.images, app.images, "{name}");
        assert_eq!((got.uv0.is_empty(), got.colors.is_empty()), (app.uv0.is_empty(), app.colors.is_empty()), "{name}");
        // One primitive per material, every triangle with its corners' positions and UVs.
        let doc: serde_json::Value = {
            let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
            serde_json::from_slice(&bytes[20..20 + len]).unwrap()
        };
        let used: std::collections::BTreeSet<u32> = app.triangle_material.iter().copied().collect();
        assert_eq!(doc["meshes"][0]["primitives"].as_array().unwrap().len(), used.len(), "{name}");
        assert_eq!(corners(&back.positions, &back.triangles, got), corners(&mesh.positions, &mesh.triangles, app), "{name}");
        // Colours round trip (the horse's are in [0, 1] already).
        let colour_of = |a: &Appearance| -> Vec<[u32; 4]> {
            let mut c: Vec<[u32; 4]> =
                a.corner_wedges.iter().flatten().filter_map(|&w| a.colors.get(w as usize)).map(|c| c.map(f32::to_bits)).collect();
            c.sort_unstable();
            c
        };
        assert_eq!(colour_of(got), colour_of(app), "{name}");
    }
}

#[test]
fn normals_follow_the_frame_and_the_input_creases() {
    // A tent of two triangles folded along the shared edge 0-1 (faces +Z and -Y). With one input normal per vertex
    // it is smooth; with per-face input normals (a crease) each face keeps its own normal.
    let mesh = TriMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(0.5, 1.0, 0.0), Vec3::new(0.5, 0.0, -1.0)],
        triangles: vec![[0, 1, 2], [1, 0, 3]],
    };
    let smooth = Appearance {
        corner_wedges: mesh.triangles.clone(),
        wedge_vertex: vec![0, 1, 2, 3],
        normals: vec![[0.0, 0.0, 1.0]; 4],
        ..Default::default()
    };
    let creased = Appearance {
        corner_wedges: vec![[0, 1, 2], [3, 4, 5]],
        wedge_vertex: vec![0, 1, 2, 1, 0, 3],
        normals: vec![[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        ..Default::default()
    };
    let normals_of = |app: &Appearance| -> Vec<Vec3> { pmcodec_mesh::glb::wedge_normals(&mesh.positions, &mesh.triangles, app) };
    let s = normals_of(&smooth);
    let shared = (Vec3::Z - Vec3::Y).normalize();
    assert!((s[0] - shared).length() < 1e-5 && (s[1] - shared).length() < 1e-5, "{s:?}");
    let c = normals_of(&creased);
    assert!((c[0] - Vec3::Z).length() < 1e-6 && (c[3] + Vec3::Y).length() < 1e-6, "{c:?}");
    // Written: six vertices for the creased tent, four for the smooth one.
    for (app, vertices) in [(&smooth, 4), (&creased, 6)] {
        let g = gltf::Gltf::from_slice(&glb_bytes_with(&mesh, Some(app)).unwrap()).unwrap();
        let prim = g.meshes().next().unwrap().primitives().next().unwrap();
        assert_eq!(prim.get(&gltf::Semantic::Positions).unwrap().count(), vertices);
        assert!(prim.material().index().is_none(), "no materials: glTF's default");
    }
}

#[test]
fn transforms_samplers_and_images_are_written_as_read() {
    let mesh = TriMesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], triangles: vec![[0, 1, 2]] };
    let transform = TextureTransform { offset: [0.5, 0.0], rotation: 0.25, scale: [2.0, 2.0], tex_coord: Some(1) };
    let app = Appearance {
        corner_wedges: vec![[0, 1, 2]],
        wedge_vertex: vec![0, 1, 2],
        uv0: vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
        uv1: vec![[0.5, 0.5]; 3],
        colors: vec![[1.0, 0.5, 0.0, 1.0]; 3],
        triangle_material: vec![1],
        materials: vec![
            Material::default(),
            Material {
                name: Some("skin".into()),
                base_color_texture: Some(TextureRef { texture: 0, tex_coord: 0, transform: Some(transform) }),
                double_sided: true,
                ..Material::default()
            },
        ],
        textures: vec![Texture { image: 0, sampler: None }],
        images: vec![Image { name: Some("s".into()), mime_type: "image/jpeg".into(), bytes: b"\xFF\xD8\xFF\xDBrest".to_vec() }],
        ..Default::default()
    };
    let bytes = glb_bytes_with(&mesh, Some(&app)).unwrap();
    let back = RiggedMesh::from_bytes(&bytes).unwrap();
    let got = back.appearance.unwrap();
    assert_eq!(got.materials, app.materials);
    assert_eq!(got.images, app.images);
    assert_eq!(got.triangle_material, [1]);
    assert_eq!((got.uv1, got.colors), (app.uv1.clone(), app.colors.clone()));
    let g = gltf::Gltf::from_slice(&bytes).unwrap();
    assert!(g.extensions_used().any(|e| e == "KHR_texture_transform"));
    // A mismatched appearance is refused with what is wrong, not written.
    let broken = Appearance { corner_wedges: vec![], ..app };
    let e = glb_bytes_with(&mesh, Some(&broken)).unwrap_err().to_string();
    assert!(e.contains("1 triangles but 0 corner wedge triples"), "{e}");
    // Without an appearance the output is what it always was.
    assert_eq!(glb_bytes_with(&mesh, None).unwrap(), glb_bytes(&mesh));
}
