//! The crate's integration tests in one binary: one binary to compile and link instead of
//! one per file (each linked every dependency again). Each file below is a module, as it was a
//! crate; a new file joins this list (tests/test-files.sh fails on one that does not).

mod anchors;
mod common;
mod multilevel;
mod progressive;
mod properties;
mod split_order;
mod validity;
