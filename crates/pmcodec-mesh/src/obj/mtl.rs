//! Wavefront material libraries (`.mtl`): the few statements that map onto glTF's
//! metallic-roughness material. `Kd` is the base colour, `d` (or `Tr = 1 - d`) its alpha, and
//! `map_Kd` its texture, an image file named relative to the library. Everything else (`Ka`,
//! `Ks`, `Ns`, `illum`, other maps) is accepted and ignored: OBJ's Phong parameters have no
//! faithful metallic-roughness equivalent, so materials come out dielectric and fully rough.

use crate::MeshError;
use crate::appearance::{AlphaMode, Image, Material, image_mime_type};
use std::path::{Path, PathBuf};

/// One `newmtl` block.
#[derive(Clone, Debug)]
pub struct MtlMaterial {
    pub name: String,
    pub material: Material,
    /// The `map_Kd` image, resolved against the library's folder, with its line.
    pub diffuse_map: Option<(PathBuf, usize)>,
    /// The library it was defined in.
    pub library: PathBuf,
}

/// Longest library a reader takes (a material library is a few kilobytes).
const MAX_MTL_BYTES: u64 = 16 << 20;
/// Largest image file a reader takes.
pub const MAX_IMAGE_BYTES: u64 = 256 << 20;

/// Reads a material library; errors name the library, its line, and the OBJ line that named it.
pub fn read_mtl(path: &Path, named_at: &str) -> Result<Vec<MtlMaterial>, MeshError> {
    let text = read_limited(path, MAX_MTL_BYTES, &format!("material library named at {named_at}"))?;
    let text =
        String::from_utf8(text).map_err(|_| MeshError::Parse { path: path.to_path_buf(), line: 0, message: "not UTF-8 text".into() })?;
    parse_mtl(&text, path)
}

/// Parses the text of a material library found at `path` (which resolves its map file names).
pub fn parse_mtl(text: &str, path: &Path) -> Result<Vec<MtlMaterial>, MeshError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let err = |line: usize, message: String| MeshError::Parse { path: path.to_path_buf(), line, message };
    let mut out: Vec<MtlMaterial> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let mut words = raw.split_ascii_whitespace();
        let Some(key) = words.next() else { continue };
        if key == "newmtl" {
            let name = words.collect::<Vec<_>>().join(" ");
            let material = Material { name: Some(name.clone()), metallic_factor: 0.0, ..Default::default() };
            out.push(MtlMaterial { name, material, diffuse_map: None, library: path.to_path_buf() });
            continue;
        }
        let known = matches!(key, "Kd" | "d" | "Tr" | "map_Kd");
        if !known {
            continue;
        }
        let Some(current) = out.last_mut() else {
            return Err(err(line, format!("{key} before any newmtl")));
        };
        let numbers = |n: usize, words: std::str::SplitAsciiWhitespace| -> Result<Vec<f32>, MeshError> {
            let values: Vec<f32> = words
                .take(n)
                .map(|w| w.parse::<f32>().map_err(|_| err(line, format!("{key} value {w:?} is not a number"))))
                .collect::<Result<_, _>>()?;
            if values.len() != n && !(key == "Kd" && values.len() == 1) {
                return Err(err(line, format!("{key} has {} values, expected {n}", values.len())));
            }
            if let Some(v) = values.iter().find(|v| !v.is_finite() || **v < 0.0) {
                return Err(err(line, format!("{key} value {v} is not a finite non-negative number")));
            }
            Ok(values)
        };
        match key {
            "Kd" => {
                let v = numbers(3, words)?;
                // `Kd r` alone means grey r.
                let rgb = if v.len() == 1 { [v[0]; 3] } else { [v[0], v[1], v[2]] };
                current.material.base_color_factor[..3].copy_from_slice(&rgb.map(|c| c.min(1.0)));
            }
            "d" | "Tr" => {
                let v = numbers(1, words)?[0].min(1.0);
                let alpha = if key == "d" { v } else { 1.0 - v };
                current.material.base_color_factor[3] = alpha;
                current.material.alpha_mode = if alpha < 1.0 { AlphaMode::Blend } else { AlphaMode::Opaque };
            }
            _ => {
                // Options (`-s 1 1 1`, `-bm 0.5`, ...) come first; the file name is last.
                let Some(file) = raw.split_ascii_whitespace().last().filter(|w| *w != "map_Kd") else {
                    return Err(err(line, "map_Kd names no file".into()));
                };
                current.diffuse_map = Some((dir.join(file.replace('\\', "/")), line));
            }
        }
    }
    Ok(out)
}

/// Reads an image file for a texture: PNG or JPEG by its signature, kept as encoded bytes.
/// `named_at` is the library and line that named it.
pub fn read_image(path: &Path, named_at: &str) -> Result<Image, MeshError> {
    let bytes = read_limited(path, MAX_IMAGE_BYTES, &format!("texture named at {named_at}"))?;
    let mime_type = image_mime_type(&bytes)
        .ok_or_else(|| MeshError::Invalid(format!("{}: texture named at {named_at} is neither a PNG nor a JPEG image", path.display())))?;
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    Ok(Image { name, mime_type: mime_type.to_string(), bytes })
}

fn read_limited(path: &Path, max: u64, what: &str) -> Result<Vec<u8>, MeshError> {
    use std::io::Read;
    let io = |e: std::io::Error| MeshError::Invalid(format!("{}: {what}: {e}", path.display()));
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    file.take(max + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > max {
        return Err(MeshError::Invalid(format!("{}: {what}: larger than {max} bytes", path.display())));
    }
    Ok(bytes)
}
