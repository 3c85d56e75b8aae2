//! The raw serialized types of version 6's appearance (postcard; proto/container.md,
//! "Appearance"), kept apart from [`pmcodec_mesh::Appearance`], the ergonomic type they are
//! converted from and to.

use pmcodec_mesh::appearance::{AlphaMode, Image, Material, Sampler, Texture, TextureRef, TextureTransform};
use serde::{Deserialize, Serialize};

/// The header's `appearance` field: what a reader needs to size and read the appearance
/// chunks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AppearanceInfo {
    /// Charts (proto/container.md, "Charts"); at least 1, at most the triangles.
    pub charts: u32,
    /// Smoothing groups; at least 1, at most the charts.
    pub groups: u32,
    /// Materials (0: every chart uses glTF's default material).
    pub materials: u32,
    /// Images, each an Image chunk (band = its index).
    pub images: u32,
    /// Texture coordinate sets per attribute entry: 0, 1 (`uv0`) or 2 (`uv0`, `uv1`).
    pub uv_sets: u8,
    /// Texture coordinates are `uv_min + q * uv_step` per axis (both sets).
    pub uv_min: [f32; 2],
    /// Quantum of texture coordinates per axis, `(max - min) / (2^bits - 1)`.
    pub uv_step: [f32; 2],
    /// Whether entries carry an RGBA colour (8 bits per channel, linear).
    pub colors: bool,
    /// Whether the input had normals (its creases split the smoothing groups); informative.
    pub normals: bool,
}

impl AppearanceInfo {
    /// Scalar channels per attribute entry: two per texture coordinate set, four for colour.
    pub fn channels(&self) -> usize {
        2 * self.uv_sets as usize + if self.colors { 4 } else { 0 }
    }
}

/// The Materials chunk (postcard).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MaterialsChunk {
    /// Materials in the input's order; charts name them by index.
    pub materials: Vec<RawMaterial>,
    /// Textures (an image and a sampler each).
    pub textures: Vec<RawTexture>,
    /// Samplers, glTF's numeric filter and wrap enums.
    pub samplers: Vec<RawSampler>,
    /// Image descriptions; image `i`'s bytes are the Image chunk of band `i`.
    pub images: Vec<RawImage>,
}

/// A glTF 2.0 metallic-roughness material as stored; [`pmcodec_mesh::appearance::Material`]
/// documents each field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RawMaterial {
    /// The input's name for it, if any.
    pub name: Option<String>,
    /// `baseColorFactor`, linear RGBA.
    pub base_color_factor: [f32; 4],
    /// `baseColorTexture`.
    pub base_color_texture: Option<RawTextureRef>,
    /// `metallicFactor`.
    pub metallic_factor: f32,
    /// `roughnessFactor`.
    pub roughness_factor: f32,
    /// `metallicRoughnessTexture`.
    pub metallic_roughness_texture: Option<RawTextureRef>,
    /// `normalTexture`.
    pub normal_texture: Option<RawTextureRef>,
    /// `normalTexture.scale`.
    pub normal_scale: f32,
    /// `occlusionTexture`.
    pub occlusion_texture: Option<RawTextureRef>,
    /// `occlusionTexture.strength`.
    pub occlusion_strength: f32,
    /// `emissiveTexture`.
    pub emissive_texture: Option<RawTextureRef>,
    /// `emissiveFactor`, linear RGB.
    pub emissive_factor: [f32; 3],
    /// 0 opaque, 1 mask, 2 blend.
    pub alpha_mode: u8,
    /// `alphaCutoff`, for mode 1 (mask).
    pub alpha_cutoff: f32,
    /// `doubleSided`.
    pub double_sided: bool,
}

/// A material's use of a texture, as stored.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RawTextureRef {
    /// Index into [`MaterialsChunk::textures`].
    pub texture: u32,
    /// Texture coordinate set: 0 or 1.
    pub tex_coord: u32,
    /// `KHR_texture_transform`, when present.
    pub transform: Option<RawTransform>,
}

/// `KHR_texture_transform`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RawTransform {
    /// UV offset.
    pub offset: [f32; 2],
    /// Rotation in radians.
    pub rotation: f32,
    /// UV scale.
    pub scale: [f32; 2],
    /// Texture coordinate set overriding [`RawTextureRef::tex_coord`].
    pub tex_coord: Option<u32>,
}

/// A texture as stored: an image and how it is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RawTexture {
    /// Index into [`MaterialsChunk::images`].
    pub image: u32,
    /// Index into [`MaterialsChunk::samplers`]; `None` for glTF's default sampler.
    pub sampler: Option<u32>,
}

/// A glTF sampler as stored (its numeric enums, as in the input).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RawSampler {
    /// `magFilter`.
    pub mag_filter: Option<u32>,
    /// `minFilter`.
    pub min_filter: Option<u32>,
    /// `wrapS`.
    pub wrap_s: u32,
    /// `wrapT`.
    pub wrap_t: u32,
}

/// An image's description; its bytes are its Image chunk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RawImage {
    /// The input's name for it, if any.
    pub name: Option<String>,
    /// `image/png` or `image/jpeg`, from the bytes' signature.
    pub mime_type: String,
    /// Length of its Image chunk's payload; a reader checks the chunk against it.
    pub byte_length: u32,
}

fn raw_ref(r: &Option<TextureRef>) -> Option<RawTextureRef> {
    r.map(|r| RawTextureRef {
        texture: r.texture,
        tex_coord: r.tex_coord,
        transform: r.transform.map(|t| RawTransform { offset: t.offset, rotation: t.rotation, scale: t.scale, tex_coord: t.tex_coord }),
    })
}

