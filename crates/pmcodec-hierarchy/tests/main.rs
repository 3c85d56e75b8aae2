//! The crate's integration tests in one binary (one link instead of one per file: most of
//! a fresh build's test time was linking); each file below is a module, as it was a crate.

mod common;
mod anchors;
mod multilevel;
mod progressive;
mod properties;
mod split_order;
mod validity;
