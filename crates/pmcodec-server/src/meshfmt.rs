//! Mesh response bodies: GLB, and the compact binary of proto/http.md for programs.

use pmcodec_mesh::TriMesh;

/// Magic of the compact binary mesh.
pub const MESH_MAGIC: &[u8; 4] = b"PMCM";
/// Version of the compact binary mesh layout.
pub const MESH_VERSION: u32 = 1;
/// Bytes before the positions: magic, version, vertex count, triangle count.
pub const MESH_HEADER_LEN: usize = 16;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    Glb,
    Bin,
}

impl MeshFormat {
    pub fn parse(s: &str) -> Option<MeshFormat> {
        match s {
            "glb" => Some(MeshFormat::Glb),
            "bin" => Some(MeshFormat::Bin),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Glb => "glb",
            MeshFormat::Bin => "bin",
        }
    }

    pub fn content_type(self) -> &'static str {
        match self {
            MeshFormat::Glb => "model/gltf-binary",
            MeshFormat::Bin => "application/vnd.pmcodec.mesh",
        }
    }
}

pub fn encode_mesh(mesh: &TriMesh, format: MeshFormat) -> Vec<u8> {
    match format {
        MeshFormat::Glb => pmcodec_mesh::write::glb_bytes(mesh),
        MeshFormat::Bin => encode_bin(mesh),
    }
}

/// Little-endian: `"PMCM"`, u32 version, u32 V, u32 T, V x 3 f32 positions, T x 3 u32 indices.
pub fn encode_bin(mesh: &TriMesh) -> Vec<u8> {
    let mut b = Vec::with_capacity(MESH_HEADER_LEN + mesh.positions.len() * 12 + mesh.triangles.len() * 12);
    b.extend_from_slice(MESH_MAGIC);
    b.extend_from_slice(&MESH_VERSION.to_le_bytes());
    b.extend_from_slice(&(mesh.positions.len() as u32).to_le_bytes());
    b.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
    for p in &mesh.positions {
        for c in p.to_array() {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    b
}

/// Reads the compact binary back (clients, tests). `None` for anything that is not exactly one
/// well-formed mesh.
pub fn decode_bin(b: &[u8]) -> Option<TriMesh> {
    let word = |i: usize| b.get(i..i + 4).and_then(|s| s.try_into().ok()).map(u32::from_le_bytes);
    if b.get(..4)? != MESH_MAGIC || word(4)? != MESH_VERSION {
        return None;
    }
    let (v, t) = (word(8)? as usize, word(12)? as usize);
    let pos_end = MESH_HEADER_LEN.checked_add(v.checked_mul(12)?)?;
    if b.len() != pos_end.checked_add(t.checked_mul(12)?)? {
        return None;
    }
    let f = |i: usize| b.get(i..i + 4).and_then(|s| s.try_into().ok()).map(f32::from_le_bytes);
    let positions = (0..v)
        .map(|k| {
            let o = MESH_HEADER_LEN + 12 * k;
            Some(glam::Vec3::new(f(o)?, f(o + 4)?, f(o + 8)?))
        })
        .collect::<Option<Vec<_>>>()?;
    let triangles = (0..t)
        .map(|k| {
            let o = pos_end + 12 * k;
            let tri = [word(o)?, word(o + 4)?, word(o + 8)?];
            tri.iter().all(|&i| (i as usize) < v).then_some(tri)
        })
        .collect::<Option<Vec<_>>>()?;
    Some(TriMesh { positions, triangles })
}
