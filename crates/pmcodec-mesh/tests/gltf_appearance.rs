//! Appearance input (UVs, normals, colours, materials, textures, images) on the real models and
//! on small generated files, and its bad-input errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::appearance::{AlphaMode, Appearance};
use pmcodec_mesh::gltf_input::{GltfOptions, RiggedMesh, load_gltf, load_gltf_bytes};
use pmcodec_mesh::{MeshError, Sequence};
use serde_json::{Value, json};
use std::collections::BTreeSet;

use crate::common;
use common::{Bin, base64, data, glb};

/// Checks what every appearance must satisfy and returns it.
fn checked(seq: &Sequence) -> &Appearance {
    seq.validate().expect("valid sequence");
    let app = seq.appearance.as_ref().expect("the glTF reader fills the appearance");
    assert_eq!(app.corner_wedges.len(), seq.triangles.len());
    // Every wedge is used by some corner.
    let used: BTreeSet<u32> = app.corner_wedges.iter().flatten().copied().collect();
    assert_eq!(used.len(), app.wedge_count());
    for n in &app.normals {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-3, "normal {n:?}");
    }
    app
}

fn load_real(name: &str) -> Sequence {
    load_gltf(&data(name), &GltfOptions { frame_rate: 2.0, ..Default::default() }).expect(name)
}

#[test]
fn fox_keeps_its_texture_its_uvs_and_its_normals() {
    let seq = load_real("Fox.glb");
    let app = checked(&seq);
    assert!(!app.uv0.is_empty() && !app.normals.is_empty());
    assert!(app.uv1.is_empty() && app.colors.is_empty());
    assert!(app.uv0.iter().flatten().all(|&x| (-0.01..=1.01).contains(&x)), "the fox's UVs lie in its atlas");
    // The fox is faceted (each triangle has its own normals): welding joins its 1,728
    // authored vertices into one surface of 290 positions, and every corner keeps its wedge.
    assert_eq!((seq.vertex_count(), seq.triangles.len(), app.wedge_count()), (290, 576, 1728));
    assert_eq!(app.materials.len(), 1);
    let m = &app.materials[0];
    assert_eq!(m.name.as_deref(), Some("fox_material"));
    assert_eq!(m.metallic_factor, 0.0);
    assert!((m.roughness_factor - 0.58).abs() < 1e-3);
    let base = m.base_color_texture.expect("a base colour texture");
    assert_eq!(base.tex_coord, 0);
    assert_eq!(app.textures.len(), 1);
    assert_eq!(app.images.len(), 1);
    let image = &app.images[app.textures[base.texture as usize].image as usize];
    assert_eq!(image.mime_type, "image/png");
    assert!(image.bytes.starts_with(b"\x89PNG") && image.bytes.len() > 10_000);
    assert!(app.triangle_material.iter().all(|&t| t == 0));
}

#[test]
fn robot_keeps_three_materials_apart() {
    let seq = load_real("RobotExpressive.glb");
    let app = checked(&seq);
    assert!(app.uv0.is_empty() && app.colors.is_empty() && !app.normals.is_empty());
    let names: Vec<_> = app.materials.iter().map(|m| m.name.clone().unwrap_or_default()).collect();
    assert_eq!(names, ["Grey", "Main", "Black"]);
    let used: BTreeSet<u32> = app.triangle_material.iter().copied().collect();
    assert_eq!(used, BTreeSet::from([0, 1, 2]));
    assert!((app.materials[1].base_color_factor[0] - 0.5903).abs() < 1e-3, "Main is the robot's yellow");
    assert!(app.textures.is_empty() && app.images.is_empty());
    // Material boundaries are seams: some vertex has wedges of two materials.
    let mut material_of_vertex = vec![u32::MAX; seq.vertex_count()];
    let mut shared = 0;
    for (t, cw) in app.corner_wedges.iter().enumerate() {
        for &w in cw {
            let v = app.wedge_vertex[w as usize] as usize;
            let m = app.triangle_material[t];
            if material_of_vertex[v] == u32::MAX {
                material_of_vertex[v] = m;
            } else if material_of_vertex[v] != m {
                shared += 1;
            }
        }
    }
    assert!(shared > 0);
}

#[test]
fn horse_keeps_its_vertex_colours_and_uvs() {
    let seq = load_real("Horse.glb");
    let app = checked(&seq);
    assert!(!app.colors.is_empty() && !app.uv0.is_empty());
    // No primitive has NORMAL, so none are kept (decoders compute them).
    assert_eq!(app.normals.len(), 0);
    let distinct: BTreeSet<[u32; 4]> = app.colors.iter().map(|c| c.map(f32::to_bits)).collect();
    assert_eq!(distinct.len(), 6, "the horse is painted with six flat colours");
    assert!(app.wedge_count() > seq.vertex_count(), "colour and UV seams: {} wedges on {} vertices", app.wedge_count(), seq.vertex_count());
    assert!(app.colors.iter().flatten().all(|&c| (0.0..=1.0).contains(&c)));
    assert_eq!(app.materials.len(), 1);
    assert_eq!(app.materials[0].base_color_factor, [0.0, 0.0, 0.0, 1.0]);
}

