//! The skin of a decoded frame in floating point, for writers that hand it to an engine
//! (`pmcodec decode --skinned-glb`): bind positions in the header's units and each palette
//! entry as the affine map from them to the frame's positions.
//!
//! The integer skinning of proto/container.md ("Skinning") maps a bind position `b` (in
//! `bind_step` quanta) through entry `e` to `L_e b / 2^15 + T_e / 4` position quanta, which the
//! header's grid places at `bbox_min + step * q`. With `x = b * bind_step` that is the affine map
//! `x -> bbox_min + step * (L_e x / (2^15 bind_step) + T_e / 4)`, exact up to the integer
//! skinning's rounding (a quarter of a quantum at most).

use super::{ENTRY, LINEAR_BITS, NodeSkin, TRANSLATION_BITS, WEIGHT_ONE};
use crate::Header;
use glam::{DMat4, DVec4, Mat4, Vec3};

/// A node's bind position in the header's units (`None` in files without a skin).
pub fn bind_position(header: &Header, skin: &NodeSkin) -> Option<Vec3> {
    let step = header.skin.as_ref()?.bind_step as f64;
    Some(Vec3::new((skin.bind[0] as f64 * step) as f32, (skin.bind[1] as f64 * step) as f32, (skin.bind[2] as f64 * step) as f32))
}

/// A node's influences as (palette entry, weight in 0..=1) pairs; unused slots have weight 0.
pub fn influences(skin: &NodeSkin) -> [(u32, f32); 4] {
    [0, 1, 2, 3].map(|k| (skin.joints[k], skin.weights[k].max(0) as f32 / WEIGHT_ONE as f32))
}

/// Every entry of `palette` (a decoded frame's, `ENTRY` values each) as the map from bind
/// positions in the header's units to that frame's positions (`None` in files without a skin).
pub fn palette_transforms(header: &Header, palette: &[i64]) -> Option<Vec<Mat4>> {
    let bind_step = header.skin.as_ref()?.bind_step as f64;
    let step = header.quantization.step as f64;
    let lo = header.bbox_min.map(|v| v as f64);
    let linear = step / ((1u64 << LINEAR_BITS) as f64 * bind_step);
    let translation = step / (1u64 << TRANSLATION_BITS) as f64;
    Some(
        palette
            .chunks_exact(ENTRY)
            .map(|m| {
                // Rows a = 0..2 of (L[a][0], L[a][1], L[a][2], T[a]); glam's matrices are by column.
                let row = |a: usize| &m[4 * a..4 * a + 4];
                let col = |c: usize| DVec4::new(row(0)[c] as f64 * linear, row(1)[c] as f64 * linear, row(2)[c] as f64 * linear, 0.0);
                let t = DVec4::new(
                    lo[0] + row(0)[3] as f64 * translation,
                    lo[1] + row(1)[3] as f64 * translation,
                    lo[2] + row(2)[3] as f64 * translation,
                    1.0,
                );
                DMat4::from_cols(col(0), col(1), col(2), t).as_mat4()
            })
            .collect(),
    )
}
