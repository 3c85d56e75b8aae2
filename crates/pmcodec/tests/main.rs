//! The crate's integration tests in one binary (one link instead of one per file: most of
//! a fresh build's test time was linking); each file below is a module, as it was a crate.

mod cli;
mod decode_textured;
mod encode_gltf;
mod fit_skin_choice;
mod lod_cli;
mod skinned_glb;
