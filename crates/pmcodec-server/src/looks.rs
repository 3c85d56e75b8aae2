//! Appearance (container version 6) over HTTP: what an asset's metadata says of its materials
//! and textures, and each texture image at its own immutable URL (proto/http.md, "Textures").

use crate::ApiError;
use crate::assets::LoadedAsset;
use bytes::Bytes;
use pmcodec_api::{AssetAppearance, MaterialInfo, TextureInfo};
use pmcodec_container::appearance::read_materials;
use pmcodec_container::{ByteSource, ChunkKind, Reader, Summary};

/// The metadata's `appearance`: materials, textures with their byte sizes and URLs (`base` is
/// `/v1/assets/{id}/v/{version}`), and the appearance bytes per level. `None` for a bare surface.
pub fn appearance<S: ByteSource>(reader: &Reader<S>, s: &Summary, base: &str) -> Result<Option<AssetAppearance>, String> {
    let Some(info) = &reader.header().appearance else { return Ok(None) };
    let m = read_materials(reader).map_err(|e| e.to_string())?;
    let materials = m
        .materials
        .iter()
        .map(|x| MaterialInfo {
            name: x.name.clone(),
            base_color_factor: x.base_color_factor,
            // Textures are listed one per image: name the image.
            base_color_texture: x.base_color_texture.and_then(|r| m.textures.get(r.texture as usize)).map(|t| t.image),
            metallic_factor: x.metallic_factor,
            roughness_factor: x.roughness_factor,
            alpha_mode: ["OPAQUE", "MASK", "BLEND"][x.alpha_mode.min(2) as usize].to_string(),
            alpha_cutoff: x.alpha_cutoff,
            double_sided: x.double_sided,
        })
        .collect();
    let textures = m
        .images
        .iter()
        .enumerate()
        .map(|(i, im)| TextureInfo {
            name: im.name.clone(),
            mime_type: im.mime_type.clone(),
            bytes: im.byte_length as u64,
            url: format!("{base}/images/{i}"),
        })
        .collect();
    Ok(Some(AssetAppearance {
        charts: info.charts,
        uv_sets: info.uv_sets,
        colors: info.colors,
        materials,
        textures,
        attribute_bytes_per_level: s.attributes_bytes.clone(),
        charts_bytes: s.charts_bytes,
        materials_bytes: s.materials_bytes,
    }))
}

/// Image `n`'s bytes (its chunk, checked and decompressed) and MIME type.
pub fn image(a: &LoadedAsset, n: u32) -> Result<(Bytes, &'static str), ApiError> {
    let images = a.header.appearance.as_ref().map_or(0, |x| x.images);
    let e = a.chunks.iter().find(|e| e.kind == ChunkKind::Image && e.band == n).ok_or_else(|| {
        ApiError::NotFound(format!(
            "image {n}: asset {} has {}",
            a.id,
            if images == 0 { "no images".into() } else { format!("images 0..={}", images - 1) }
        ))
    })?;
    let reader = Reader::open(&a.bytes[..]).map_err(|e| ApiError::Internal(format!("asset {}: {e}", a.id)))?;
    let raw = reader.read_chunk(e).map_err(|e| ApiError::Internal(format!("asset {} image {n}: {e}", a.id)))?;
    let mime = pmcodec_mesh::appearance::image_mime_type(&raw).unwrap_or("application/octet-stream");
    Ok((Bytes::from(raw), mime))
}