// ------------------------------------------------------------------------------------------------
// Generated files
// ------------------------------------------------------------------------------------------------

const PNG: &[u8] = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR-not-a-real-image-but-the-signature-is-right";
const JPEG: &[u8] = b"\xFF\xD8\xFF\xE0\0\x10JFIF\0";

/// A unit square of two primitives meeting along the diagonal (0,0)-(1,1), each with its own
/// three vertices (so the diagonal is a seam after welding): primitive 0 has material 0 and UV
/// islands that differ on the diagonal, primitive 1 material 1. Texture 0 samples embedded
/// image 0 through sampler 0.
fn two_material_square() -> (Bin, Value) {
    let mut bin = Bin::default();
    let p0 = bin.f32(&[0., 0., 0., 1., 0., 0., 1., 1., 0.], "VEC3");
    let p1 = bin.f32(&[0., 0., 0., 1., 1., 0., 0., 1., 0.], "VEC3");
    let uv0 = bin.f32(&[0.0, 0.0, 0.5, 0.0, 0.5, 0.5], "VEC2");
    // u8 normalised: 255 is 1.0.
    let uv1 = bin.add(&[128, 0, 255, 255, 128, 255], 3, "VEC2", 5121, true);
    // NORMAL as normalised i8 (KHR_mesh_quantization) for one primitive, float for the other.
    let n0 = bin.add(&[0, 0, 127, 0, 0, 127, 0, 0, 127], 3, "VEC3", 5120, true);
    let n1 = bin.f32(&[0., 0., 1., 0., 0., 1., 0., 0., 1.], "VEC3");
    // COLOR_0 as VEC3 of normalised u8 and as VEC4 of normalised u16.
    let c0 = bin.add(&[255, 0, 0, 255, 0, 0, 255, 0, 0, 0], 3, "VEC3", 5121, true);
    let c1_bytes: Vec<u8> = [0u16, 65535, 0, 65535].repeat(3).iter().flat_map(|x| x.to_le_bytes()).collect();
    let c1 = bin.add(&c1_bytes, 3, "VEC4", 5123, true);
    let image_view = bin.view(PNG);
    let doc = json!({
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": p0, "TEXCOORD_0": uv0, "NORMAL": n0, "COLOR_0": c0}, "material": 0},
            {"attributes": {"POSITION": p1, "TEXCOORD_1": uv1, "NORMAL": n1, "COLOR_0": c1}, "material": 1}
        ]}],
        "materials": [
            {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1],
                "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.25], "rotation": 0.5, "scale": [2, 3]}}}},
             "normalTexture": {"index": 0, "scale": 0.5, "texCoord": 1}, "occlusionTexture": {"index": 0, "strength": 0.25},
             "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": true},
            {"name": "green", "emissiveFactor": [0, 1, 0], "alphaMode": "BLEND"}
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 33071}],
        "images": [{"bufferView": image_view, "mimeType": "image/png", "name": "checker"}]
    });
    (bin, doc)
}

fn read(doc: &Value, bin: &Bin) -> Result<Sequence, MeshError> {
    load_gltf_bytes(&glb(&bin.document(doc.clone()), &bin.bytes), &GltfOptions::default())
}

