//! Writers for one frame: Wavefront OBJ and binary glTF 2.0 (GLB), and a file writer that
//! never leaves a half-written file behind.

use crate::{MeshError, TriMesh};
use glam::Vec3;
use std::io::Write;
use std::path::Path;

/// Writes positions (shortest round-trip formatting of f32) and 1-based faces.
pub fn write_obj<W: Write>(mut w: W, mesh: &TriMesh) -> std::io::Result<()> {
    writeln!(w, "# pmcodec: {} vertices, {} triangles", mesh.positions.len(), mesh.triangles.len())?;
    for p in &mesh.positions {
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for t in &mesh.triangles {
        writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    w.flush()
}

/// Area-weighted vertex normals (zero-area neighbourhoods get +Z).
pub fn vertex_normals(mesh: &TriMesh) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; mesh.positions.len()];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        let face = (b - a).cross(c - a); // length = twice the area: area weighting for free
        for &i in t {
            if let Some(slot) = n.get_mut(i as usize) {
                *slot += face;
            }
        }
    }
    n.into_iter().map(|v| v.try_normalize().unwrap_or(Vec3::Z)).collect()
}

const GLB_MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"

/// A GLB holding one mesh (POSITION, NORMAL, u32 indices), one node and one scene.
pub fn glb_bytes(mesh: &TriMesh) -> Vec<u8> {
    let normals = vertex_normals(mesh);
    let mut bin: Vec<u8> = Vec::with_capacity(mesh.positions.len() * 24 + mesh.triangles.len() * 12);
    for p in &mesh.positions {
        for c in p.to_array() {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let normals_offset = bin.len();
    for p in &normals {
        for c in p.to_array() {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let indices_offset = bin.len();
    for t in &mesh.triangles {
        for i in t {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let nv = mesh.positions.len();
    let mut accessors = vec![];
    let mut views = vec![];
    let mut attributes = serde_json::Map::new();
    if nv > 0 {
        views.push(serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": normals_offset, "target": 34962}));
        views.push(serde_json::json!({"buffer": 0, "byteOffset": normals_offset, "byteLength": indices_offset - normals_offset, "target": 34962}));
        accessors.push(serde_json::json!({"bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3",
            "min": lo.to_array(), "max": hi.to_array()}));
        accessors.push(serde_json::json!({"bufferView": 1, "componentType": 5126, "count": nv, "type": "VEC3"}));
        attributes.insert("POSITION".into(), 0.into());
        attributes.insert("NORMAL".into(), 1.into());
    }
    let mut primitive = serde_json::json!({"attributes": attributes, "mode": 4});
    if !mesh.triangles.is_empty() && nv > 0 {
        views.push(serde_json::json!({"buffer": 0, "byteOffset": indices_offset, "byteLength": bin.len() - indices_offset, "target": 34963}));
        accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5125, "count": mesh.triangles.len() * 3, "type": "SCALAR"}));
        primitive["indices"] = (accessors.len() - 1).into();
    }
    // An empty mesh becomes an empty scene: glTF requires a primitive to have attributes.
    let mut json = if nv == 0 {
        serde_json::json!({"asset": {"version": "2.0", "generator": "pmcodec"}, "scene": 0, "scenes": [{"nodes": []}]})
    } else {
        serde_json::json!({
            "asset": {"version": "2.0", "generator": "pmcodec"},
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [primitive]}],
            "accessors": accessors,
            "bufferViews": views,
        })
    };
    if !bin.is_empty() {
        json["buffers"] = serde_json::json!([{"byteLength": bin.len()}]);
    }
    let mut json_bytes = serde_json::to_vec(&json).unwrap_or_default();
    // GLB chunks are 4-byte aligned: JSON padded with spaces, BIN with zeros (glTF 2.0, 4.4.3).
    while json_bytes.len() % 4 != 0 {
        json_bytes.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&GLB_MAGIC.to_le_bytes());
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json_bytes);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    out
}

pub fn write_glb<W: Write>(mut w: W, mesh: &TriMesh) -> std::io::Result<()> {
    w.write_all(&glb_bytes(mesh))?;
    w.flush()
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so that a
/// failure (or a kill) never leaves a half-written file under the final name.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), MeshError> {
    let io = |source| MeshError::Io { path: path.to_path_buf(), source };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    Ok(())
}

/// Writes one mesh as `.obj` or `.glb`, chosen by the extension.
pub fn write_mesh_file(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let bytes = match ext.as_str() {
        "glb" => glb_bytes(mesh),
        "obj" => {
            let mut v = Vec::new();
            write_obj(&mut v, mesh).map_err(|source| MeshError::Io { path: path.to_path_buf(), source })?;
            v
        }
        other => {
            return Err(MeshError::Invalid(format!(
                "cannot write {}: unknown extension {other:?} (use .obj or .glb)",
                path.display()
            )));
        }
    };
    write_atomic(path, &bytes)
}
