//! The crate's integration tests in one binary (one link instead of one per file: most of
//! a fresh build's test time was linking); each file below is a module, as it was a crate.

mod common;
mod binmesh;
mod compressed_gltf;
mod glb_writer;
mod gltf_appearance;
mod gltf_errors;
mod gltf_input;
mod gltf_sampler;
mod limits;
mod obj_appearance;
mod obj_fuzz;
mod skin;
mod skin_fit;
mod write;
