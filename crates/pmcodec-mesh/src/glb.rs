//! The one GLB assembler every writer uses: buffer views (4-byte aligned, in one buffer),
//! accessors (with the min/max glTF requires of positions and animation inputs), images as
//! buffer views, the JSON and BIN chunks, and the format's 4 GiB limit; and the writing of an
//! [`Appearance`] (materials, textures, samplers, images, per-wedge attributes, one primitive
//! per material).
//!
//! glTF 2.0, "Binary glTF Layout" (§4.4) and "Accessors" (§3.6).

use crate::MeshError;
use crate::appearance::{AlphaMode, Appearance, Material, TextureRef};
use glam::Vec3;
use serde_json::{Map, Value, json};

/// glTF component type FLOAT (32-bit IEEE float).
pub const FLOAT: u32 = 5126;
/// glTF component type UNSIGNED_SHORT (16-bit indices, joint indices).
pub const UNSIGNED_SHORT: u32 = 5123;
/// glTF component type UNSIGNED_INT (32-bit indices).
pub const UNSIGNED_INT: u32 = 5125;
/// Buffer view target for vertex attributes.
pub const ARRAY_BUFFER: u32 = 34962;
/// Buffer view target for indices.
pub const ELEMENT_ARRAY_BUFFER: u32 = 34963;
/// Primitive mode TRIANGLES.
pub const TRIANGLES: u32 = 4;
/// Meshes with fewer vertices get 16-bit indices. glTF forbids an index equal to the
/// component type's largest value (primitive restart), so 65,535 vertices at most.
pub const MAX_U16_VERTICES: usize = 65_535;
const GLB_MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"

/// Binary data and the views and accessors over it, collected while a document is built.
#[derive(Default)]
pub struct GlbBuilder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl GlbBuilder {
    /// Bytes of binary data so far.
    pub fn bin_len(&self) -> usize {
        self.bin.len()
    }

    /// Appends `bytes` as a buffer view starting on a 4-byte boundary (every component type is
    /// then aligned, as §3.6.2.4 requires); `target` is the GL buffer target, if any.
    pub fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    /// An accessor over a new view of `bytes`.
    pub fn accessor(&mut self, bytes: &[u8], target: Option<u32>, component: u32, count: usize, ty: &str) -> usize {
        let view = self.view(bytes, target);
        self.accessors.push(json!({"bufferView": view, "componentType": component, "count": count, "type": ty}));
        self.accessors.len() - 1
    }

    /// Float accessor of `values.len() / width` elements of type `ty`; with `min_max`, the
    /// per-component bounds.
    pub fn floats(&mut self, values: &[f32], target: Option<u32>, ty: &str, width: usize, min_max: bool) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        let width = width.max(1);
        let count = values.len() / width;
        let a = self.accessor(&bytes, target, FLOAT, count, ty);
        if min_max && count > 0 {
            let mut lo = vec![f32::INFINITY; width];
            let mut hi = vec![f32::NEG_INFINITY; width];
            for chunk in values.chunks_exact(width) {
                for (k, &x) in chunk.iter().enumerate() {
                    lo[k] = lo[k].min(x);
                    hi[k] = hi[k].max(x);
                }
            }
            self.accessors[a]["min"] = json!(lo);
            self.accessors[a]["max"] = json!(hi);
        }
        a
    }

    /// VEC3 float accessor; `min_max` for positions and morph target deltas.
    pub fn vec3s(&mut self, values: &[Vec3], target: Option<u32>, min_max: bool) -> usize {
        let flat: Vec<f32> = values.iter().flat_map(|v| v.to_array()).collect();
        self.floats(&flat, target, "VEC3", 3, min_max)
    }

    /// SCALAR u32 accessor (tables no mesh uses).
    pub fn u32s(&mut self, values: &[u32], target: Option<u32>) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.accessor(&bytes, target, UNSIGNED_INT, values.len(), "SCALAR")
    }

    /// VEC4 u16 accessor (skin joints).
    pub fn joints(&mut self, joints: &[[u16; 4]]) -> usize {
        let bytes: Vec<u8> = joints.iter().flatten().flat_map(|j| j.to_le_bytes()).collect();
        self.accessor(&bytes, Some(ARRAY_BUFFER), UNSIGNED_SHORT, joints.len(), "VEC4")
    }

    /// Triangle indices into `vertex_count` vertices: u16 when they fit, else u32.
    pub fn indices(&mut self, indices: &[u32], vertex_count: usize) -> usize {
        if vertex_count <= MAX_U16_VERTICES {
            let bytes: Vec<u8> = indices.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect();
            self.accessor(&bytes, Some(ELEMENT_ARRAY_BUFFER), UNSIGNED_SHORT, indices.len(), "SCALAR")
        } else {
            self.u32s(indices, Some(ELEMENT_ARRAY_BUFFER))
        }
    }

    /// Completes `root` with the accessors, views and buffer (when there is binary data) and
    /// assembles the GLB. Errors when the result would pass the 4 GiB the header can state.
    pub fn finish(self, mut root: Value) -> Result<Vec<u8>, MeshError> {
        if !self.bin.is_empty() {
            root["accessors"] = Value::Array(self.accessors);
            root["bufferViews"] = Value::Array(self.views);
            root["buffers"] = json!([{"byteLength": self.bin.len()}]);
        }
        assemble(&root, self.bin)
    }
}

