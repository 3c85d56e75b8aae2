//! Writing a decoded cut with its appearance: a textured GLB (one primitive per material,
//! images embedded) or OBJ with its MTL and image files. A local writer until the workspace's
//! unified GLB writer takes appearance; [`textured_glb`] is the one function to swap.

use crate::ContainerError;
use pmcodec_mesh::appearance::{AlphaMode, TextureRef};
use pmcodec_mesh::{Appearance, TriMesh};
use serde_json::{Value, json};
use std::fmt::Write as _;

const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

fn texture_ref(r: &TextureRef) -> Value {
    let mut v = json!({"index": r.texture, "texCoord": r.tex_coord});
    if let Some(t) = r.transform {
        let mut x = json!({"offset": t.offset, "rotation": t.rotation, "scale": t.scale});
        if let Some(c) = t.tex_coord {
            x["texCoord"] = json!(c);
        }
        v["extensions"] = json!({"KHR_texture_transform": x});
    }
    v
}

fn materials_json(app: &Appearance) -> Vec<Value> {
    app.materials
        .iter()
        .map(|m| {
            let mut pbr =
                json!({"baseColorFactor": m.base_color_factor, "metallicFactor": m.metallic_factor, "roughnessFactor": m.roughness_factor});
            if let Some(r) = &m.base_color_texture {
                pbr["baseColorTexture"] = texture_ref(r);
            }
            if let Some(r) = &m.metallic_roughness_texture {
                pbr["metallicRoughnessTexture"] = texture_ref(r);
            }
            let mut v = json!({"pbrMetallicRoughness": pbr, "doubleSided": m.double_sided, "emissiveFactor": m.emissive_factor});
            if let Some(name) = &m.name {
                v["name"] = json!(name);
            }
            if let Some(r) = &m.normal_texture {
                v["normalTexture"] = texture_ref(r);
                v["normalTexture"]["scale"] = json!(m.normal_scale);
            }
            if let Some(r) = &m.occlusion_texture {
                v["occlusionTexture"] = texture_ref(r);
                v["occlusionTexture"]["strength"] = json!(m.occlusion_strength);
            }
            if let Some(r) = &m.emissive_texture {
                v["emissiveTexture"] = texture_ref(r);
            }
            match m.alpha_mode {
                AlphaMode::Opaque => {}
                AlphaMode::Blend => v["alphaMode"] = json!("BLEND"),
                AlphaMode::Mask => {
                    v["alphaMode"] = json!("MASK");
                    v["alphaCutoff"] = json!(m.alpha_cutoff);
                }
            }
            v
        })
        .collect()
}

/// A GLB of `mesh` with `app` (one wedge per vertex, as [`crate::Decoder::textured_mesh`]
/// gives): POSITION, NORMAL, TEXCOORD_0/1 and COLOR_0 per vertex, one primitive per material
/// used, the images embedded in the binary chunk.
pub fn textured_glb(mesh: &TriMesh, app: &Appearance) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views: Vec<Value> = Vec::new();
    let mut accessors: Vec<Value> = Vec::new();
    let nv = mesh.positions.len();
    let mut view = |bin: &mut Vec<u8>, data: &[f32], target: Option<u32>| {
        let at = bin.len();
        for x in data {
            bin.extend_from_slice(&x.to_le_bytes());
        }
        let mut v = json!({"buffer": 0, "byteOffset": at, "byteLength": bin.len() - at});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        views.push(v);
        views.len() - 1
    };
    let mut attributes = serde_json::Map::new();
    let flat: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
    let (lo, hi) = mesh.bounds().map_or(([0.0; 3], [0.0; 3]), |(a, b)| (a.to_array(), b.to_array()));
    let v = view(&mut bin, &flat, Some(ARRAY_BUFFER));
    accessors.push(json!({"bufferView": v, "componentType": FLOAT, "count": nv, "type": "VEC3", "min": lo, "max": hi}));
    attributes.insert("POSITION".into(), json!(accessors.len() - 1));
    let columns: [(&str, &str, Vec<f32>); 4] = [
        ("NORMAL", "VEC3", app.normals.iter().flatten().copied().collect()),
        ("TEXCOORD_0", "VEC2", app.uv0.iter().flatten().copied().collect()),
        ("TEXCOORD_1", "VEC2", app.uv1.iter().flatten().copied().collect()),
        ("COLOR_0", "VEC4", app.colors.iter().flatten().copied().collect()),
    ];
    for (name, kind, data) in columns {
        if data.is_empty() {
            continue;
        }
        let v = view(&mut bin, &data, Some(ARRAY_BUFFER));
        accessors.push(json!({"bufferView": v, "componentType": FLOAT, "count": nv, "type": kind}));
        attributes.insert(name.into(), json!(accessors.len() - 1));
    }
    // One primitive per material, triangles in the mesh's order.
    let materials = app.materials.len().max(1);
    let mut primitives = Vec::new();
    for m in 0..materials {
        let indices: Vec<u32> = mesh
            .triangles
            .iter()
            .enumerate()
            .filter(|(t, _)| app.triangle_material.get(*t).copied().unwrap_or(0) as usize == m)
            .flat_map(|(_, tri)| *tri)
            .collect();
        if indices.is_empty() {
            continue;
        }
        let at = bin.len();
        for i in &indices {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        views.push(json!({"buffer": 0, "byteOffset": at, "byteLength": bin.len() - at, "target": ELEMENT_ARRAY_BUFFER}));
        accessors.push(json!({"bufferView": views.len() - 1, "componentType": UNSIGNED_INT, "count": indices.len(), "type": "SCALAR"}));
        let mut p = json!({"attributes": attributes, "indices": accessors.len() - 1, "mode": 4});
        if !app.materials.is_empty() {
            p["material"] = json!(m);
        }
        primitives.push(p);
    }
    let mut images = Vec::new();
    for image in &app.images {
        let at = bin.len();
        bin.extend_from_slice(&image.bytes);
        views.push(json!({"buffer": 0, "byteOffset": at, "byteLength": image.bytes.len()}));
        let mut v = json!({"bufferView": views.len() - 1, "mimeType": image.mime_type});
        if let Some(n) = &image.name {
            v["name"] = json!(n);
        }
        images.push(v);
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
    }
    let mut gltf = json!({
        "asset": {"version": "2.0", "generator": "pmcodec"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": primitives}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    if !app.materials.is_empty() {
        gltf["materials"] = json!(materials_json(app));
    }
    if !app.textures.is_empty() {
        gltf["textures"] = json!(
            app.textures
                .iter()
                .map(|t| {
                    let mut v = json!({"source": t.image});
                    if let Some(s) = t.sampler {
                        v["sampler"] = json!(s);
                    }
                    v
                })
                .collect::<Vec<_>>()
        );
        gltf["images"] = json!(images);
    }
    if !app.samplers.is_empty() {
        gltf["samplers"] = json!(
            app.samplers
                .iter()
                .map(|s| {
                    let mut v = json!({"wrapS": s.wrap_s, "wrapT": s.wrap_t});
                    if let Some(f) = s.mag_filter {
                        v["magFilter"] = json!(f);
                    }
                    if let Some(f) = s.min_filter {
                        v["minFilter"] = json!(f);
                    }
                    v
                })
                .collect::<Vec<_>>()
        );
    }
    let uses_transform = app.materials.iter().any(|m| {
        [&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture, &m.occlusion_texture, &m.emissive_texture]
            .into_iter()
            .flatten()
            .any(|r| r.transform.is_some())
    });
    if uses_transform {
        gltf["extensionsUsed"] = json!(["KHR_texture_transform"]);
    }
    glb(&gltf, bin)
}

/// GLB container: header, JSON chunk (space padded), BIN chunk (zero padded).
fn glb(json: &Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap_or_default();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + j.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    for word in [0x4654_6C67u32, 2, total as u32, j.len() as u32, 0x4E4F_534A] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&j);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    out
}

/// The file name an image is written under beside an OBJ: its own name when it has a safe
/// one, else `{stem}-image{i}.png|jpg`.
pub fn image_file_name(app: &Appearance, i: usize, stem: &str) -> String {
    let image = &app.images[i];
    let ext = if image.mime_type == "image/jpeg" { "jpg" } else { "png" };
    match &image.name {
        Some(n) if !n.is_empty() && n.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) && !n.starts_with('.') => {
            format!("{stem}-{i}-{n}")
        }
        _ => format!("{stem}-image{i}.{ext}"),
    }
}

