//! Appearance: what a surface looks like, apart from where it is.
//!
//! A deforming sequence has one connectivity, so its appearance (texture coordinates, vertex
//! colours, the input's normals, materials and their textures) is the same in every frame and
//! is stored once. Attributes live on *wedges* (Hoppe, "New quadric metric for simplifying
//! meshes with appearance attributes", 1999): a wedge is one (vertex, attribute record) pair, and
//! each triangle corner names its wedge. A vertex on a seam (a UV island's border, a crease in
//! the input normals, a material boundary) has several wedges; elsewhere it has one. Positions
//! stay per vertex (the simplifier and the codec weld across seams), attributes per wedge.
//!
//! Arrays are flat and indexed by `u32`: every per-wedge array is either empty (the input has no
//! such attribute) or has exactly `wedge_vertex.len()` entries.

use crate::MeshError;

/// The appearance of a [`crate::Sequence`] (or a rig), constant over frames.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Appearance {
    /// `corner_wedges[t][i]` is the wedge of corner `i` of triangle `t`. Parallel to the
    /// triangles it describes; the wedge's vertex is that corner's vertex.
    pub corner_wedges: Vec<[u32; 3]>,
    /// The vertex of each wedge.
    pub wedge_vertex: Vec<u32>,
    /// `TEXCOORD_0` per wedge (glTF convention: origin top left, v down), or empty.
    pub uv0: Vec<[f32; 2]>,
    /// `TEXCOORD_1` per wedge, or empty.
    pub uv1: Vec<[f32; 2]>,
    /// The input's unit normals per wedge in rest (bind) space, or empty. Decoders recompute
    /// normals from decoded positions; these tell them where the creases are.
    pub normals: Vec<[f32; 3]>,
    /// `COLOR_0` per wedge as linear RGBA, or empty.
    pub colors: Vec<[f32; 4]>,
    /// Material of each triangle, an index into `materials`; empty means every triangle uses
    /// material 0 (or the default material when `materials` is empty too).
    pub triangle_material: Vec<u32>,
    /// The materials `triangle_material` indexes (glTF §3.9); empty for an input without any.
    pub materials: Vec<Material>,
    /// The textures materials name through [`TextureRef::texture`].
    pub textures: Vec<Texture>,
    /// The samplers textures name through [`Texture::sampler`].
    pub samplers: Vec<Sampler>,
    /// The encoded images textures name through [`Texture::image`].
    pub images: Vec<Image>,
}

/// glTF 2.0's metallic-roughness material (§3.9), the core fields.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The material's name in the input (glTF `name`, OBJ `newmtl`), if any.
    pub name: Option<String>,
    /// `baseColorFactor`, linear RGBA; multiplies the base colour texture.
    pub base_color_factor: [f32; 4],
    /// `baseColorTexture` (sRGB).
    pub base_color_texture: Option<TextureRef>,
    /// `metallicFactor` in 0..=1.
    pub metallic_factor: f32,
    /// `roughnessFactor` in 0..=1.
    pub roughness_factor: f32,
    /// `metallicRoughnessTexture`: roughness in its green channel, metalness in blue.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// `normalTexture`, a tangent-space normal map.
    pub normal_texture: Option<TextureRef>,
    /// `normalTexture.scale`.
    pub normal_scale: f32,
    /// `occlusionTexture`: ambient occlusion in its red channel.
    pub occlusion_texture: Option<TextureRef>,
    /// `occlusionTexture.strength`.
    pub occlusion_strength: f32,
    /// `emissiveTexture` (sRGB).
    pub emissive_texture: Option<TextureRef>,
    /// `emissiveFactor`, linear RGB.
    pub emissive_factor: [f32; 3],
    /// `alphaMode`: how the base colour's alpha is used.
    pub alpha_mode: AlphaMode,
    /// `alphaCutoff`: the threshold of [`AlphaMode::Mask`], ignored otherwise.
    pub alpha_cutoff: f32,
    /// `doubleSided`: back faces are drawn and lit too.
    pub double_sided: bool,
}

impl Default for Material {
    /// glTF's defaults (and its default material, §3.9.6).
    fn default() -> Self {
        Material {
            name: None,
            base_color_factor: [1.0; 4],
            base_color_texture: None,
            metallic_factor: 1.0,
            roughness_factor: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            emissive_texture: None,
            emissive_factor: [0.0; 3],
            alpha_mode: AlphaMode::Opaque,
            alpha_cutoff: 0.5,
            double_sided: false,
        }
    }
}

/// glTF `alphaMode`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AlphaMode {
    /// Alpha is ignored; the surface is fully opaque.
    #[default]
    Opaque,
    /// Alpha below [`Material::alpha_cutoff`] is not drawn, the rest is opaque.
    Mask,
    /// Alpha blends with what is behind.
    Blend,
}

/// A material's use of a texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`Appearance::textures`].
    pub texture: u32,
    /// Which texture coordinates: 0 for `uv0`, 1 for `uv1`.
    pub tex_coord: u32,
    /// `KHR_texture_transform`, when present.
    pub transform: Option<TextureTransform>,
}

