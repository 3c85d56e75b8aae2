//! The crate's integration tests in one binary: one binary to compile and link instead of
//! one per file (each linked every dependency again). Each file below is a module, as it was a
//! crate; a new file joins this list (tests/test-files.sh fails on one that does not).

mod binmesh;
mod common;
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
