//! Skinned streams (format version 6): the skeleton once, its joint palette's matrices per frame,
//! and node positions predicted by linear blend skinning, so that only residuals are coded (the
//! motion compensation of MPEG-4 FAMC: Mamou, Zaharia and Prêteux, "FAMC: the MPEG-4 standard
//! for animated mesh compression", 2008; coarse nodes placed in bone space as Houle and Poulin,
//! "Simplification and real-time smooth transitions of articulated meshes", 2001, place them).
//!
//! Everything a decoder computes here is integer arithmetic (proto/container.md, "Skinning"):
//! a node's bind position in bind quanta, its at most four weights in 1/65536, the palette's
//! linear parts in 2^-15 position quanta per bind quantum and translations in 2^-2 quanta, all
//! combined in wrapping 64-bit integers, so a decoder in any language gets the same bits.

// Per-axis and per-node loops index several parallel arrays at once, as the spec states them.
#![allow(clippy::needless_range_loop)]

mod bits;
mod fit;
mod hierarchy;
mod joints;
mod linked;
mod payload;
mod place;
mod rig;
mod skeleton;

pub(crate) use fit::{SkinFit, fit_skin};
pub use hierarchy::{Link, NO_REF};
pub(crate) use hierarchy::{choose_links, fit_frame, read_before};
pub use joints::Rig;
pub(crate) use joints::{JointPrediction, JointsFrame, read_joints, write_joints, write_joints_best};
pub(crate) use payload::{PosePrediction, read_binds, read_palette, read_pose, write_binds, write_palette};
pub(crate) use place::CoarseQuadrics;
pub use place::SkinnedCoarse;
pub use rig::{bind_position, influences, palette_transforms};

use serde::{Deserialize, Serialize};

/// The header's skin fields (version 6; `None` in files without skinning).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkinHeader {
    /// Entries of the joint palette.
    pub palette_len: u32,
    /// The bind-space quantum: bind positions are stored as integers times this.
    pub bind_step: f32,
}

/// Caps a reader checks so that what it allocates stays bounded and the arithmetic stays in
/// range for sane files (proto/container.md, "Limits").
pub const MAX_PALETTE: u32 = 1 << 16;
/// Bound on a bind coordinate, in bind quanta.
pub const MAX_BIND: i64 = 1 << 30;
/// Bound on a matrix value, in its fixed-point units.
pub const MAX_MATRIX: i64 = 1 << 40;
/// Weights are in units of 2^-16 and sum to this.
pub const WEIGHT_ONE: i64 = 1 << 16;
/// Fixed-point bits of the palette's linear parts and of its translations.
pub const LINEAR_BITS: u32 = 15;
pub const TRANSLATION_BITS: u32 = 2;
/// Values per palette entry: three rows of (three linear values, one translation).
pub const ENTRY: usize = 12;

/// One node's skin: bind position and influences (palette entry, weight; weight 0 unused).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeSkin {
    /// Bind position in quanta of the header's `bind_step`.
    pub bind: [i64; 3],
    /// Palette entries of the influences, in stored order.
    pub joints: [u32; 4],
    /// Their weights in units of 2^-16, summing to 65536; 0 marks an unused slot.
    pub weights: [i64; 4],
}

/// Node `skin` posed by `palette` (ENTRY values per entry), in position quanta. Per influence
/// `k` and axis `a`: `y = ((L[a][0] b0 + L[a][1] b1 + L[a][2] b2) >> 13) + T[a]` (2^-2 quanta),
/// summed as `acc += w_k y`; the result is `(acc + 2^17) >> 18` wrapped to 32 bits. Every
/// operation wraps in 64 bits and `>>` is arithmetic.
#[inline]
pub fn lbs(skin: &NodeSkin, palette: &[i64]) -> [i32; 3] {
    let mut acc = [0i64; 3];
    for k in 0..4 {
        let w = skin.weights[k];
        if w == 0 {
            continue;
        }
        let base = skin.joints[k] as usize * ENTRY;
        let Some(m) = palette.get(base..base + ENTRY) else { continue };
        for a in 0..3 {
            let r = &m[4 * a..4 * a + 4];
            let dot =
                r[0].wrapping_mul(skin.bind[0]).wrapping_add(r[1].wrapping_mul(skin.bind[1])).wrapping_add(r[2].wrapping_mul(skin.bind[2]));
            let y = (dot >> (LINEAR_BITS - TRANSLATION_BITS)).wrapping_add(r[3]);
            acc[a] = acc[a].wrapping_add(w.wrapping_mul(y));
        }
    }
    let round = 1i64 << (15 + TRANSLATION_BITS);
    acc.map(|v| (v.wrapping_add(round) >> (16 + TRANSLATION_BITS)) as i32)
}