#[test]
fn seams_and_materials_survive_welding() {
    let (bin, doc) = two_material_square();
    let seq = read(&doc, &bin).unwrap();
    let app = checked(&seq);
    // Six authored vertices weld into the square's four corners.
    assert_eq!(seq.vertex_count(), 4);
    assert_eq!(seq.triangles.len(), 2);
    // Six wedges survive: the two diagonal vertices have one wedge per primitive.
    assert_eq!(app.wedge_count(), 6);
    let mut per_vertex = vec![0; 4];
    for &v in &app.wedge_vertex {
        per_vertex[v as usize] += 1;
    }
    per_vertex.sort_unstable();
    assert_eq!(per_vertex, [1, 1, 2, 2]);
    assert_eq!(app.triangle_material, [0, 1]);
    // The corners carry what was authored for them.
    let corner_uv0: Vec<[f32; 2]> = app.corner_wedges[0].iter().map(|&w| app.uv0[w as usize]).collect();
    assert_eq!(corner_uv0, [[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]);
    // Primitive 1 has no TEXCOORD_0: its wedges get (0, 0); primitive 0 none of TEXCOORD_1.
    assert!(app.corner_wedges[1].iter().all(|&w| app.uv0[w as usize] == [0.0, 0.0]));
    let uv1: Vec<[f32; 2]> = app.corner_wedges[1].iter().map(|&w| app.uv1[w as usize]).collect();
    assert!((uv1[0][0] - 128.0 / 255.0).abs() < 1e-6 && uv1[1] == [1.0, 1.0], "{uv1:?}");
    assert!(app.corner_wedges[0].iter().all(|&w| app.normals[w as usize] == [0.0, 0.0, 1.0]));
    assert!(app.corner_wedges[0].iter().all(|&w| app.colors[w as usize] == [1.0, 0.0, 0.0, 1.0]));
    assert!(app.corner_wedges[1].iter().all(|&w| app.colors[w as usize] == [0.0, 1.0, 0.0, 1.0]));

    let red = &app.materials[0];
    assert_eq!(red.name.as_deref(), Some("red"));
    let t = red.base_color_texture.unwrap().transform.expect("KHR_texture_transform");
    assert_eq!((t.offset, t.rotation, t.scale, t.tex_coord), ([0.5, 0.25], 0.5, [2.0, 3.0], None));
    assert_eq!((red.normal_scale, red.normal_texture.unwrap().tex_coord), (0.5, 1));
    assert_eq!(red.occlusion_strength, 0.25);
    assert_eq!((red.alpha_mode, red.alpha_cutoff, red.double_sided), (AlphaMode::Mask, 0.3, true));
    let green = &app.materials[1];
    assert_eq!((green.emissive_factor, green.alpha_mode, green.double_sided), ([0.0, 1.0, 0.0], AlphaMode::Blend, false));
    assert_eq!(app.samplers[0].wrap_s, 33071);
    assert_eq!(app.samplers[0].wrap_t, 10497);
    assert_eq!(app.images[0].bytes, PNG);
    assert_eq!(app.images[0].name.as_deref(), Some("checker"));

    // Without welding every authored vertex keeps its single wedge.
    let rig = RiggedMesh::from_bytes(&glb(&bin.document(doc), &bin.bytes)).unwrap();
    let app = rig.appearance.as_ref().unwrap();
    assert_eq!((rig.vertex_count(), app.wedge_count()), (6, 6));
    assert_eq!(app.corner_wedges, rig.triangles);
}

#[test]
fn duplicate_wedges_merge_and_unused_ones_go() {
    // Every triangle with its own vertices and equal attributes at shared positions: welding
    // leaves one wedge per vertex; a vertex no triangle uses takes its wedge with it.
    let mut bin = Bin::default();
    let p = bin.f32(&[0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 0., 0., 1., 1., 0., 0., 1., 0., 5., 5., 5.], "VEC3");
    let uv = bin.f32(&[0., 0., 1., 0., 1., 1., 0., 0., 1., 1., 0., 1., 9., 9.], "VEC2");
    let idx = bin.add(&[0, 1, 2, 3, 4, 5], 6, "SCALAR", 5121, false);
    let doc = json!({"scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p, "TEXCOORD_0": uv}, "indices": idx}]}]});
    let seq = read(&doc, &bin).unwrap();
    let app = checked(&seq);
    assert_eq!((seq.vertex_count(), app.wedge_count()), (4, 4));
    assert!(!app.uv0.contains(&[9.0, 9.0]));
    // No material: glTF's default material.
    assert_eq!(app.materials.len(), 1);
    assert_eq!(app.materials[0].base_color_factor, [1.0; 4]);
    assert_eq!(app.materials[0].metallic_factor, 1.0);
    assert_eq!(app.triangle_material, [0, 0]);
}

#[test]
fn images_from_data_uris_and_files_beside_the_gltf() {
    let (bin, mut doc) = two_material_square();
    doc["images"] = json!([{"uri": format!("data:image/jpeg;base64,{}", base64(JPEG))}]);
    let seq = read(&doc, &bin).unwrap();
    let image = &checked(&seq).images[0];
    assert_eq!((image.mime_type.as_str(), image.bytes.as_slice()), ("image/jpeg", JPEG));

    let dir = std::env::temp_dir().join(format!("pmcodec-gltf-looks-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("tex")).unwrap();
    std::fs::write(dir.join("tex/fox skin.png"), PNG).unwrap();
    doc["images"] = json!([{"uri": "tex/fox%20skin.png"}]);
    let glb_bytes = glb(&bin.document(doc.clone()), &bin.bytes);
    std::fs::write(dir.join("square.glb"), &glb_bytes).unwrap();
    let seq = load_gltf(&dir.join("square.glb"), &GltfOptions::default()).unwrap();
    assert_eq!(checked(&seq).images[0].bytes, PNG);
    // From bytes an external image cannot be found: a clear error, not a blank texture.
    let e = load_gltf_bytes(&glb_bytes, &GltfOptions::default()).unwrap_err().to_string();
    assert!(e.contains("image 0") && e.contains("tex/fox%20skin.png") && e.contains("path"), "{e}");
    // A missing image file names the glTF file, the image and the missing file.
    doc["images"] = json!([{"uri": "tex/missing.png"}]);
    std::fs::write(dir.join("missing.glb"), glb(&bin.document(doc.clone()), &bin.bytes)).unwrap();
    let e = load_gltf(&dir.join("missing.glb"), &GltfOptions::default()).unwrap_err().to_string();
    assert!(e.contains("missing.glb") && e.contains("image 0") && e.contains("tex/missing.png"), "{e}");
    // Outside the folder is refused.
    doc["images"] = json!([{"uri": "../x.png"}]);
    std::fs::write(dir.join("escape.glb"), glb(&bin.document(doc), &bin.bytes)).unwrap();
    let e = load_gltf(&dir.join("escape.glb"), &GltfOptions::default()).unwrap_err();
    assert!(matches!(e, MeshError::Unsupported(_)), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Loads the square after `change` and returns the error message.
fn error_after(change: &dyn Fn(&mut Value, &mut Bin)) -> String {
    let (mut bin, mut doc) = two_material_square();
    change(&mut doc, &mut bin);
    match read(&doc, &bin) {
        Ok(_) => panic!("the change was accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_appearance_input_is_named() {
    // Image bytes that are neither PNG nor JPEG (a GIF).
    let e = error_after(&|d, b| {
        let v = b.view(b"GIF89a\x01\0\x01\0");
        d["images"][0]["bufferView"] = json!(v);
    });
    assert!(e.contains("image 0") && e.contains("checker") && e.contains("neither PNG nor JPEG"), "{e}");
    // NaN texture coordinates.
    let e = error_after(&|d, b| {
        let uv = b.f32(&[0.0, 0.0, f32::NAN, 0.0, 1.0, 1.0], "VEC2");
        d["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uv);
    });
    assert!(e.contains("mesh 0 primitive 0 TEXCOORD_0") && e.contains("element 1") && e.contains("not a finite number"), "{e}");
    // An attribute whose count disagrees with POSITION's.
    let e = error_after(&|d, b| {
        let c = b.f32(&[1.0; 8], "VEC4");
        d["meshes"][0]["primitives"][1]["attributes"]["COLOR_0"] = json!(c);
    });
    assert!(e.contains("mesh 0 primitive 1 COLOR_0") && e.contains("2 elements but POSITION has 3"), "{e}");
    let e = error_after(&|d, b| {
        let n = b.f32(&[0.0, 0.0, 1.0], "VEC3");
        d["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(n);
    });
    assert!(e.contains("mesh 0 primitive 0 NORMAL") && e.contains("1 elements but POSITION has 3"), "{e}");
    // Indices out of range: material, texture, sampler, image.
    let e = error_after(&|d, _| d["meshes"][0]["primitives"][1]["material"] = json!(7));
    assert!(e.contains("mesh 0 primitive 1") && e.contains("material 7 does not exist"), "{e}");
    let e = error_after(&|d, _| d["materials"][0]["occlusionTexture"]["index"] = json!(3));
    assert!(e.contains("material 0 occlusionTexture") && e.contains("texture 3 does not exist"), "{e}");
    let e = error_after(&|d, _| d["textures"][0]["sampler"] = json!(2));
    assert!(e.contains("texture 0") && e.contains("sampler 2 does not exist"), "{e}");
    let e = error_after(&|d, _| d["textures"][0]["source"] = json!(4));
    assert!(e.contains("texture 0") && e.contains("image 4 does not exist"), "{e}");
    let e = error_after(&|d, _| d["materials"][1]["alphaMode"] = json!("CLIP"));
    assert!(e.contains("material 1") && e.contains("CLIP"), "{e}");
    let e = error_after(&|d, _| d["materials"][0]["normalTexture"]["texCoord"] = json!(2));
    assert!(e.contains("material 0 normalTexture") && e.contains("TEXCOORD_2"), "{e}");
    // A colour with the wrong component type is refused by name.
    let e = error_after(&|d, b| {
        let c = b.add(&[0; 48], 3, "VEC4", 5125, false);
        d["meshes"][0]["primitives"][1]["attributes"]["COLOR_0"] = json!(c);
    });
    assert!(e.contains("mesh 0 primitive 1 COLOR_0"), "{e}");
}
