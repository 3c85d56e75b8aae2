//! Turns the first frame's `vt`/`vn`/`usemtl` records and its material libraries into the
//! sequence's [`Appearance`]: one wedge per distinct (vertex, `vt`, `vn`) triple a face corner
//! names (Hoppe 1999's wedges), materials in order of first use, one texture per distinct
//! `map_Kd` image.

use super::mtl::{self, MtlMaterial};
use super::{NONE, ObjFrame};
use crate::MeshError;
use crate::appearance::{Appearance, Material, Texture, TextureRef};
use glam::Vec3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The appearance of the OBJ file at `path` (its first frame), or `None` when it has neither
/// texture coordinates, normals nor materials.
pub fn build(frame: &ObjFrame, path: &Path) -> Result<Option<Appearance>, MeshError> {
    build_within(frame, path, None)
}

/// [`build`], reading libraries and images only below `root` when given: a file the OBJ or a
/// library names outside it (`../../etc/passwd`, an absolute path) is refused, not read, so an
/// uploaded library cannot make a server read its own files.
pub fn build_within(frame: &ObjFrame, path: &Path, root: Option<&Path>) -> Result<Option<Appearance>, MeshError> {
    let attrs = &frame.attributes;
    let has_uv = attrs.corners.iter().flatten().any(|c| c[0] != NONE);
    let has_normals = attrs.corners.iter().flatten().any(|c| c[1] != NONE);
    let has_materials = !attrs.material_names.is_empty();
    if !has_uv && !has_normals && !has_materials {
        return Ok(None);
    }
    let mut out = Appearance::default();
    if has_materials {
        materials(frame, path, root, &mut out)?;
    }
    wedges(frame, has_uv, has_normals, &mut out);
    Ok(Some(out))
}

/// Corner wedges: a corner without `vn` (when others have one) gets its face's normal, a
/// wedge of its own, as a renderer draws such a face flat; one without `vt` gets (0, 0).
fn wedges(frame: &ObjFrame, has_uv: bool, has_normals: bool, out: &mut Appearance) {
    let attrs = &frame.attributes;
    let mut index: HashMap<(u32, u32, u64), u32> = HashMap::new();
    out.corner_wedges.reserve(frame.triangles.len());
    for (t, (tri, corners)) in frame.triangles.iter().zip(&attrs.corners).enumerate() {
        let face_normal = || {
            let p = tri.map(|v| frame.positions[v as usize]);
            (p[1] - p[0]).cross(p[2] - p[0]).try_normalize().unwrap_or(Vec3::Z).to_array()
        };
        let mut cw = [0u32; 3];
        for i in 0..3 {
            let [vt, vn] = corners[i];
            let vt = if has_uv { vt } else { NONE };
            let normal_key = match (has_normals, vn) {
                (false, _) => NONE as u64,
                (true, NONE) => (1u64 << 32) | t as u64,
                (true, vn) => vn as u64,
            };
            let next = out.wedge_vertex.len() as u32;
            let w = *index.entry((tri[i], vt, normal_key)).or_insert(next);
            if w == next {
                out.wedge_vertex.push(tri[i]);
                if has_uv {
                    // OBJ's v points up from the bottom of the image; glTF's down from the top.
                    let uv = attrs.texcoords.get(vt as usize).copied().unwrap_or([0.0, 0.0]);
                    out.uv0.push([uv[0], 1.0 - uv[1]]);
                }
                if has_normals {
                    let n = match attrs.normals.get(vn as usize) {
                        Some(n) => Vec3::from_array(*n).try_normalize().map(|n| n.to_array()).unwrap_or_else(face_normal),
                        None => face_normal(),
                    };
                    out.normals.push(n);
                }
            }
            cw[i] = w;
        }
        out.corner_wedges.push(cw);
    }
}

/// Materials in order of first `usemtl`, then glTF's default material if some face comes
/// before any `usemtl`; their `map_Kd` images, each read once.
/// `path` with `.` and `..` resolved by its components alone (the files checked here are ones a
/// server unpacked itself: no links), and whether that stays below `root`.
fn below(path: &Path, root: &Path) -> bool {
    use std::path::Component;
    let mut parts: Vec<Component> = Vec::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !matches!(parts.pop(), Some(Component::Normal(_))) {
                    return false;
                }
            }
            c => parts.push(c),
        }
    }
    parts.iter().collect::<PathBuf>().starts_with(root)
}

/// Refuses a file outside `root` (when given), naming where the OBJ or library names it.
fn confine(file: &Path, root: Option<&Path>, path: &Path, line: usize) -> Result<(), MeshError> {
    match root {
        Some(r) if !below(file, r) => {
            Err(MeshError::Parse { path: path.to_path_buf(), line, message: format!("{} is outside the upload", file.display()) })
        }
        _ => Ok(()),
    }
}

fn materials(frame: &ObjFrame, path: &Path, root: Option<&Path>, out: &mut Appearance) -> Result<(), MeshError> {
    let attrs = &frame.attributes;
    let dir = path.parent().unwrap_or(Path::new("."));
    let at = |line: usize| format!("{}:{line}", path.display());
    let mut library: Vec<MtlMaterial> = Vec::new();
    for (name, line) in &attrs.libraries {
        let file = dir.join(name);
        confine(&file, root, path, *line)?;
        library.extend(mtl::read_mtl(&file, &at(*line))?);
    }
    let mut images: HashMap<PathBuf, u32> = HashMap::new();
    for (name, line) in &attrs.material_names {
        let Some(found) = library.iter().find(|m| m.name == *name) else {
            let libs: Vec<&str> = attrs.libraries.iter().map(|(l, _)| l.as_str()).collect();
            let message = if libs.is_empty() {
                format!("usemtl {name:?}, but the file names no material library (mtllib)")
            } else {
                format!("usemtl {name:?}: no such material in {}", libs.join(", "))
            };
            return Err(MeshError::Parse { path: path.to_path_buf(), line: *line, message });
        };
        let mut material = found.material.clone();
        if let Some((image_path, map_line)) = &found.diffuse_map {
            let texture = match images.get(image_path) {
                Some(&t) => t,
                None => {
                    confine(image_path, root, &found.library, *map_line)?;
                    let named_at = format!("{}:{map_line} (material {name:?})", found.library.display());
                    out.images.push(mtl::read_image(image_path, &named_at)?);
                    let t = out.textures.len() as u32;
                    out.textures.push(Texture { image: out.images.len() as u32 - 1, sampler: None });
                    images.insert(image_path.clone(), t);
                    t
                }
            };
            material.base_color_texture = Some(TextureRef { texture, tex_coord: 0, transform: None });
        }
        out.materials.push(material);
    }
    let default = out.materials.len() as u32;
    out.triangle_material = attrs.triangle_material.iter().map(|&m| if m == NONE { default } else { m }).collect();
    if attrs.triangle_material.contains(&NONE) {
        out.materials.push(Material { metallic_factor: 0.0, ..Default::default() });
    }
    Ok(())
}