/// Header and chunks: each chunk's data padded to a multiple of 4 bytes, JSON with spaces
/// (still valid JSON), BIN with zeros; no BIN chunk without binary data. For a document whose
/// binary data is already laid out (see [`GlbBuilder`] to lay it out); errors past 4 GiB.
pub fn assemble(json: &Value, mut bin: Vec<u8>) -> Result<Vec<u8>, MeshError> {
    let mut text = serde_json::to_vec(json).map_err(|e| MeshError::Invalid(format!("GLB JSON: {e}")))?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = 12 + 8 + text.len() + bin_chunk;
    if total > u32::MAX as usize {
        return Err(MeshError::TooLarge { what: format!("{total} bytes exceed the 4 GiB a GLB file can hold") });
    }
    let mut out = Vec::with_capacity(total);
    for word in [GLB_MAGIC, 2, total as u32, text.len() as u32, CHUNK_JSON] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    Ok(out)
}

// ------------------------------------------------------------------------------------------------
// Appearance
// ------------------------------------------------------------------------------------------------

/// Writes the materials, textures, samplers and images of `app` (images as buffer views) into
/// `root`, with `extensionsUsed` when a texture transform needs it. Materials keep their
/// indices, so `triangle_material` indexes the written array; an appearance without materials
/// gets none (glTF's default material).
pub fn write_looks(b: &mut GlbBuilder, app: &Appearance, root: &mut Value) {
    let mut transforms = false;
    let materials: Vec<Value> = app.materials.iter().map(|m| material_json(m, &mut transforms)).collect();
    let images: Vec<Value> = app
        .images
        .iter()
        .map(|img| {
            let mut v = json!({"bufferView": b.view(&img.bytes, None), "mimeType": img.mime_type});
            if let Some(name) = &img.name {
                v["name"] = json!(name);
            }
            v
        })
        .collect();
    let textures: Vec<Value> = app
        .textures
        .iter()
        .map(|t| {
            let mut v = json!({"source": t.image});
            if let Some(s) = t.sampler {
                v["sampler"] = json!(s);
            }
            v
        })
        .collect();
    let samplers: Vec<Value> = app
        .samplers
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
        .collect();
    for (key, list) in [("materials", materials), ("textures", textures), ("samplers", samplers), ("images", images)] {
        if !list.is_empty() {
            root[key] = Value::Array(list);
        }
    }
    if transforms {
        root["extensionsUsed"] = json!(["KHR_texture_transform"]);
    }
}

fn texture_json(r: &TextureRef, transforms: &mut bool) -> Value {
    let mut v = json!({"index": r.texture});
    if r.tex_coord != 0 {
        v["texCoord"] = json!(r.tex_coord);
    }
    if let Some(t) = &r.transform {
        *transforms = true;
        let mut e = json!({"offset": t.offset, "rotation": t.rotation, "scale": t.scale});
        if let Some(c) = t.tex_coord {
            e["texCoord"] = json!(c);
        }
        v["extensions"] = json!({"KHR_texture_transform": e});
    }
    v
}