fn cooked_ref(r: &Option<RawTextureRef>) -> Option<TextureRef> {
    r.map(|r| TextureRef {
        texture: r.texture,
        tex_coord: r.tex_coord,
        transform: r.transform.map(|t| TextureTransform { offset: t.offset, rotation: t.rotation, scale: t.scale, tex_coord: t.tex_coord }),
    })
}

impl MaterialsChunk {
    /// The chunk for `a`'s materials, textures, samplers and image descriptions (the image bytes go in Image chunks).
    pub fn from_appearance(a: &pmcodec_mesh::Appearance) -> MaterialsChunk {
        MaterialsChunk {
            materials: a
                .materials
                .iter()
                .map(|m| RawMaterial {
                    name: m.name.clone(),
                    base_color_factor: m.base_color_factor,
                    base_color_texture: raw_ref(&m.base_color_texture),
                    metallic_factor: m.metallic_factor,
                    roughness_factor: m.roughness_factor,
                    metallic_roughness_texture: raw_ref(&m.metallic_roughness_texture),
                    normal_texture: raw_ref(&m.normal_texture),
                    normal_scale: m.normal_scale,
                    occlusion_texture: raw_ref(&m.occlusion_texture),
                    occlusion_strength: m.occlusion_strength,
                    emissive_texture: raw_ref(&m.emissive_texture),
                    emissive_factor: m.emissive_factor,
                    alpha_mode: match m.alpha_mode {
                        AlphaMode::Opaque => 0,
                        AlphaMode::Mask => 1,
                        AlphaMode::Blend => 2,
                    },
                    alpha_cutoff: m.alpha_cutoff,
                    double_sided: m.double_sided,
                })
                .collect(),
            textures: a.textures.iter().map(|t| RawTexture { image: t.image, sampler: t.sampler }).collect(),
            samplers: a
                .samplers
                .iter()
                .map(|s| RawSampler { mag_filter: s.mag_filter, min_filter: s.min_filter, wrap_s: s.wrap_s, wrap_t: s.wrap_t })
                .collect(),
            images: a
                .images
                .iter()
                .map(|i| RawImage { name: i.name.clone(), mime_type: i.mime_type.clone(), byte_length: i.bytes.len() as u32 })
                .collect(),
        }
    }

    /// Checks every index and enum against the counts, naming the first that is wrong.
    pub fn check(&self, info: &AppearanceInfo) -> Result<(), String> {
        if self.materials.len() != info.materials as usize || self.images.len() != info.images as usize {
            return Err(format!(
                "{} materials and {} images where the header says {} and {}",
                self.materials.len(),
                self.images.len(),
                info.materials,
                info.images
            ));
        }
        for (m, mat) in self.materials.iter().enumerate() {
            if mat.alpha_mode > 2 {
                return Err(format!("material {m}: alpha mode {}", mat.alpha_mode));
            }
            let refs = [
                &mat.base_color_texture,
                &mat.metallic_roughness_texture,
                &mat.normal_texture,
                &mat.occlusion_texture,
                &mat.emissive_texture,
            ];
            if let Some(r) = refs.into_iter().flatten().find(|r| r.texture as usize >= self.textures.len()) {
                return Err(format!("material {m} uses texture {} of {}", r.texture, self.textures.len()));
            }
        }
        for (i, t) in self.textures.iter().enumerate() {
            if t.image as usize >= self.images.len() || t.sampler.is_some_and(|s| s as usize >= self.samplers.len()) {
                return Err(format!("texture {i}: image or sampler out of range"));
            }
        }
        Ok(())
    }

    /// The materials, textures and samplers as [`pmcodec_mesh::Appearance`] fields; images
    /// get their descriptions and `bytes` in order (each an Image chunk's payload).
    pub fn to_appearance(&self, image_bytes: Vec<Vec<u8>>) -> pmcodec_mesh::Appearance {
        let mut bytes = image_bytes.into_iter();
        pmcodec_mesh::Appearance {
            materials: self
                .materials
                .iter()
                .map(|m| Material {
                    name: m.name.clone(),
                    base_color_factor: m.base_color_factor,
                    base_color_texture: cooked_ref(&m.base_color_texture),
                    metallic_factor: m.metallic_factor,
                    roughness_factor: m.roughness_factor,
                    metallic_roughness_texture: cooked_ref(&m.metallic_roughness_texture),
                    normal_texture: cooked_ref(&m.normal_texture),
                    normal_scale: m.normal_scale,
                    occlusion_texture: cooked_ref(&m.occlusion_texture),
                    occlusion_strength: m.occlusion_strength,
                    emissive_texture: cooked_ref(&m.emissive_texture),
                    emissive_factor: m.emissive_factor,
                    alpha_mode: match m.alpha_mode {
                        1 => AlphaMode::Mask,
                        2 => AlphaMode::Blend,
                        _ => AlphaMode::Opaque,
                    },
                    alpha_cutoff: m.alpha_cutoff,
                    double_sided: m.double_sided,
                })
                .collect(),
            textures: self.textures.iter().map(|t| Texture { image: t.image, sampler: t.sampler }).collect(),
            samplers: self
                .samplers
                .iter()
                .map(|s| Sampler { mag_filter: s.mag_filter, min_filter: s.min_filter, wrap_s: s.wrap_s, wrap_t: s.wrap_t })
                .collect(),
            images: self
                .images
                .iter()
                .map(|i| Image { name: i.name.clone(), mime_type: i.mime_type.clone(), bytes: bytes.next().unwrap_or_default() })
                .collect(),
            ..Default::default()
        }
    }
}
