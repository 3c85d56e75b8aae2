//! Writing a decoded cut with its appearance: a textured GLB (one primitive per material,
//! images embedded) or OBJ with its MTL and image files.

use crate::ContainerError;
use pmcodec_mesh::{Appearance, TriMesh};
use std::fmt::Write as _;

/// A GLB of `mesh` with `app` (one wedge per vertex, as [`crate::Decoder::textured_mesh`]
/// gives): POSITION, NORMAL (the appearance's, as decoded), TEXCOORD_0/1 and COLOR_0 per
/// vertex, one primitive per material used, the images embedded in the binary chunk. Written
/// by the workspace's one GLB writer ([`pmcodec_mesh::write::glb_bytes_with_normals`]); an
/// appearance that does not match the mesh is an error, not a broken file.
pub fn textured_glb(mesh: &TriMesh, app: &Appearance) -> Result<Vec<u8>, ContainerError> {
    Ok(pmcodec_mesh::write::glb_bytes_with_normals(mesh, app)?)
}

/// The file name an image is written under beside an OBJ: its own name when it has a safe
/// one, else `{stem}-image{i}.png|jpg`.
pub fn image_file_name(app: &Appearance, i: usize, stem: &str) -> String {
    let image = &app.images[i];
    let ext = if image.mime_type == "image/jpeg" { "jpg" } else { "png" };
    match &image.name {
        Some(n) if !n.is_empty() && n.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) && !n.starts_with('.') => {
            format!("{stem}-{i}-{n}")
        }
        _ => format!("{stem}-image{i}.{ext}"),
    }
}

/// An OBJ of `mesh` with `app` (`v` per vertex of `mesh`, `vt` with v flipped to OBJ's upward
/// axis and `vn` per wedge, `usemtl` runs) naming `mtl_name`, and that MTL's text (`Kd`, `d`,
/// `map_Kd` naming the files [`image_file_name`] gives). `wedges[t]` are the wedges of
/// `mesh.triangles[t]`'s corners (the same triangles, indexed into `app`'s per-wedge arrays):
/// an OBJ indexes positions and attributes apart, so a seam does not split a vertex.
pub fn textured_obj(
    mesh: &TriMesh,
    wedges: &[[u32; 3]],
    app: &Appearance,
    mtl_name: &str,
    stem: &str,
) -> Result<(String, String), ContainerError> {
    if wedges.len() != mesh.triangles.len() {
        return Err(ContainerError::Options(format!("{} triangles with wedges for {} triangles", mesh.triangles.len(), wedges.len())));
    }
    let mut obj = String::new();
    let _ = writeln!(obj, "# pmcodec\nmtllib {mtl_name}");
    for p in &mesh.positions {
        let _ = writeln!(obj, "v {} {} {}", p.x, p.y, p.z);
    }
    for uv in &app.uv0 {
        let _ = writeln!(obj, "vt {} {}", uv[0], 1.0 - uv[1]);
    }
    for n in &app.normals {
        let _ = writeln!(obj, "vn {} {} {}", n[0], n[1], n[2]);
    }
    let (has_uv, has_n) = (!app.uv0.is_empty(), !app.normals.is_empty());
    let mut current = u32::MAX;
    for (t, (tri, tw)) in mesh.triangles.iter().zip(wedges).enumerate() {
        let m = app.triangle_material.get(t).copied().unwrap_or(0);
        if m != current && !app.materials.is_empty() {
            let _ = writeln!(obj, "usemtl material{m}");
            current = m;
        }
        obj.push('f');
        for (&v, &w) in tri.iter().zip(tw) {
            let (i, j) = (v + 1, w + 1);
            let _ = match (has_uv, has_n) {
                (true, true) => write!(obj, " {i}/{j}/{j}"),
                (true, false) => write!(obj, " {i}/{j}"),
                (false, true) => write!(obj, " {i}//{j}"),
                (false, false) => write!(obj, " {i}"),
            };
        }
        obj.push('\n');
    }
    let mut mtl = String::from("# pmcodec\n");
    for (m, mat) in app.materials.iter().enumerate() {
        let c = mat.base_color_factor;
        let _ = writeln!(mtl, "newmtl material{m}\nKd {} {} {}\nd {}", c[0], c[1], c[2], c[3]);
        if let Some(r) = &mat.base_color_texture
            && let Some(t) = app.textures.get(r.texture as usize)
            && (t.image as usize) < app.images.len()
        {
            let _ = writeln!(mtl, "map_Kd {}", image_file_name(app, t.image as usize, stem));
        }
    }
    Ok((obj, mtl))
}
