//! Writers for one frame: Wavefront OBJ and binary glTF 2.0 (GLB, with or without an
//! [`Appearance`], assembled by [`crate::glb`]), and a file writer that never leaves a
//! half-written file behind.
//!
//! Both writers expect a mesh that passed [`crate::Sequence::validate`] (finite coordinates,
//! indices in range); they do not check it again.

use crate::glb::{ARRAY_BUFFER, GlbBuilder, TRIANGLES, triangles_by_material, wedge_attributes, wedge_normals, write_looks};
use crate::{Appearance, MeshError, TriMesh};
use glam::Vec3;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Writes `v` lines and 1-based `f` lines. Coordinates use Rust's `{}` formatting of `f32`,
/// the shortest decimal that parses back to the same `f32`, so a round trip is exact. `w` gets
/// many small writes: give it a `BufWriter` (or a `Vec`) rather than a bare `File`.
/// A mesh without triangles is written as its vertices alone.
pub fn write_obj<W: Write>(mut w: W, mesh: &TriMesh) -> std::io::Result<()> {
    writeln!(w, "# pmcodec: {} vertices, {} triangles", mesh.positions.len(), mesh.triangles.len())?;
    for p in &mesh.positions {
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for t in &mesh.triangles {
        writeln!(w, "f {} {} {}", u64::from(t[0]) + 1, u64::from(t[1]) + 1, u64::from(t[2]) + 1)?;
    }
    w.flush()
}

/// Area-weighted vertex normals, unit length. A vertex whose faces have no area (or that no
/// face uses) gets +Z: glTF requires unit normals, and any unit vector is as good as another
/// there. Indices out of range are skipped rather than trusted.
pub fn vertex_normals(mesh: &TriMesh) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; mesh.positions.len()];
    for t in &mesh.triangles {
        let Some([a, b, c]) = corners(mesh, t) else { continue };
        // The cross product's length is twice the area: area weighting for free.
        let face = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += face;
        }
    }
    n.into_iter().map(|v| v.try_normalize().unwrap_or(Vec3::Z)).collect()
}

fn corners(mesh: &TriMesh, t: &[u32; 3]) -> Option<[Vec3; 3]> {
    Some([*mesh.positions.get(t[0] as usize)?, *mesh.positions.get(t[1] as usize)?, *mesh.positions.get(t[2] as usize)?])
}

/// Bytes of binary data a GLB of `mesh` carries: positions, normals, indices.
fn bin_len(mesh: &TriMesh) -> u64 {
    mesh.positions.len() as u64 * 24 + mesh.triangles.len() as u64 * 12
}

/// Whether `mesh` fits the GLB format, whose header stores the file length in a `u32` (4 GiB,
/// about 170 million triangles with their vertices). 4 KiB is kept for the JSON, far more than
/// its few hundred bytes.
fn fits_glb(mesh: &TriMesh) -> bool {
    bin_len(mesh) + 4096 <= u64::from(u32::MAX)
}

/// A glTF 2.0 binary holding one scene with one node and one mesh of one indexed triangle
/// primitive: POSITION (with the min/max the spec requires), area-weighted NORMAL and indices
/// (`u16` up to 65,535 vertices, else `u32`), each in its own 4-byte-aligned buffer view of a
/// single buffer.
///
/// A mesh without triangles has no surface to draw and becomes a valid GLB of one scene with
/// one empty node (no mesh, no buffer), so a reader always gets a file it can open.
///
/// The mesh must fit the format's 4 GiB (see [`write_glb`], which checks); a larger one gives
/// an empty vector.
pub fn glb_bytes(mesh: &TriMesh) -> Vec<u8> {
    debug_assert!(fits_glb(mesh), "mesh too large for GLB");
    glb_bytes_with(mesh, None).unwrap_or_default()
}

/// [`glb_bytes`] with an appearance (`corner_wedges` parallel to `mesh.triangles`, wedges on
/// `mesh.positions`): each wedge becomes a glTF vertex with its position, `TEXCOORD_0`/`_1`
/// and `COLOR_0`, and a normal computed from `mesh.positions` (area-weighted, split where the
/// input's normals differ: see [`crate::glb::wedge_normals`]); one primitive per material;
/// materials, textures, samplers and images (as buffer views) as in the appearance. Errors
/// name what does not match (the appearance is validated against the mesh) or the size.
pub fn glb_bytes_with(mesh: &TriMesh, appearance: Option<&Appearance>) -> Result<Vec<u8>, MeshError> {
    glb_document(mesh, appearance, WedgeNormals::FromPositions)
}

/// [`glb_bytes_with`] for a decoder's textured cut, whose appearance already holds the normals
/// to show (`normals`, one per wedge, as `pmcodec-container` computes them over the cut, so
/// that every decoder of the stream shows the same bits): they are written as given. Without
/// normals in the appearance they are computed as in [`glb_bytes_with`].
pub fn glb_bytes_with_normals(mesh: &TriMesh, appearance: &Appearance) -> Result<Vec<u8>, MeshError> {
    let source = if appearance.normals.is_empty() { WedgeNormals::FromPositions } else { WedgeNormals::Given };
    glb_document(mesh, Some(appearance), source)
}

/// Where a textured GLB's `NORMAL`s come from.
#[derive(Clone, Copy, PartialEq, Eq)]
enum WedgeNormals {
    /// From the positions, split where the input's normals differ ([`wedge_normals`]).
    FromPositions,
    /// The appearance's own per-wedge normals.
    Given,
}