fn material_json(m: &Material, transforms: &mut bool) -> Value {
    let mut pbr =
        json!({"baseColorFactor": m.base_color_factor, "metallicFactor": m.metallic_factor, "roughnessFactor": m.roughness_factor});
    if let Some(t) = &m.base_color_texture {
        pbr["baseColorTexture"] = texture_json(t, transforms);
    }
    if let Some(t) = &m.metallic_roughness_texture {
        pbr["metallicRoughnessTexture"] = texture_json(t, transforms);
    }
    let mut v = json!({"pbrMetallicRoughness": pbr});
    if let Some(name) = &m.name {
        v["name"] = json!(name);
    }
    if let Some(t) = &m.normal_texture {
        v["normalTexture"] = texture_json(t, transforms);
        v["normalTexture"]["scale"] = json!(m.normal_scale);
    }
    if let Some(t) = &m.occlusion_texture {
        v["occlusionTexture"] = texture_json(t, transforms);
        v["occlusionTexture"]["strength"] = json!(m.occlusion_strength);
    }
    if let Some(t) = &m.emissive_texture {
        v["emissiveTexture"] = texture_json(t, transforms);
    }
    if m.emissive_factor != [0.0; 3] {
        v["emissiveFactor"] = json!(m.emissive_factor);
    }
    match m.alpha_mode {
        AlphaMode::Opaque => {}
        AlphaMode::Mask => {
            v["alphaMode"] = json!("MASK");
            v["alphaCutoff"] = json!(m.alpha_cutoff);
        }
        AlphaMode::Blend => v["alphaMode"] = json!("BLEND"),
    }
    if m.double_sided {
        v["doubleSided"] = json!(true);
    }
    v
}

/// Per-wedge normals from `positions` (per vertex): area-weighted over the triangles around
/// each vertex, shared by the wedges of one vertex that carry the same input normal (so creases
/// and faceted input stay sharp, and UV seams stay smooth); without input normals, one smooth
/// normal per vertex. Unit length; +Z where the faces have no area.
pub fn wedge_normals(positions: &[Vec3], triangles: &[[u32; 3]], app: &Appearance) -> Vec<Vec3> {
    let wedges = app.wedge_count();
    // Group of each wedge: the first wedge on its vertex with the same input normal bits.
    let mut group = vec![0u32; wedges];
    let mut first: std::collections::HashMap<(u32, [u32; 3]), u32> = std::collections::HashMap::new();
    for (w, g) in group.iter_mut().enumerate() {
        let n = app.normals.get(w).map_or([0; 3], |n| n.map(f32::to_bits));
        *g = *first.entry((app.wedge_vertex[w], n)).or_insert(w as u32);
    }
    let mut sum = vec![Vec3::ZERO; wedges];
    for (t, cw) in triangles.iter().zip(&app.corner_wedges) {
        let p = t.map(|i| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        let face = (p[1] - p[0]).cross(p[2] - p[0]);
        for &w in cw {
            if let Some(s) = group.get(w as usize).and_then(|&g| sum.get_mut(g as usize)) {
                *s += face;
            }
        }
    }
    group.iter().map(|&g| sum[g as usize].try_normalize().unwrap_or(Vec3::Z)).collect()
}

/// The per-wedge attributes of `app` other than positions and normals, as accessors:
/// `TEXCOORD_0`, `TEXCOORD_1` and `COLOR_0` (clamped to [0, 1], as glTF requires of colours).
pub fn wedge_attributes(b: &mut GlbBuilder, app: &Appearance) -> Map<String, Value> {
    let mut out = Map::new();
    for (name, uv) in [("TEXCOORD_0", &app.uv0), ("TEXCOORD_1", &app.uv1)] {
        if !uv.is_empty() {
            let flat: Vec<f32> = uv.iter().flatten().copied().collect();
            out.insert(name.into(), json!(b.floats(&flat, Some(ARRAY_BUFFER), "VEC2", 2, false)));
        }
    }
    if !app.colors.is_empty() {
        let flat: Vec<f32> = app.colors.iter().flatten().map(|c| c.clamp(0.0, 1.0)).collect();
        out.insert("COLOR_0".into(), json!(b.floats(&flat, Some(ARRAY_BUFFER), "VEC4", 4, false)));
    }
    out
}

/// Triangles as wedge indices grouped by material, materials in increasing order; materials
/// without triangles are left out.
pub fn triangles_by_material(app: &Appearance) -> Vec<(u32, Vec<u32>)> {
    let mut groups: std::collections::BTreeMap<u32, Vec<u32>> = std::collections::BTreeMap::new();
    for (t, cw) in app.corner_wedges.iter().enumerate() {
        groups.entry(app.material_of(t)).or_default().extend(cw);
    }
    groups.into_iter().collect()
}
