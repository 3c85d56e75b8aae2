//! Mesh response bodies: GLB, and the compact binary of proto/http.md for programs
//! ([`pmcodec_mesh::binmesh`]).

use pmcodec_mesh::{Appearance, TriMesh};

pub use pmcodec_mesh::binmesh::{MAGIC as MESH_MAGIC, decode_bin, decode_bin_appearance, encode_bin, encode_bin_v3};

/// The body format of a mesh response (`format=glb|bin`, `layout=3`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Binary glTF (`model/gltf-binary`), one mesh in one scene; textured when the asset has an
    /// appearance.
    Glb,
    /// The compact binary, layout version 2 (positions and triangles).
    Bin,
    /// The compact binary, layout version 3 (`format=bin&layout=3`): with normals and, for an
    /// asset with an appearance, texture coordinates, colours and material runs.
    Bin3,
}

impl MeshFormat {
    /// The format named by a `format` query value (`glb` or `bin`); `layout=3` turns `bin` into [`MeshFormat::Bin3`] in the route.
    pub fn parse(s: &str) -> Option<MeshFormat> {
        match s {
            "glb" => Some(MeshFormat::Glb),
            "bin" => Some(MeshFormat::Bin),
            _ => None,
        }
    }

    /// The name in logs and metrics labels (`glb`, `bin`, `bin3`).
    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Glb => "glb",
            MeshFormat::Bin => "bin",
            MeshFormat::Bin3 => "bin3",
        }
    }

    /// The response's `Content-Type`.
    pub fn content_type(self) -> &'static str {
        match self {
            MeshFormat::Glb => "model/gltf-binary",
            MeshFormat::Bin | MeshFormat::Bin3 => "application/vnd.pmcodec.mesh",
        }
    }
}

/// The body of a bare mesh (an asset without an appearance); layout 3 carries its normals
/// (area weighted, as the GLB's).
pub fn encode_mesh(mesh: &TriMesh, format: MeshFormat) -> Vec<u8> {
    match format {
        MeshFormat::Glb => pmcodec_mesh::write::glb_bytes(mesh),
        MeshFormat::Bin => encode_bin(mesh),
        MeshFormat::Bin3 => {
            let normals = pmcodec_mesh::write::vertex_normals(mesh).into_iter().map(|n| n.to_array()).collect();
            let app = Appearance { normals, ..Default::default() };
            // Per-vertex arrays of the mesh's own length: the writer cannot refuse them.
            encode_bin_v3(mesh, &app).unwrap_or_else(|_| encode_bin(mesh))
        }
    }
}
