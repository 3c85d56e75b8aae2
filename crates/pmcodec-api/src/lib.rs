//! The JSON bodies of the pmcodec HTTP API (proto/http.md, proto/openapi.yaml): written by
//! `pmcodec-server`, read by `pmcodec-client`, so that the two cannot drift apart.
#![warn(missing_docs)]

use serde::{Deserialize, Serialize};

/// What `GET /v1/assets` lists per asset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AssetSummary {
    /// The asset's id (its name in the store).
    pub id: String,
    /// The container's content hash: what its immutable URLs and strong ETags carry.
    pub version: String,
    /// Frames in the sequence.
    pub frames: u32,
    /// Playback rate, frames per second.
    pub frame_rate: f32,
    /// Vertices of the input mesh (level 0).
    pub vertices: u32,
    /// Triangles of the input mesh.
    pub triangles: u32,
    /// Nodes per level, `|M_0|` (the input) to `|M_top|`.
    pub levels: Vec<u32>,
    /// Size of the container.
    pub bytes: u64,
    /// The container's immutable URL.
    pub file: String,
}

/// What `GET /v1/assets/{id}` returns.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AssetInfo {
    #[serde(flatten)]
    /// What the asset list says of it.
    pub summary: AssetSummary,
    /// Bounding box over all frames: its low corner.
    pub bbox_min: [f32; 3],
    /// Bounding box over all frames: its high corner.
    pub bbox_max: [f32; 3],
    /// Frames from one keyframe to the next.
    pub keyframe_interval: u32,
    /// Triangles shown when every node of a level is drawn (frame 0).
    pub triangles_per_level: Vec<usize>,
    /// Stored bytes of each band (all frames).
    pub bytes_per_level: Vec<u64>,
    /// Everything a client stopping at each level reads: preamble, header, index, the bands
    /// from the top down to that level, and the input triangles for level 0.
    pub bytes_to_level: Vec<u64>,
    /// Bytes per frame of deltas and positions a client stopping at each level reads.
    pub bytes_per_frame_to_level: Vec<f64>,
    /// Stored bits of quantized positions per vertex and frame.
    pub positions_bits_per_vertex_frame: f64,
    /// The chunk table (JSON) at an immutable URL.
    pub index: String,
    /// Header and frames in playback order, one request.
    pub stream: String,
    /// The encoder that wrote the container.
    pub generator: String,
    /// Texture coordinates, colours, materials and textures (container version 6); absent for
    /// a bare surface.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<AssetAppearance>,
}

/// An asset's appearance, as `GET /v1/assets/{id}` describes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AssetAppearance {
    /// Charts: regions of one material and continuous texture coordinates.
    pub charts: u32,
    /// Texture coordinate sets (0, 1 or 2).
    pub uv_sets: u8,
    /// Whether vertices carry colours.
    pub colors: bool,
    /// The materials, in the order triangles name them.
    pub materials: Vec<MaterialInfo>,
    /// One per image, in order; a material's texture indices point here.
    pub textures: Vec<TextureInfo>,
    /// Stored bytes of the attribute table of each level (all a client at level L reads is
    /// levels L..top), and of the charts and materials every client reads once.
    pub attribute_bytes_per_level: Vec<u64>,
    /// Stored bytes of the charts.
    pub charts_bytes: u64,
    /// Stored bytes of the materials.
    pub materials_bytes: u64,
}

/// A material (glTF metallic-roughness, the fields a viewer needs first).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialInfo {
    /// The material's name in the input, if it had one.
    pub name: Option<String>,
    /// Base colour factor, linear RGBA.
    pub base_color_factor: [f32; 4],
    /// Index into `textures` of the base colour texture.
    pub base_color_texture: Option<u32>,
    /// Metalness factor, 0 to 1.
    pub metallic_factor: f32,
    /// Roughness factor, 0 to 1.
    pub roughness_factor: f32,
    /// `OPAQUE`, `MASK` or `BLEND`.
    pub alpha_mode: String,
    /// Alpha below which a `MASK` material is transparent.
    pub alpha_cutoff: f32,
    /// Whether back faces are drawn.
    pub double_sided: bool,
}

/// A texture image at its immutable URL.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TextureInfo {
    /// The image's name in the input, if it had one.
    pub name: Option<String>,
    /// `image/png` or `image/jpeg`.
    pub mime_type: String,
    /// Size of the image.
    pub bytes: u64,
    /// `/v1/assets/{id}/v/{version}/images/{n}`.
    pub url: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn asset_info_is_flat_json_and_round_trips() {
        let summary = AssetSummary {
            id: "horse".into(),
            version: "414ac7f9".into(),
            frames: 48,
            frame_rate: 30.0,
            vertices: 8431,
            triangles: 16843,
            levels: vec![8431, 2108, 843],
            bytes: 976_125,
            file: "/v1/assets/horse/v/414ac7f9/file".into(),
        };
        let info = AssetInfo {
            summary,
            bbox_min: [-1.0, 0.0, -2.0],
            bbox_max: [1.0, 2.0, 2.0],
            keyframe_interval: 16,
            triangles_per_level: vec![16843, 4200, 1678],
            bytes_per_level: vec![700_000, 200_000, 60_000],
            bytes_to_level: vec![976_125, 260_000, 61_000],
            bytes_per_frame_to_level: vec![14925.0, 6021.0, 2657.0],
            positions_bits_per_vertex_frame: 13.8,
            index: "/v1/assets/horse/v/414ac7f9/index".into(),
            stream: "/v1/assets/horse/stream".into(),
            generator: "pmcodec 0.1.0".into(),
            appearance: None,
        };
        let json = serde_json::to_value(&info).expect("serialize");
        // The summary's fields sit at the top level beside the details (proto/http.md).
        assert_eq!(json["id"], "horse");
        assert_eq!(json["triangles_per_level"][2], 1678);
        assert!(json.get("summary").is_none());
        let back: AssetInfo = serde_json::from_value(json).expect("deserialize");
        assert_eq!(back, info);
    }
}
