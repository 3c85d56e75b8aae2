//! A textured sample: the waving cloth with texture coordinates, two materials (a textured
//! left half, a plain coloured right half), vertex colours, and a small checkerboard PNG made
//! by our own encoder, so that every appearance test has a textured input without any
//! third-party file.

use crate::Sequence;
use crate::appearance::{AlphaMode, Appearance, Image, Material, Texture, TextureRef};

/// [`super::waving_cloth`] with an [`Appearance`]: UVs spanning the sheet (v down from the
/// pinned top edge), material 0 (textured) on the left half and material 1 (orange, double
/// sided, alpha 0.9 blended) on the right, a seam of doubled wedges where they meet, and a
/// colour gradient. `texture_size` is the checkerboard's width and height in pixels.
pub fn textured_cloth(w: u32, h: u32, frames: u32, texture_size: u32) -> Sequence {
    let mut seq = super::waving_cloth(w, h, frames);
    let (w, h) = (w.max(2), h.max(2));
    let split = (w - 1) / 2; // quads with x < split are material 0
    let mut a = Appearance::default();
    // Wedges: one per vertex, plus a second one for the vertices of the seam column, used by
    // the right half (a material boundary is a seam).
    let vertex_wedge = |v: u32| v;
    let mut seam_wedge = vec![u32::MAX; (w * h) as usize];
    let uv_of = |v: u32| [(v % w) as f32 / (w - 1) as f32, (v / w) as f32 / (h - 1) as f32];
    let colour_of = |v: u32, right: bool| {
        let [u, t] = uv_of(v);
        if right { [1.0, 0.5 + 0.5 * t, 0.2, 1.0] } else { [0.5 + 0.5 * u, 1.0, 1.0 - 0.5 * t, 1.0] }
    };
    for v in 0..w * h {
        a.wedge_vertex.push(v);
        a.uv0.push(uv_of(v));
        a.colors.push(colour_of(v, false));
    }
    for v in (0..h).map(|y| y * w + split) {
        seam_wedge[v as usize] = a.wedge_vertex.len() as u32;
        a.wedge_vertex.push(v);
        // The right half maps to its own region of the texture: a UV seam as well.
        let [u, t] = uv_of(v);
        a.uv0.push([u + 0.25, t]);
        a.colors.push(colour_of(v, true));
    }
    for tri in &seq.triangles {
        let right = tri.iter().map(|&v| v % w).min().unwrap_or(0) >= split;
        a.triangle_material.push(right as u32);
        a.corner_wedges.push(tri.map(|v| if right && v % w == split { seam_wedge[v as usize] } else { vertex_wedge(v) }));
    }
    // Right-half wedges off the seam: their UVs shift too, and their colours are the right's.
    for (v, (uv, c)) in a.uv0.iter_mut().zip(a.colors.iter_mut()).enumerate().take((w * h) as usize) {
        if (v as u32 % w) > split {
            uv[0] += 0.25;
            *c = colour_of(v as u32, true);
        }
    }
    a.materials.push(Material {
        name: Some("checker".into()),
        base_color_texture: Some(TextureRef { texture: 0, tex_coord: 0, transform: None }),
        metallic_factor: 0.0,
        ..Default::default()
    });
    a.materials.push(Material {
        name: Some("orange".into()),
        base_color_factor: [1.0, 0.45, 0.1, 0.9],
        metallic_factor: 0.0,
        roughness_factor: 0.6,
        alpha_mode: AlphaMode::Blend,
        double_sided: true,
        ..Default::default()
    });
    a.textures.push(Texture { image: 0, sampler: None });
    a.images.push(Image { name: Some("checker.png".into()), mime_type: "image/png".into(), bytes: checkerboard_png(texture_size.max(1)) });
    seq.appearance = Some(a);
    seq
}

/// An 8 x 8 checkerboard of two colours, `size` pixels square, as PNG bytes.
pub fn checkerboard_png(size: u32) -> Vec<u8> {
    let cell = (size / 8).max(1);
    let mut rgba = Vec::with_capacity((size * size * 4) as usize);
    for y in 0..size {
        for x in 0..size {
            let dark = ((x / cell) + (y / cell)) % 2 == 1;
            rgba.extend_from_slice(if dark { &[40, 60, 160, 255] } else { &[240, 230, 200, 255] });
        }
    }
    png_rgba(size, size, &rgba)
}

/// Encodes 8-bit RGBA pixels (rows top to bottom) as a PNG (ISO/IEC 15948): one IDAT whose
/// zlib stream (RFC 1950) holds stored deflate blocks (RFC 1951 section 3.2.4). Uncompressed,
/// which is what a small test texture needs: no dependency, and any decoder reads it.
pub fn png_rgba(width: u32, height: u32, rgba: &[u8]) -> Vec<u8> {
    let row = width as usize * 4;
    let mut raw = Vec::with_capacity((row + 1) * height as usize);
    for y in 0..height as usize {
        raw.push(0); // filter type None
        raw.extend_from_slice(&rgba[y * row..(y + 1) * row]);
    }
    let mut z = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65_535).collect();
    for (i, block) in blocks.iter().enumerate() {
        z.push((i + 1 == blocks.len()) as u8);
        let len = block.len() as u16;
        z.extend_from_slice(&len.to_le_bytes());
        z.extend_from_slice(&(!len).to_le_bytes());
        z.extend_from_slice(block);
    }
    z.extend_from_slice(&adler32(&raw).to_be_bytes());
    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]); // 8 bits, RGBA, deflate, adaptive filters, no interlace
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    for (kind, data) in [(b"IHDR", &ihdr[..]), (b"IDAT", &z[..]), (b"IEND", &[][..])] {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let start = png.len();
        png.extend_from_slice(kind);
        png.extend_from_slice(data);
        let crc = crc32(&png[start..]);
        png.extend_from_slice(&crc.to_be_bytes());
    }
    png
}

fn adler32(data: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for chunk in data.chunks(5552) {
        for &x in chunk {
            a += x as u32;
            b += a;
        }
        a %= 65_521;
        b %= 65_521;
    }
    (b << 16) | a
}

/// CRC-32 (IEEE 802.3), bit by bit: a test texture is small.
fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &x in data {
        c ^= x as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textured_cloth_is_valid_with_a_seam() {
        let seq = textured_cloth(12, 8, 4, 16);
        seq.validate().expect("valid");
        let a = seq.appearance.as_ref().expect("appearance");
        assert_eq!(a.wedge_count(), 12 * 8 + 8);
        assert!(a.triangle_material.contains(&0) && a.triangle_material.contains(&1));
        assert!(a.images[0].bytes.starts_with(b"\x89PNG"));
    }

    #[test]
    fn png_checksums_are_the_known_ones() {
        // The IEND chunk's CRC is fixed by the format: AE 42 60 82.
        let png = png_rgba(1, 1, &[1, 2, 3, 4]);
        assert_eq!(&png[png.len() - 4..], &[0xAE, 0x42, 0x60, 0x82]);
        assert_eq!(adler32(b"Wikipedia"), 0x11E6_0398);
    }
}
