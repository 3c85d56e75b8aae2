//! The crate's integration tests in one binary (one link instead of one per file: most of
//! a fresh build's test time was linking); each file below is a module, as it was a crate.

mod api;
mod appearance;
mod limits_and_cache;