/// The skinning prediction of a node stored as `prev` in the previous frame: on keyframes its
/// skinned position, else its previous position moved as skinning moves it.
#[inline]
pub fn predict_skinned(skin: &NodeSkin, palette: &[i64], previous_palette: &[i64], intra: bool, prev: [i32; 3]) -> [i32; 3] {
    let now = lbs(skin, palette);
    if intra {
        return now;
    }
    skinned_motion(now, lbs(skin, previous_palette), prev)
}

/// [`predict_skinned`] off a keyframe from the node's skinned positions under the frame's
/// palette (`now`) and the previous frame's (`before`): its previous position `prev` moved as
/// skinning moves it.
#[inline]
pub fn skinned_motion(now: [i32; 3], before: [i32; 3], prev: [i32; 3]) -> [i32; 3] {
    [0, 1, 2].map(|a| prev[a].wrapping_add(now[a].wrapping_sub(before[a])))
}

/// What a decoder keeps of the skin: every decoded node's skin and the palettes of the current
/// and the previous frame, with the current frame's band mask.
#[derive(Clone, Debug, Default)]
pub struct SkinState {
    /// Per global node id (nodes of bands below the decoder's level stay default).
    pub nodes: Vec<NodeSkin>,
    pub palette: Vec<i64>,
    /// The previous frame's palette, when the current frame is not a keyframe (empty else).
    pub previous: Vec<i64>,
    /// Bit j: band j is predicted by skinning in the current frame.
    pub mask: u64,
    /// Files with Palette or Joints chunks: the palette entries each band's chunk carries (see
    /// [`band_entries`]; empty below the decoder's level). `None`: one Pose chunk per frame.
    pub bands: Option<Vec<Vec<u32>>>,
    /// Files with Joints chunks: each entry's rigid parameters in the current frame and in the
    /// previous one (`None`: not rigid; empty where the palette is).
    pub rig: Vec<Option<Rig>>,
    pub rig_before: Vec<Option<Rig>>,
    /// Files with Joints chunks: each entry's link in the linked coding since the last keyframe
    /// ([`Link::NONE`]: none; empty where the palette is).
    pub links: Vec<Link>,
    /// The file's palettes are in Joints chunks (else Palette or Pose chunks).
    pub joints: bool,
}

/// The palette entries each band's Palette chunk carries: those some node of the band uses
/// (with a positive weight) and no node of a coarser band does, ascending. A client reading
/// bands `L..=top` so gets exactly the entries its nodes use, and works them out from the Bind
/// chunks of those bands alone. `nodes` holds every node by global id; bands below `min_level`
/// get none.
pub fn band_entries(nodes: &[NodeSkin], offsets: &[u32], min_level: usize, palette_len: u32) -> Vec<Vec<u32>> {
    let levels = offsets.len().saturating_sub(1);
    let mut taken = vec![false; palette_len as usize];
    let mut out = vec![Vec::new(); levels];
    for j in (min_level..levels).rev() {
        let band = nodes.get(offsets[j] as usize..offsets[j + 1] as usize).unwrap_or_default();
        for n in band {
            for k in 0..4 {
                let e = n.joints[k] as usize;
                if n.weights[k] > 0 && e < taken.len() && !taken[e] {
                    taken[e] = true;
                    out[j].push(e as u32);
                }
            }
        }
        out[j].sort_unstable();
    }
    out
}

/// Whether band `j` of a file with Palette chunks has one in each frame: the top band always
/// (it carries the band mask for every client), another band when it has entries.
pub fn has_palette_chunk(bands: &[Vec<u32>], j: usize) -> bool {
    j + 1 == bands.len() || bands.get(j).is_some_and(|b| !b.is_empty())
}