fn glb_document(mesh: &TriMesh, appearance: Option<&Appearance>, normal_source: WedgeNormals) -> Result<Vec<u8>, MeshError> {
    let asset = json!({"version": "2.0", "generator": "pmcodec"});
    if mesh.triangles.is_empty() || mesh.positions.is_empty() {
        // One scene holding one node without a mesh: `scene.nodes` may not be an empty array
        // (glTF 2.0 schema, minItems 1), the `gltf` crate rejects a scene without `nodes`, and
        // viewers expect a default scene to exist.
        return GlbBuilder::default().finish(json!({"asset": asset, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{}]}));
    }
    let mut b = GlbBuilder::default();
    let mut root = json!({"asset": asset, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}]});
    let primitives = match appearance {
        None => {
            let pos = b.vec3s(&mesh.positions, Some(ARRAY_BUFFER), true);
            let nrm = b.vec3s(&vertex_normals(mesh), Some(ARRAY_BUFFER), false);
            let flat: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
            let idx = b.indices(&flat, mesh.positions.len());
            vec![json!({"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": idx, "mode": TRIANGLES})]
        }
        Some(app) => {
            app.validate(mesh.positions.len(), &mesh.triangles)?;
            let positions: Vec<Vec3> = app.wedge_vertex.iter().map(|&v| mesh.positions[v as usize]).collect();
            let mut attributes = wedge_attributes(&mut b, app);
            attributes.insert("POSITION".into(), json!(b.vec3s(&positions, Some(ARRAY_BUFFER), true)));
            let normals = match normal_source {
                WedgeNormals::FromPositions => wedge_normals(&mesh.positions, &mesh.triangles, app),
                WedgeNormals::Given => app.normals.iter().map(|&n| Vec3::from_array(n)).collect(),
            };
            attributes.insert("NORMAL".into(), json!(b.vec3s(&normals, Some(ARRAY_BUFFER), false)));
            write_looks(&mut b, app, &mut root);
            triangles_by_material(app)
                .into_iter()
                .map(|(material, wedges)| {
                    let mut prim = json!({"attributes": attributes, "indices": b.indices(&wedges, positions.len()), "mode": TRIANGLES});
                    if !app.materials.is_empty() {
                        prim["material"] = json!(material);
                    }
                    prim
                })
                .collect()
        }
    };
    root["meshes"] = json!([{"primitives": primitives}]);
    b.finish(root)
}

/// Writes [`glb_bytes`] to `w`. Errors (`InvalidInput`) for a mesh beyond the format's 4 GiB.
pub fn write_glb<W: Write>(mut w: W, mesh: &TriMesh) -> std::io::Result<()> {
    if !fits_glb(mesh) {
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, too_large(mesh)));
    }
    w.write_all(&glb_bytes(mesh))?;
    w.flush()
}

fn too_large(mesh: &TriMesh) -> String {
    format!("{} vertices and {} triangles exceed the 4 GiB a GLB file can hold", mesh.positions.len(), mesh.triangles.len())
}

/// Distinguishes temporary files of concurrent writes from one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so that
/// a failure (or a kill) never leaves a half-written file under the final name: readers see the
/// old file or the new one. The temporary file is removed on any error.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), MeshError> {
    let io = |error| MeshError::Io { path: path.to_path_buf(), error };
    let Some(name) = path.file_name() else {
        return Err(MeshError::Invalid(format!("cannot write {}: it does not name a file", path.display())));
    };
    // Same folder, so the rename stays on one file system and is atomic.
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    // Hidden, and unique per process and call; `create_new` refuses to reuse a leftover from a
    // crashed run, so try a few names before giving up.
    let mut attempt = 0;
    let (tmp, mut file) = loop {
        let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{}.{}.{n}.tmp", name.to_string_lossy(), std::process::id()));
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => break (tmp, f),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && attempt < 8 => attempt += 1,
            Err(e) => return Err(io(e)),
        }
    };
    let result = file
        .write_all(bytes)
        // The data must be on disk before the rename makes it visible under the final name.
        .and_then(|()| file.sync_all())
        .and_then(|()| {
            drop(file);
            std::fs::rename(&tmp, path)
        });
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    // Make the rename itself durable. Best effort: not every platform can sync a directory.
    if let Ok(d) = std::fs::File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Writes one mesh as `.obj` or `.glb` (case-insensitive), chosen by the extension, through
/// [`write_atomic`].
pub fn write_mesh_file(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    let bytes = match ext.as_deref() {
        Some("glb") => {
            if !fits_glb(mesh) {
                return Err(MeshError::TooLarge { what: too_large(mesh) });
            }
            glb_bytes(mesh)
        }
        Some("obj") => {
            let mut v = Vec::new();
            write_obj(&mut v, mesh).map_err(|error| MeshError::Io { path: path.to_path_buf(), error })?;
            v
        }
        Some(other) => {
            return Err(MeshError::Invalid(format!("cannot write {}: unknown extension \".{other}\" (use .obj or .glb)", path.display())));
        }
        None => {
            return Err(MeshError::Invalid(format!(
                "cannot write {}: no extension to choose the format by (use .obj or .glb)",
                path.display()
            )));
        }
    };
    write_atomic(path, &bytes)
}
