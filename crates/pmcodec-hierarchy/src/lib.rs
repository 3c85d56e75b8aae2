//! The multilevel hierarchy of Kircher & Garland, *Progressive Multiresolution Meshes for
//! Deforming Surfaces* (2005): built by QEM edge collapse (section 3, [`mod@build`]), with degenerate sets
//! ([`DegenerateSets`]) that make triangle budgets exact, and cuts ([`cut`]) that extract a mesh for
//! any frame.
//!
//! Data is flat arrays indexed by `u32`; nodes have a global id (see [`Hierarchy`]).

#![warn(missing_docs)]
// `!(x > 0.0)` is written on purpose: it is also true for NaN, which these checks must reject.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod base;
pub mod build;
pub mod cut;
mod degenerate;
mod hierarchy;
mod levels;
mod nodes;
pub mod progressive;
pub mod quadric;
pub mod recluster;
pub mod rows;
pub mod split_order;
mod target;
mod topology;

pub use build::{BuildError, BuildOptions, build};
pub use cut::{ChildIndex, Cut};
pub use degenerate::DegenerateSets;
pub use hierarchy::{Hierarchy, NONE};
pub use nodes::NodeState;
pub use quadric::{Quadric, QuadricOptions};
pub use target::{CutTarget, Distance};
pub use topology::FineTopology;
