//! The crate's integration tests in one binary (one link instead of one per file: most of
//! a fresh build's test time was linking); each file below is a module, as it was a crate.

mod appearance;
mod appearance_bind;
mod banded;
mod compat;
mod corpus;
mod encode_posed;
mod fitted_skin;
mod frame0_levels;
mod key_changes;
mod resealed;
mod resealed_appearance;
mod roundtrip;
mod skinned;
mod stream;
mod streams;
mod topology;
mod triangles;
