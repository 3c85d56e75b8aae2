//! Deformation-aware discrete LODs for skinned and morph-target glTF models (issue 7).
//!
//! The pipeline, one module per step (private but for the writer and the measurement; the API
//! is what this file exports):
//! 1. `poses`: the example poses (frames sampled from every animation, each morph target at
//!    full weight, the rest pose), their user weights, the per-pose transforms, and the
//!    per-vertex displacement weights of Berner & Rieger (tertiles, or a smooth variant).
//! 2. `attrs`: the welded vertex record the simplifier carries (rest position, four skin
//!    influences, morph deltas) and how it is posed: in every pose a vertex is an affine
//!    function of its rest position, which makes multi-pose quadrics solvable in rest space.
//! 3. `placement`: where a collapsed vertex goes and which skin it gets: endpoint (Mohr &
//!    Gleicher 4.3), optimal with blended weights cut to four influences, or Houle & Poulin's
//!    bone-space translation (4.1).
//! 4. `simplify`: greedy edge collapse over the quadrics summed over poses, snapshotted at
//!    every triangle target: one run gives a nested LOD chain.
//! 5. `refit`: every level's rest positions, morph deltas and skin weights refitted by least
//!    squares to the input surface over all example poses (closest-point correspondences, a few
//!    rounds; not for [`Placement::Endpoint`], which keeps input vertices as they are).
//! 6. `chain`: the LOD chain as rigs (per LOD a [`pmcodec_mesh::gltf_input::RiggedMesh`] that
//!    poses like the input) plus the correspondence tables for geomorphing.
//! 7. [`gltf_out`]: the GLB writer (skins, morph targets, animations, one scene per LOD, the
//!    chain described in `extras`, see `proto/lod.md`).
//! 8. [`measure`]: per-frame error over every animation, and the meshoptimizer baseline.

#![warn(missing_docs)]
// `!(x > 0.0)` is written on purpose: it is also true for NaN, which these checks must reject.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod attrs;
mod chain;
mod error;
pub mod fixture;
pub mod gltf_out;
pub mod measure;
mod placement;
mod poses;
mod refit;
mod simplify;
mod wedges;

pub use chain::{LodChain, LodLevel, build_chain, build_chain_with};
pub use error::LodError;
pub use placement::Placement;
pub use poses::{PoseOptions, PoseWeights, VertexWeighting};
pub use refit::RefitOptions;

/// Everything [`build_chain`] needs besides the rig and the targets.
#[derive(Clone, Debug, Default)]
pub struct LodOptions {
    /// Which example poses the quadrics sum over, and their weights.
    pub poses: PoseOptions,
    /// Where a collapse puts the survivor and which skin it gets (default Houle & Poulin).
    pub placement: Placement,
}
