//! The serialized form of a document's appearance (materials, textures, samplers, images), read
//! apart from `gltf`'s JSON types: those only expose `KHR_texture_transform` on some texture
//! references and only with crate features, and a second narrow parse keeps the reading of
//! looks independent of everything else. Unknown fields are skipped; defaults are glTF's.

use serde::Deserialize;

/// The parts of the root object this module reads. Everything else (buffers with megabytes of
/// base64, animations) is skipped by serde without being kept.
#[derive(Deserialize, Default)]
#[serde(default)]
pub(super) struct RawLooks {
    pub materials: Vec<RawMaterial>,
    pub textures: Vec<RawTexture>,
    pub samplers: Vec<RawSampler>,
    pub images: Vec<RawImage>,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
pub(super) struct RawMaterial {
    pub name: Option<String>,
    pub pbr_metallic_roughness: RawPbr,
    pub normal_texture: Option<RawTextureInfo>,
    pub occlusion_texture: Option<RawTextureInfo>,
    pub emissive_texture: Option<RawTextureInfo>,
    pub emissive_factor: Option<[f32; 3]>,
    pub alpha_mode: Option<String>,
    pub alpha_cutoff: Option<f32>,
    pub double_sided: bool,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
pub(super) struct RawPbr {
    pub base_color_factor: Option<[f32; 4]>,
    pub base_color_texture: Option<RawTextureInfo>,
    pub metallic_factor: Option<f32>,
    pub roughness_factor: Option<f32>,
    pub metallic_roughness_texture: Option<RawTextureInfo>,
}

/// `textureInfo`, `normalTextureInfo` and `occlusionTextureInfo` in one: `scale` and
/// `strength` are read where they mean something.
#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct RawTextureInfo {
    pub index: u64,
    #[serde(default)]
    pub tex_coord: u32,
    pub scale: Option<f32>,
    pub strength: Option<f32>,
    #[serde(default)]
    pub extensions: RawInfoExtensions,
}

#[derive(Deserialize, Default)]
#[serde(default)]
pub(super) struct RawInfoExtensions {
    #[serde(rename = "KHR_texture_transform")]
    pub texture_transform: Option<RawTextureTransform>,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
pub(super) struct RawTextureTransform {
    pub offset: Option<[f32; 2]>,
    pub rotation: Option<f32>,
    pub scale: Option<[f32; 2]>,
    pub tex_coord: Option<u32>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
pub(super) struct RawTexture {
    pub sampler: Option<u64>,
    pub source: Option<u64>,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
pub(super) struct RawSampler {
    pub mag_filter: Option<u32>,
    pub min_filter: Option<u32>,
    pub wrap_s: Option<u32>,
    pub wrap_t: Option<u32>,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
pub(super) struct RawImage {
    pub name: Option<String>,
    pub uri: Option<String>,
    pub mime_type: Option<String>,
    pub buffer_view: Option<u64>,
}