/// An OBJ of `mesh` with `app` (`v` per vertex of `mesh`, `vt` with v flipped to OBJ's upward
/// axis and `vn` per wedge, `usemtl` runs) naming `mtl_name`, and that MTL's text (`Kd`, `d`,
/// `map_Kd` naming the files [`image_file_name`] gives). `wedges[t]` are the wedges of
/// `mesh.triangles[t]`'s corners (the same triangles, indexed into `app`'s per-wedge arrays):
/// an OBJ indexes positions and attributes apart, so a seam does not split a vertex.
pub fn textured_obj(
    mesh: &TriMesh,
    wedges: &[[u32; 3]],
    app: &Appearance,
    mtl_name: &str,
    stem: &str,
) -> Result<(String, String), ContainerError> {
    if wedges.len() != mesh.triangles.len() {
        return Err(ContainerError::Options(format!("{} triangles with wedges for {} triangles", mesh.triangles.len(), wedges.len())));
    }
    let mut obj = String::new();
    let _ = writeln!(obj, "# pmcodec\nmtllib {mtl_name}");
    for p in &mesh.positions {
        let _ = writeln!(obj, "v {} {} {}", p.x, p.y, p.z);
    }
    for uv in &app.uv0 {
        let _ = writeln!(obj, "vt {} {}", uv[0], 1.0 - uv[1]);
    }
    for n in &app.normals {
        let _ = writeln!(obj, "vn {} {} {}", n[0], n[1], n[2]);
    }
    let (has_uv, has_n) = (!app.uv0.is_empty(), !app.normals.is_empty());
    let mut current = u32::MAX;
    for (t, (tri, tw)) in mesh.triangles.iter().zip(wedges).enumerate() {
        let m = app.triangle_material.get(t).copied().unwrap_or(0);
        if m != current && !app.materials.is_empty() {
            let _ = writeln!(obj, "usemtl material{m}");
            current = m;
        }
        obj.push('f');
        for (&v, &w) in tri.iter().zip(tw) {
            let (i, j) = (v + 1, w + 1);
            let _ = match (has_uv, has_n) {
                (true, true) => write!(obj, " {i}/{j}/{j}"),
                (true, false) => write!(obj, " {i}/{j}"),
                (false, true) => write!(obj, " {i}//{j}"),
                (false, false) => write!(obj, " {i}"),
            };
        }
        obj.push('\n');
    }
    let mut mtl = String::from("# pmcodec\n");
    for (m, mat) in app.materials.iter().enumerate() {
        let c = mat.base_color_factor;
        let _ = writeln!(mtl, "newmtl material{m}\nKd {} {} {}\nd {}", c[0], c[1], c[2], c[3]);
        if let Some(r) = &mat.base_color_texture
            && let Some(t) = app.textures.get(r.texture as usize)
            && (t.image as usize) < app.images.len()
        {
            let _ = writeln!(mtl, "map_Kd {}", image_file_name(app, t.image as usize, stem));
        }
    }
    Ok((obj, mtl))
}
