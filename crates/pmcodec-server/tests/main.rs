//! The crate's integration tests in one binary: one compile and link of the test harness and
//! the crate's dependencies instead of one per file. Each file below is a module, as it was a
//! crate; a new file joins this list (tests/test-files.sh fails on one that does not).

mod api;
mod appearance;
mod limits_and_cache;
