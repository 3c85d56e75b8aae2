//! Mesh response bodies: GLB, and the compact binary of proto/http.md for programs
//! ([`pmcodec_mesh::binmesh`]).

use pmcodec_mesh::TriMesh;

pub use pmcodec_mesh::binmesh::{MAGIC as MESH_MAGIC, decode_bin, encode_bin};

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
