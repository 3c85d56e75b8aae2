//! What an encode is asked for: [`EncodeOptions`] and the choices it names.

use crate::derive::DerivedTopology;
use crate::format::*;
use crate::skin::SkinnedCoarse;
use pmcodec_hierarchy::BuildOptions;
use pmcodec_hierarchy::base::BaseOptions;
use pmcodec_hierarchy::recluster::ReclusterOptions;

/// How positions are quantized.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum QuantizationChoice {
    /// Every position within this fraction of the bounding-box diagonal of its true value.
    MaxError(f64),
    /// This many bits per axis over the bounding box's largest extent.
    Bits(u8),
}

/// Everything `encode` can be told.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodeOptions {
    /// Hierarchy construction: branching and the QEM options (Kircher & Garland section 3).
    pub build: BuildOptions,
    /// The base poses and weights the quadrics are summed over.
    pub base: BaseOptions,
    /// Per-frame reclustering: swap budget, passes, benefit threshold (section 4).
    pub recluster: ReclusterOptions,
    /// A keyframe every this many frames (0: only frame 0).
    pub keyframe_interval: u32,
    /// How finely positions are quantized: an error bound or a bit count.
    pub quantization: QuantizationChoice,
    /// Coarser nodes on a grid of `2^(level + k)` quanta (see [`crate::coarse_shift`]): fewer
    /// bits, coarser cuts. The default, `Some(0)`, stores level j on a grid of about 2^j quanta,
    /// far below the geometric error of its nodes (horse at 12 bits: 8% fewer bytes, 4% more RMS
    /// error at 10% of the triangles). None keeps every stored position within the bound.
    pub coarse_grid: Option<u32>,
    /// Coarse nodes stored on their clusters' surfaces: of the grid points within reach, one
    /// whose distance to the cluster's planes is within 0.3 grid steps of the true position's
    /// (`grid::on_surface_grid`), not merely the cheapest, which may sit a grid step off the
    /// surface. The default; the decoder reads either alike. Frame 0's worst level against plain
    /// QEM (`pmcodec eval --sweep`): horse 1.068 -> 1.048, cat 1.099 -> 1.060, for 0.1-2% more
    /// bytes. Once a band has been stored, a point off the surface is weighed against the bits
    /// reaching the surface costs in it (`grid::on_surface_grid_rated`): where skinning
    /// predicts most nodes exactly, nodes mostly stay at their cheapest points (issue 17's
    /// character: 15% -> 2.5% more bytes than without). False stores them as files before it
    /// did.
    pub surface_grid: bool,
    /// Band 0's prediction on inter frames. `KeyframeAffine` (the default) stores 21% fewer
    /// position bytes than `Mean` on the horse at 12 bits (17% on samba) for about a tenth more
    /// decoding time; `Affine` about 1% fewer again, for half again `Mean`'s decoding time,
    /// which also lengthens seeks (up to 15 frames from a keyframe).
    pub motion: Motion,
    /// Band 0's decoding order. `BreadthFirst` (the default) gives each input vertex a stencil
    /// on one side of it; `Input` is what versions 3 and 4 used.
    pub order: VertexOrder,
    /// For a skinned sequence, where coarse nodes sit in bind space; `None` encodes it as any
    /// other sequence. Skinning then predicts every band whose frame it pays for.
    pub skin: Option<SkinPlacement>,
    /// In bands skinning predicts, coarse nodes stored at their skinned positions (residual
    /// zero) where that keeps their cluster's error within this tolerance (see
    /// [`SkinnedCoarse`]; Houle and Poulin's coarse vertices are bind-space points). `None`
    /// stores them near their per-frame quadric-optimal points, as files before it did.
    pub skinned_coarse: Option<SkinnedCoarse>,
    /// The preamble flags to write with (`format::DEFAULT_FLAGS`, the default: small chunks
    /// stored as they are, empty Delta and Corners chunks left out, front-coded names, and the
    /// banded index where it is no longer, which coarse clients read in part; `format::FLAGS`:
    /// the same with the frame-by-frame index; 0: every chunk a zstd frame, as files before
    /// the flags, for comparison). Unknown bits are dropped.
    pub chunk_flags: u16,
    /// How a skinned file codes each frame's palette: Joints chunks (the default) or the
    /// Palette chunks files had before them (kept for comparison and for tests of readers).
    pub palette_coding: PaletteCoding,
    /// Which bands' faces and corner updates the file leaves for their readers to derive from
    /// the Triangles chunk and the Key and Delta chunks below them (proto/container.md, "Faces",
    /// coding 2). `Always` (the default) writes the smallest file; `Never` writes them all, as
    /// files before the derived coding did.
    pub derived_topology: DerivedTopology,
    /// For a skinned sequence predicted by skinning, recluster (Kircher & Garland section 4)
    /// only every this many frames; the frames between keep their clusters and move their
    /// nodes (0 or 1: every frame). Where the motion is the skin's, clusters fitted to one pose
    /// stay good for the next few, and the swap search is the larger part of the reclustering
    /// thread's work (issue 17, "Encode cost"). A value beyond the frame count (`u32::MAX`)
    /// keeps frame 0's clusters throughout, as `pmcodec encode` does for a glTF's own skin: a
    /// coarse node's skin is fitted to its frame-0 cluster, and a node whose cluster swaps drifts
    /// from its skinned prediction (a generated 34,102-vertex character: 11.2 MB -> 7.1 MB).
    pub skinned_recluster_every: u32,
}

/// The chunk kind a skinned file's palettes are written in (proto/container.md, "Palette" and
/// "Joints").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PaletteCoding {
    /// Rigid entries as quaternion, scale and translation, Exp-Golomb coded, each chunk in the
    /// shorter of the plain and the linked coding (entries predicted through a reference entry,
    /// "Linked coding").
    #[default]
    Joints,
    /// Joints chunks in the plain coding only (as the encoder wrote them before the linked
    /// coding; kept for comparison).
    JointsPlain,
    /// Twelve varints per moved entry (files written before the Joints chunk).
    Palette,
}

/// Where a coarse node of a skinned sequence sits in bind space (input vertices keep their
/// own rest positions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SkinPlacement {
    /// The rest centroid of the node's cluster.
    Centroid,
    /// The node's frame-0 position carried back through its blended frame-0 transform (Houle
    /// and Poulin's bone-space placement).
    #[default]
    BackPropagated,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions {
            // Levels at 25% and 10% of the input, the budgets LOD chains commonly ship, then
            // every 4x: a client drawing 10% of the triangles reads bands 2.. only.
            build: BuildOptions { anchors: vec![0.25, 0.10], ..BuildOptions::default() },
            base: BaseOptions::default(),
            recluster: ReclusterOptions::default(),
            keyframe_interval: 16,
            quantization: QuantizationChoice::MaxError(1e-4),
            coarse_grid: Some(0),
            surface_grid: true,
            motion: Motion::KeyframeAffine,
            order: VertexOrder::BreadthFirst,
            skin: Some(SkinPlacement::default()),
            skinned_coarse: Some(SkinnedCoarse::default()),
            chunk_flags: crate::format::DEFAULT_FLAGS,
            palette_coding: PaletteCoding::Joints,
            derived_topology: DerivedTopology::Always,
            skinned_recluster_every: 1,
        }
    }
}
