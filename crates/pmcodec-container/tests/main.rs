//! The crate's integration tests in one binary: one binary to compile and link instead of
//! one per file (each linked every dependency again). Each file below is a module, as it was a
//! crate; a new file joins this list (tests/test-files.sh fails on one that does not).

mod appearance;
mod appearance_bind;
mod banded;
mod compat;
mod corpus;
mod encode_posed;
mod fitted_skin;
mod frame0_levels;
mod key_changes;
mod pinned_bytes;
mod resealed;
mod resealed_appearance;
mod roundtrip;
mod skinned;
mod stream;
mod streams;
mod surface_cost;
mod topology;
mod triangles;
