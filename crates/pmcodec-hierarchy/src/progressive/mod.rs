//! The progressive representation (section 5): a keyframe holding a whole hierarchy H_f, then
//! per frame the swaps and degenerate-set deltas that turn H_{f-1} into H_f. [`Encoder`]
//! produces it; [`Replay`] plays it back and keeps a cut's shown triangles up to date
//! incrementally (section 5.1), without re-deriving them from scratch.
//!
//! The degenerate-set deltas are a function of the swaps: a triangle's degeneration node is
//! where two of its corners' ancestor chains first meet, and a swap of node v changes only the
//! chains of the triangles with a corner under v. So a replay *derives* them, for just those
//! triangles, and a stream needs to carry only the swaps (the paper's "swaps only" figure,
//! section 6); [`Encoder::degeneration`] gives the encoder's side of them, for measurement and
//! tests.
//!
//! Everything is organised by *band*: band j is what a client needs to refine down to level j.
//! A client that stops at level L reads bands top..=L only, so what it reads grows with |M_L|:
//! - swaps of level-j nodes are in band j;
//! - corner updates: a triangle *alive at level j* (its corners have three distinct level-j
//!   ancestors) is drawn by a level-j client through its level-j corners; when those change
//!   (swaps at finer levels, invisible to that client), band j carries the new corners, also
//!   when the triangle becomes alive at j or stops being alive (then the new corners repeat a
//!   node). Only a client whose finest level is exactly j needs them. Level-0 corners are the
//!   input triangles and never change.
//!
//! Convention: frame 0 has a delta too (reclustering the built base to fit frame 0), so the
//! hierarchy of frame f is the base plus the deltas of frames 0..=f; the keyframe of frame f is
//! the state after frame f's delta.
//!
//! Modules: `encoder` ([`Encoder`]), `replay` ([`Replay`] and its incremental cut), `incidence`
//! (a replay's triangles by corner), `cuts` (cuts a replay chooses from decoded data alone).

use crate::Hierarchy;
use crate::degenerate::degeneration_nodes;
use crate::hierarchy::NONE;
use crate::nodes::NodeState;
use crate::recluster::{FrameStats, ReclusterOptions, Reclusterer, Swap};
use crate::topology::FineTopology;
use glam::Vec3;

/// Sentinel degeneration node of a triangle that is not alive at a replay's finest level (its
/// node lies at or below that level, which such a replay does not track).
pub const BELOW: u32 = u32::MAX - 1;

/// New level-`level` corners of triangle `t` (two equal corners: t is no longer alive there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CornerUpdate {
    /// The level whose corners change.
    pub level: u32,
    /// The fine triangle.
    pub t: u32,
    /// Its new level-`level` corners (level-local ids).
    pub corners: [u32; 3],
}

/// What turns H_{f-1} into H_f.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameDelta {
    /// Swaps in the order they were made (coarse levels first).
    pub swaps: Vec<Swap>,
    /// Corner updates, by level then triangle.
    pub corners: Vec<CornerUpdate>,
}

/// Level of a global node id, with level(NONE) = top + 1.
#[inline]
pub fn node_level(h: &Hierarchy, g: u32) -> usize {
    if g == NONE { h.levels() } else { h.local(g).0 }
}

impl FrameDelta {
    /// The parts of this delta in bands `min_level..`.
    pub fn from_level(&self, min_level: usize) -> FrameDelta {
        FrameDelta {
            swaps: self.swaps.iter().filter(|s| s.level as usize >= min_level).copied().collect(),
            corners: self.corners.iter().filter(|c| c.level as usize >= min_level).copied().collect(),
        }
    }
}

/// One band of a keyframe: level j's parent map and the triangles alive at level j with their
/// level-j corners (empty for band 0, whose corners are the input triangles).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KeyBand {
    /// Parent (level j + 1 local id) of every level-j node; empty for the top level.
    pub parent: Vec<u32>,
    /// The triangles alive at level j, as (fine triangle, level-j corners).
    pub faces: Vec<(u32, [u32; 3])>,
}

/// A whole hierarchy, by band (index = level).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Keyframe {
    /// Band j holds level j.
    pub bands: Vec<KeyBand>,
}

/// Whether three corners are three different nodes (the triangle is alive at their level).
#[inline]
pub fn distinct(c: [u32; 3]) -> bool {
    c[0] != c[1] && c[1] != c[2] && c[0] != c[2]
}

/// Data that does not fit the hierarchy it is applied to.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum DeltaError {
    /// A swap names a node or a cluster the level does not have.
    // Fields: the swap's or update's index in its delta and the ids it names, as the message says.
    #[allow(missing_docs)]
    #[error("swap {index}: level {level} has no node {v} or no cluster {to} above it")]
    SwapOutOfRange { index: usize, level: u32, v: u32, to: u32 },
    /// A swap moves a node from a cluster it is not in.
    // Fields: the swap's or update's index in its delta and the ids it names, as the message says.
    #[allow(missing_docs)]
    #[error("swap {index}: node {v} of level {level} is in cluster {actual}, not {from}")]
    SwapMismatch { index: usize, level: u32, v: u32, from: u32, actual: u32 },
    /// A swap would leave a cluster without nodes.
    // Fields: the swap's or update's index in its delta and the ids it names, as the message says.
    #[allow(missing_docs)]
    #[error("swap {index}: cluster {from} of level {} would be left empty", level + 1)]
    EmptyCluster { index: usize, level: u32, from: u32 },
    /// A corner update names a triangle or a node the level does not have.
    // Fields: the swap's or update's index in its delta and the ids it names, as the message says.
    #[allow(missing_docs)]
    #[error("corner update {index}: triangle {triangle} or a corner out of range at level {level}")]
    CornerOutOfRange { index: usize, level: u32, triangle: u32 },
    /// A keyframe that does not describe a hierarchy.
    #[error("keyframe: {0}")]
    Keyframe(String),
}

mod cuts;
mod encoder;
mod incidence;
mod replay;

pub use encoder::Encoder;
pub use replay::Replay;