/// `KHR_texture_transform`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureTransform {
    /// UV offset, applied after rotation and scale.
    pub offset: [f32; 2],
    /// Counter-clockwise rotation of the UVs in radians.
    pub rotation: f32,
    /// UV scale, applied first.
    pub scale: [f32; 2],
    /// Overrides [`TextureRef::tex_coord`] when set.
    pub tex_coord: Option<u32>,
}

/// A texture: an image and how it is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Texture {
    /// Index into [`Appearance::images`].
    pub image: u32,
    /// Index into [`Appearance::samplers`]; `None` is glTF's default (repeat, auto filtering).
    pub sampler: Option<u32>,
}

/// glTF sampler (§3.8.4), its numeric enums as in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sampler {
    /// `magFilter` (9728 NEAREST, 9729 LINEAR); `None` lets the renderer choose.
    pub mag_filter: Option<u32>,
    /// `minFilter` (NEAREST, LINEAR or one of the four mipmap modes); `None` lets the renderer choose.
    pub min_filter: Option<u32>,
    /// `wrapS` (10497 REPEAT, 33071 CLAMP_TO_EDGE, 33648 MIRRORED_REPEAT).
    pub wrap_s: u32,
    /// `wrapT`, the same values as `wrap_s`.
    pub wrap_t: u32,
}

impl Default for Sampler {
    fn default() -> Self {
        Sampler { mag_filter: None, min_filter: None, wrap_s: 10497, wrap_t: 10497 }
    }
}

/// An encoded image, kept as the input's bytes (PNG or JPEG); never re-encoded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// The image's name in the input, if any (kept for writers and tools, not for decoding).
    pub name: Option<String>,
    /// `image/png` or `image/jpeg`.
    pub mime_type: String,
    /// The encoded file, exactly as read.
    pub bytes: Vec<u8>,
}

/// The MIME type of encoded image bytes from their signature, whatever a file or name declares:
/// the two formats glTF 2.0 allows (§3.8.2), PNG by its 8-byte signature (ISO/IEC 15948 §5.2)
/// and JPEG by its SOI marker and the start of the next marker. Every reader of images (glTF,
/// MTL, the server's image route) asks this one function.
pub fn image_mime_type(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else {
        None
    }
}

impl Appearance {
    /// Number of wedges.
    pub fn wedge_count(&self) -> usize {
        self.wedge_vertex.len()
    }

    /// Checks that every index is in range and every per-wedge array has one entry per wedge
    /// (or none), for a mesh of `vertex_count` vertices and `triangles`. Names the first thing
    /// that is wrong.
    pub fn validate(&self, vertex_count: usize, triangles: &[[u32; 3]]) -> Result<(), MeshError> {
        let bad = |what: String| Err(MeshError::Invalid(format!("appearance: {what}")));
        let wedges = self.wedge_count();
        if self.corner_wedges.len() != triangles.len() {
            return bad(format!("{} triangles but {} corner wedge triples", triangles.len(), self.corner_wedges.len()));
        }
        for (name, len) in
            [("uv0", self.uv0.len()), ("uv1", self.uv1.len()), ("normals", self.normals.len()), ("colors", self.colors.len())]
        {
            if len != 0 && len != wedges {
                return bad(format!("{name} has {len} entries for {wedges} wedges"));
            }
        }
        if let Some(w) = self.wedge_vertex.iter().position(|&v| v as usize >= vertex_count) {
            return bad(format!("wedge {w} names vertex {} of {vertex_count}", self.wedge_vertex[w]));
        }
        for (t, (tri, cw)) in triangles.iter().zip(&self.corner_wedges).enumerate() {
            for i in 0..3 {
                match self.wedge_vertex.get(cw[i] as usize) {
                    Some(&v) if v == tri[i] => {}
                    Some(&v) => return bad(format!("triangle {t} corner {i}: wedge {} is on vertex {v}, the corner on {}", cw[i], tri[i])),
                    None => return bad(format!("triangle {t} corner {i}: wedge {} of {wedges}", cw[i])),
                }
            }
        }
        if let Some(w) = self.uv0.iter().chain(&self.uv1).position(|uv| !uv.iter().all(|x| x.is_finite())) {
            return bad(format!("texture coordinates of wedge {} are not finite", w % wedges.max(1)));
        }
        if let Some(w) = self.normals.iter().position(|n| !n.iter().all(|x| x.is_finite())) {
            return bad(format!("the normal of wedge {w} is not finite"));
        }
        if let Some(w) = self.colors.iter().position(|c| !c.iter().all(|x| x.is_finite())) {
            return bad(format!("the colour of wedge {w} is not finite"));
        }
        if !self.triangle_material.is_empty() && self.triangle_material.len() != triangles.len() {
            return bad(format!("{} triangles but {} triangle materials", triangles.len(), self.triangle_material.len()));
        }
        let materials = self.materials.len().max(1);
        if let Some(t) = self.triangle_material.iter().position(|&m| m as usize >= materials) {
            return bad(format!("triangle {t} uses material {} of {materials}", self.triangle_material[t]));
        }
        for (m, mat) in self.materials.iter().enumerate() {
            let refs = [
                &mat.base_color_texture,
                &mat.metallic_roughness_texture,
                &mat.normal_texture,
                &mat.occlusion_texture,
                &mat.emissive_texture,
            ];
            for r in refs.into_iter().flatten() {
                if r.texture as usize >= self.textures.len() {
                    return bad(format!("material {m} uses texture {} of {}", r.texture, self.textures.len()));
                }
            }
        }
        for (i, tex) in self.textures.iter().enumerate() {
            if tex.image as usize >= self.images.len() {
                return bad(format!("texture {i} uses image {} of {}", tex.image, self.images.len()));
            }
            if tex.sampler.is_some_and(|s| s as usize >= self.samplers.len()) {
                return bad(format!("texture {i} uses a sampler out of range"));
            }
        }
        Ok(())
    }
}

