//! Writers for one frame: Wavefront OBJ and binary glTF 2.0 (GLB), and a file writer that
//! never leaves a half-written file behind.
//!
//! Both writers expect a mesh that passed [`crate::Sequence::validate`] (finite coordinates,
//! indices in range); they do not check it again.

use crate::{MeshError, TriMesh};
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

const GLB_MAGIC: u32 = 0x4654_6C67; // "glTF"
const GLB_VERSION: u32 = 2;
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
/// Meshes with fewer vertices get 16-bit indices. glTF forbids an index equal to the
/// component type's largest value (primitive restart), so 65,535 vertices at most.
const MAX_U16_VERTICES: usize = 65_535;
const TRIANGLES: u32 = 4;

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
/// a file with a wrong length field.
pub fn glb_bytes(mesh: &TriMesh) -> Vec<u8> {
    debug_assert!(fits_glb(mesh), "mesh too large for GLB");
    let nv = mesh.positions.len();
    let nt = mesh.triangles.len();
    let empty = nt == 0 || nv == 0;

    let (json, bin) = if empty {
        // One scene holding one node without a mesh: `scene.nodes` may not be an empty array
        // (glTF 2.0 schema, minItems 1), the `gltf` crate rejects a scene without `nodes`, and
        // viewers expect a default scene to exist.
        (json!({"asset": {"version": "2.0", "generator": "pmcodec"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{}]}), Vec::new())
    } else {
        let mut bin: Vec<u8> = Vec::with_capacity(bin_len(mesh) as usize);
        // Positions and normals are 4-byte floats and the indices come last, so each view
        // starts 4-byte aligned without padding between them.
        let put = |bin: &mut Vec<u8>, v: Vec3| {
            for c in v.to_array() {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        };
        for &p in &mesh.positions {
            put(&mut bin, p);
        }
        let normals_at = bin.len();
        for n in vertex_normals(mesh) {
            put(&mut bin, n);
        }
        let indices_at = bin.len();
        let short = nv <= MAX_U16_VERTICES;
        for &i in mesh.triangles.iter().flatten() {
            if short {
                bin.extend_from_slice(&(i as u16).to_le_bytes());
            } else {
                bin.extend_from_slice(&i.to_le_bytes());
            }
        }
        let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let json = json!({
            "asset": {"version": "2.0", "generator": "pmcodec"},
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{
                "attributes": {"POSITION": 0, "NORMAL": 1},
                "indices": 2,
                "mode": TRIANGLES,
            }]}],
            "accessors": [
                {"bufferView": 0, "componentType": FLOAT, "count": nv, "type": "VEC3",
                 "min": lo.to_array(), "max": hi.to_array()},
                {"bufferView": 1, "componentType": FLOAT, "count": nv, "type": "VEC3"},
                {"bufferView": 2, "componentType": if short { UNSIGNED_SHORT } else { UNSIGNED_INT },
                 "count": nt * 3, "type": "SCALAR"},
            ],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": normals_at, "target": ARRAY_BUFFER},
                {"buffer": 0, "byteOffset": normals_at, "byteLength": indices_at - normals_at, "target": ARRAY_BUFFER},
                {"buffer": 0, "byteOffset": indices_at, "byteLength": bin.len() - indices_at, "target": ELEMENT_ARRAY_BUFFER},
            ],
            "buffers": [{"byteLength": bin.len()}],
        });
        (json, bin)
    };
    assemble_glb(&json, bin)
}

/// Header and chunks (glTF 2.0, "Binary glTF Layout"): each chunk's data is padded to a
/// multiple of 4 bytes, JSON with spaces (still valid JSON), BIN with zeros. No BIN chunk when
/// there is no binary data.
fn assemble_glb(json: &serde_json::Value, mut bin: Vec<u8>) -> Vec<u8> {
    // Serialising a `Value` whose keys are all strings cannot fail.
    let mut json_bytes = serde_json::to_vec(json).unwrap_or_default();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = 12 + 8 + json_bytes.len() + bin_chunk;
    let mut out = Vec::with_capacity(total);
    for word in [GLB_MAGIC, GLB_VERSION, total as u32, json_bytes.len() as u32, CHUNK_JSON] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json_bytes);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    out
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