impl SkinState {
    /// How the next frame's pose is predicted: from nothing on a keyframe; else from the
    /// current palette, and the one before it when both follow the last keyframe.
    pub fn prediction(&self, intra: bool) -> PosePrediction<'_> {
        match (intra, self.palette.is_empty(), self.previous.is_empty()) {
            (true, ..) | (_, true, _) => PosePrediction::Key,
            (false, false, true) => PosePrediction::Previous(&self.palette),
            (false, false, false) => PosePrediction::Linear(&self.palette, &self.previous),
        }
    }

    /// How the next frame's Joints chunks are predicted (see [`SkinState::prediction`]).
    pub fn joint_prediction(&self, intra: bool) -> JointPrediction<'_> {
        JointPrediction { pose: self.prediction(intra), rig: &self.rig, rig_before: &self.rig_before, links: &self.links }
    }

    /// Makes `palette` the current frame's (`intra`: a keyframe's).
    pub fn advance(&mut self, palette: Vec<i64>, intra: bool, mask: u64) {
        self.previous = std::mem::replace(&mut self.palette, palette);
        if intra {
            // Nothing before a keyframe predicts what follows it.
            self.previous.clear();
        }
        self.mask = mask;
    }

    /// [`SkinState::advance`] for files with Joints chunks, with the frame's rigid parameters
    /// and links.
    pub fn advance_rig(&mut self, palette: Vec<i64>, (rig, links): (Vec<Option<Rig>>, Vec<Link>), intra: bool, mask: u64) {
        self.advance(palette, intra, mask);
        self.links = links;
        self.rig_before = std::mem::replace(&mut self.rig, rig);
        if intra {
            self.rig_before.clear();
        }
    }

    /// Whether band `j` is predicted by skinning in the current frame.
    pub fn uses(&self, j: usize) -> bool {
        j < 64 && self.mask >> j & 1 == 1
    }
}

/// The header's skin fields checked before anything is sized from them; `Some(detail)` when
/// they are not what an encoder writes.
pub fn check_header(h: &crate::Header) -> Option<String> {
    let s = h.skin.as_ref()?;
    if s.palette_len == 0 || s.palette_len > MAX_PALETTE {
        return Some(format!("skin palette of {} entries (1 to {MAX_PALETTE})", s.palette_len));
    }
    if !(s.bind_step.is_finite() && s.bind_step > 0.0) {
        return Some(format!("skin bind quantum {}", s.bind_step));
    }
    None
}

/// An index entry of a skin chunk where the format puts them: only in skinned files, Bind
/// chunks in frame 0, Pose chunks in band 0.
pub fn check_entry(h: &crate::Header, e: &crate::ChunkEntry) -> Result<(), String> {
    use crate::ChunkKind;
    match e.kind {
        ChunkKind::Bind | ChunkKind::Pose | ChunkKind::Palette | ChunkKind::Joints if h.skin.is_none() => {
            Err("a skin chunk in a file without a skin".into())
        }
        ChunkKind::Bind if e.frame != 0 => Err(format!("frame {}, where bind chunks are frame 0", e.frame)),
        ChunkKind::Pose if e.band != 0 => Err(format!("band {}, where pose chunks are band 0", e.band)),
        _ => Ok(()),
    }
}

/// The decompressed sizes a skin chunk may declare: a bind chunk of `n` nodes takes 4 to 101
/// bytes per node (three coordinates, a count, four entries and three weights of up to 10
/// bytes), a pose chunk 1 to 10 bytes per palette value and its mask, a palette chunk its
/// mask (1 to 10 bytes), a bit per entry and up to 10 bytes per value; a joints chunk its mask,
/// up to 35 bits of orders, and per entry up to 4 flag bits, a reference, a pivot and twelve
/// values of up to 127 bits each.
pub fn raw_len_range(h: &crate::Header, kind: crate::ChunkKind, n: u64) -> (u64, u64) {
    let p = h.skin.as_ref().map_or(0, |s| s.palette_len as u64) * ENTRY as u64;
    match kind {
        crate::ChunkKind::Bind => (4 * n, 101 * n),
        crate::ChunkKind::Palette => (1, 10 + p / ENTRY as u64 / 8 + 1 + 10 * p),
        // Per entry at most 4 flag bits, a reference (16 bits), a pivot and twelve values (127
        // bits each): 241 bytes; the mask, 7 orders and the last byte 16. The compact coding's
        // one more bit (all rigid) fits in the 3 bits per entry this leaves over.
        crate::ChunkKind::Joints => (2, 16 + 241 * (p / ENTRY as u64)),
        _ => (1 + p, 10 + 10 * p),
    }
}