// ------------------------------------------------------------------------------------------------
// Keeping wedges right when a mesh's vertices or triangles change
// ------------------------------------------------------------------------------------------------

impl Appearance {
    /// Keeps the corner wedges and materials of the triangles `kept` (old triangle indices,
    /// increasing), so that they stay parallel to a filtered triangle list.
    pub fn retain_triangles(&mut self, kept: &[usize]) {
        self.corner_wedges = kept.iter().filter_map(|&t| self.corner_wedges.get(t).copied()).collect();
        if !self.triangle_material.is_empty() {
            self.triangle_material = kept.iter().filter_map(|&t| self.triangle_material.get(t).copied()).collect();
        }
    }

    /// Moves every wedge to the new index of its vertex (`remap[old]`, `u32::MAX` for a vertex
    /// that went), merges wedges that now sit on one vertex with bitwise-equal attributes, and
    /// drops wedges no corner uses. Wedges keep their order (the first of equal ones survives).
    pub fn remap_vertices(&mut self, remap: &[u32]) {
        for v in &mut self.wedge_vertex {
            *v = remap.get(*v as usize).copied().unwrap_or(u32::MAX);
        }
        let mut used = vec![false; self.wedge_count()];
        for &w in self.corner_wedges.iter().flatten() {
            if let Some(u) = used.get_mut(w as usize) {
                *u = true;
            }
        }
        let mut first_of: std::collections::HashMap<Vec<u32>, u32> = std::collections::HashMap::new();
        let mut keep: Vec<usize> = Vec::new();
        let mut wedge_remap = vec![u32::MAX; self.wedge_count()];
        for w in 0..self.wedge_count() {
            if !used[w] || self.wedge_vertex[w] == u32::MAX {
                continue;
            }
            let next = keep.len() as u32;
            wedge_remap[w] = *first_of.entry(self.wedge_key(w)).or_insert_with(|| {
                keep.push(w);
                next
            });
        }
        fn gather<T: Copy>(old: &[T], keep: &[usize]) -> Vec<T> {
            if old.is_empty() { Vec::new() } else { keep.iter().filter_map(|&w| old.get(w).copied()).collect() }
        }
        self.wedge_vertex = gather(&self.wedge_vertex, &keep);
        self.uv0 = gather(&self.uv0, &keep);
        self.uv1 = gather(&self.uv1, &keep);
        self.normals = gather(&self.normals, &keep);
        self.colors = gather(&self.colors, &keep);
        for c in self.corner_wedges.iter_mut().flatten() {
            *c = wedge_remap.get(*c as usize).copied().unwrap_or(u32::MAX);
        }
    }

    /// A wedge's vertex and the bits of all its attributes.
    fn wedge_key(&self, w: usize) -> Vec<u32> {
        let mut key = vec![self.wedge_vertex[w]];
        key.extend(self.uv0.get(w).into_iter().flatten().map(|x| x.to_bits()));
        key.extend(self.uv1.get(w).into_iter().flatten().map(|x| x.to_bits()));
        key.extend(self.normals.get(w).into_iter().flatten().map(|x| x.to_bits()));
        key.extend(self.colors.get(w).into_iter().flatten().map(|x| x.to_bits()));
        key
    }

    /// Material of triangle `t` (0 when triangles carry none).
    pub fn material_of(&self, t: usize) -> u32 {
        self.triangle_material.get(t).copied().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::image_mime_type;

    #[test]
    fn images_are_known_by_their_signatures_alone() {
        assert_eq!(image_mime_type(b"\x89PNG\r\n\x1a\n rest"), Some("image/png"));
        assert_eq!(image_mime_type(&[0xFF, 0xD8, 0xFF, 0xE0]), Some("image/jpeg"));
        // A truncated signature, a GIF and nothing at all are neither.
        assert_eq!(image_mime_type(b"\x89PNG\r\n"), None);
        assert_eq!(image_mime_type(b"GIF89a"), None);
        assert_eq!(image_mime_type(&[0xFF, 0xD8]), None);
        assert_eq!(image_mime_type(&[]), None);
    }
}
