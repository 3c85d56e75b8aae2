//! Decoding: replaying keyframes and deltas down to a finest level L, reconstructing the
//! quantized node positions, and extracting meshes at any cut.

mod cut;
mod derived;
mod textured;

use cut::Derived;
pub use cut::{BudgetCut, BudgetPriorities, banded_priority};

use crate::appearance::DecodedAppearance;
use crate::derive::Below;
use crate::format::{ChunkKind, Motion};
use crate::payload;
use crate::predict::{AffineFits, Band0Motion, LowerNeighbours, Siblings, StencilWeights, predict};
use crate::skin::{
    NodeSkin, Rig, SkinState, band_entries, has_palette_chunk, predict_skinned, read_binds, read_joints, read_palette, read_pose,
};

/// A frame's pose as read, applied once the rest of the frame is: its palette, its entries'
/// rigid parameters (files with Joints chunks; empty else), its band mask, and whether it is a
/// keyframe's.
/// A frame's rigid parameters and links (files with Joints chunks).
type HeldRig = (Vec<Option<Rig>>, Vec<crate::skin::Link>);
type ReadPose = (Vec<i64>, HeldRig, u64, bool);
use crate::{ByteSource, ContainerError, Reader};
use glam::Vec3;
use pmcodec_hierarchy::NONE;
use pmcodec_hierarchy::progressive::{CornerUpdate, FrameDelta, KeyBand, Keyframe, Replay};
use pmcodec_hierarchy::recluster::Swap;

/// Plays a container frame by frame down to a finest level. It owns its [`Reader`]; use
/// [`Reader::borrowed`] to decode from a reader you keep. A clone is an independent decoder
/// at the same frame (servers keep states per frame and step clones forward).
#[derive(Clone)]
pub struct Decoder<S> {
    reader: Reader<S>,
    min_level: usize,
    replay: Option<Replay>,
    frame: Option<u32>,
    triangles: Option<Vec<[u32; 3]>>,
    /// Level-0 lower neighbours (from the triangles; empty when level 0 is not decoded).
    lower: LowerNeighbours,
    /// Scratch for the sibling-motion prediction.
    siblings: Siblings,
    /// Scratch for band 0's affine motion prediction (version 4).
    fits: AffineFits,
    /// Band 0's stencil weights from the last keyframe decoded (keyframe affine motion).
    weights: StencilWeights,
    /// Quantized positions of every node (global ids; only levels >= min_level are decoded).
    current: Vec<[i32; 3]>,
    previous: Vec<[i32; 3]>,
    /// Dequantized positions, split priorities and split order of the current frame, computed
    /// by the first [`Decoder::mesh`] after a seek (a server cuts one decoded frame at many
    /// budgets).
    derived: Option<Derived>,
    /// Keyframe states kept by [`Decoder::keep_keyframes`], most recently used last.
    kept: Vec<KeptKeyframe>,
    keep: usize,
    /// The appearance chunks (version 6), read with the first keyframe.
    looks: Option<DecodedAppearance>,
    /// The skin of a skinned file, once its bind chunks are read.
    skin: Option<SkinState>,
    /// The input triangles, read for deriving a band's faces ([`crate::derive`]) by a decoder
    /// above level 0.
    fine: Option<std::sync::Arc<Vec<[u32; 3]>>>,
    /// The levels below `min_level` while the current keyframe interval derives band
    /// `min_level`'s faces and corner updates (Faces coding 2).
    below: Option<Below>,
    /// How budgets are cut.
    budget_cut: BudgetCut,
    /// Dequantized positions of the current interval's keyframe (every node, global ids):
    /// what [`BudgetPriorities::Keyframe`] ranks reveals by on each frame of the interval;
    /// empty unless the budget cut needs them (a server's many decoder states pay nothing).
    key_positions: Vec<Vec3>,
}

/// A decoder's state just after loading a keyframe: what seeking back to it restores.
#[derive(Clone)]
struct KeptKeyframe {
    frame: u32,
    replay: Replay,
    current: Vec<[i32; 3]>,
    /// Band 0's stencil weights from it (keyframe affine motion; empty otherwise).
    weights: StencilWeights,
    /// Its joint palette, rigid parameters and skinned bands (skinned files).
    pose: (Vec<i64>, HeldRig, u64),
    /// The levels below `min_level` when the interval derives its faces.
    below: Option<Below>,
}

impl<S: ByteSource> Decoder<S> {
    /// A decoder that reads bands `min_level..` only.
    pub fn new(reader: Reader<S>, min_level: usize) -> Result<Self, ContainerError> {
        let h = reader.header();
        if min_level >= h.levels() {
            return Err(ContainerError::Options(format!("level {min_level}: the file has levels 0..{}", h.levels() - 1)));
        }
        if !reader.covers(min_level) {
            return Err(ContainerError::Options(format!("level {min_level}: the reader holds the index entries of another level only")));
        }
        let total = h.node_count() as usize;
        Ok(Decoder {
            reader,
            min_level,
            replay: None,
            frame: None,
            triangles: None,
            lower: LowerNeighbours::default(),
            siblings: Siblings::default(),
            fits: AffineFits::default(),
            weights: StencilWeights::default(),
            current: vec![[0; 3]; total],
            previous: vec![[0; 3]; total],
            derived: None,
            kept: Vec::new(),
            keep: 0,
            looks: None,
            skin: None,
            fine: None,
            below: None,
            budget_cut: BudgetCut::default(),
            key_positions: Vec::new(),
        })
    }

    /// Chooses how budgets are cut ([`BudgetCut`]; the default is the spec's whole splits).
    /// Error bounds and levels are unaffected. A cut that ranks by the keyframe's positions
    /// needs them: chosen at a frame, it decodes the frame again from its keyframe (the error
    /// is that decoding's), since decoders keep them only while such a cut is chosen.
    pub fn set_budget_cut(&mut self, c: BudgetCut) -> Result<(), ContainerError> {
        if c == self.budget_cut {
            return Ok(());
        }
        let needs = c.holds_keyframe() && !self.budget_cut.holds_keyframe();
        self.budget_cut = c;
        self.invalidate_derived();
        if !c.holds_keyframe() {
            self.key_positions = Vec::new();
        }
        if let (true, Some(f)) = (needs, self.frame) {
            self.frame = None;
            self.seek(f)?;
        }
        Ok(())
    }

    /// Keeps the state after each of the last `n` keyframes loaded (0, the default, keeps
    /// none), so that seeking back to one of them restores it instead of reading and decoding
    /// it again: a player that scrubs, or a random seek, then pays only the frames after the
    /// keyframe. Each kept state costs about as much memory as the decoder itself.
    pub fn keep_keyframes(&mut self, n: usize) {
        self.keep = n;
        let excess = self.kept.len().saturating_sub(n);
        self.kept.drain(..excess);
    }

    /// The frame the decoder holds (the last one decoded), `None` before the first.
    pub fn frame(&self) -> Option<u32> {
        self.frame
    }

    /// The reader the decoder fetches chunks through.
    pub fn reader(&self) -> &Reader<S> {
        &self.reader
    }

    /// Finest level this decoder reads.
    pub fn min_level(&self) -> usize {
        self.min_level
    }

    /// The chunks that advancing to `frame` reads that are not yet read (for prefetching by a
    /// network client): from the current frame when on the way, else from the keyframe.
    pub fn chunks_for(&self, frame: u32) -> Vec<crate::ChunkEntry> {
        let h = self.reader.header();
        if frame >= h.frame_count {
            return Vec::new();
        }
        let key = h.keyframe_before(frame);
        let (start, load_key) = match self.frame {
            Some(c) if c <= frame && c >= key => (c + 1, false),
            _ => (key, true),
        };
        // Frames whose deltas are applied: after the keyframe, or after the current frame.
        let first_delta = start + if load_key { 1 } else { 0 };
        let first_positions = if load_key { key } else { start };
        let mut out = Vec::new();
        // A band whose faces the interval derives reads the input triangles and the Key and
        // Delta chunks below it too.
        let derived = self.reader.derives(key, self.min_level);
        let wanted = |e: &&crate::ChunkEntry| {
            e.kind.read_at(e.band as usize, self.min_level)
                || (derived
                    && (e.kind == ChunkKind::Triangles
                        || (matches!(e.kind, ChunkKind::Key | ChunkKind::Delta) && (e.band as usize) < self.min_level)))
        };
        for e in self.reader.index().chunks.iter().filter(wanted) {
            let take = match e.kind {
                ChunkKind::Triangles => load_key && self.triangles.is_none() && self.fine.is_none(),
                // Frame 0's too: attribute tables may predict through its hierarchy, and a
                // keyframe's Key chunk in coding 3 codes its changes from frame 0's.
                ChunkKind::Key => load_key && (e.frame == key || e.frame == 0),
                ChunkKind::Faces => load_key && e.frame == key,
                ChunkKind::Delta | ChunkKind::Corners => e.frame >= first_delta && e.frame <= frame,
                ChunkKind::Positions | ChunkKind::Pose | ChunkKind::Palette | ChunkKind::Joints => {
                    e.frame >= first_positions && e.frame <= frame
                }
                // Read once, with the first keyframe; images are fetched on their own.
                ChunkKind::Charts | ChunkKind::Materials | ChunkKind::Attributes => load_key && self.looks.is_none(),
                ChunkKind::Image => false,
                ChunkKind::Bind => load_key && self.skin.is_none(),
            };
            if take {
                out.push(*e);
            }
        }
        out
    }

    /// The replayed hierarchy of the current frame (cut, degenerate sets, swaps applied), `None` before the first frame.
    pub fn replay(&self) -> Option<&Replay> {
        self.replay.as_ref()
    }

    fn chunk(&self, kind: ChunkKind, frame: u32, band: usize) -> Result<Vec<u8>, ContainerError> {
        let found = self.reader.find(kind, frame, band as u32);
        if found.is_none() && crate::format::sparse_kind(kind, self.reader.flags()) {
            return Ok(crate::format::left_out_payload(kind).to_vec());
        }
        let e = found.ok_or_else(|| ContainerError::Corrupt {
            what: format!("frame {frame} band {band} {}", kind.name()),
            detail: "missing from the index".into(),
        })?;
        self.reader.read_chunk(e)
    }

    /// Brings the decoder to `frame`: from the current frame when that is on the way, else
    /// from the keyframe at or before it.
    pub fn seek(&mut self, frame: u32) -> Result<(), ContainerError> {
        self.invalidate_derived();
        let h = self.reader.header();
        if frame >= h.frame_count {
            return Err(ContainerError::NoSuchFrame { frame, frames: h.frame_count });
        }
        let key = h.keyframe_before(frame);
        let start = match self.frame {
            Some(c) if c <= frame && c >= key => c,
            _ => {
                self.enter_keyframe(key)?;
                key
            }
        };
        for f in start + 1..=frame {
            self.step(f)?;
        }
        Ok(())
    }

    /// Brings the decoder to keyframe `key`: restored when it is kept, else loaded (and kept
    /// when [`Decoder::keep_keyframes`] asks for it).
    fn enter_keyframe(&mut self, key: u32) -> Result<(), ContainerError> {
        if let Some(i) = self.kept.iter().position(|k| k.frame == key) {
            let k = self.kept.remove(i);
            match self.replay.as_mut() {
                Some(r) => r.copy_from(&k.replay),
                None => self.replay = Some(k.replay.clone()),
            }
            self.current.copy_from_slice(&k.current);
            self.weights.clone_from(&k.weights);
            self.below.clone_from(&k.below);
            if let Some(s) = self.skin.as_mut() {
                s.advance_rig(k.pose.0.clone(), k.pose.1.clone(), true, k.pose.2);
            }
            self.frame = Some(key);
            self.kept.push(k);
            self.hold_key_positions();
            return Ok(());
        }
        self.load_keyframe(key)?;
        self.hold_key_positions();
        if let (true, Some(replay)) = (self.keep > 0, &self.replay) {
            if self.kept.len() >= self.keep {
                self.kept.remove(0);
            }
            self.kept.push(KeptKeyframe {
                frame: key,
                replay: replay.clone(),
                current: self.current.clone(),
                weights: self.weights.clone(),
                pose: self.skin.as_ref().map(|s| (s.palette.clone(), (s.rig.clone(), s.links.clone()), s.mask)).unwrap_or_default(),
                below: self.below.clone(),
            });
        }
        Ok(())
    }

    /// Keeps the keyframe just entered's positions for [`BudgetPriorities::Keyframe`].
    fn hold_key_positions(&mut self) {
        if !self.budget_cut.holds_keyframe() {
            return;
        }
        let mut key = std::mem::take(&mut self.key_positions);
        self.positions_into(&mut key);
        self.key_positions = key;
    }

    fn load_keyframe(&mut self, frame: u32) -> Result<(), ContainerError> {
        // The skin first: band 0's texture coordinates may be predicted from its bind positions.
        if self.reader.header().skin.is_some() && self.skin.is_none() {
            self.skin = Some(self.load_skin()?);
        }
        self.load_appearance()?;
        let h = self.reader.header();
        let sizes = &h.level_sizes;
        let mut key = Keyframe { bands: vec![KeyBand::default(); h.levels()] };
        for j in (self.min_level..h.levels()).rev() {
            let what = format!("frame {frame} band {j} keyframe");
            key.bands[j].parent = self.read_parents(frame, j)?;
            // Clusters are never empty (proto/container.md, "The model the file encodes"): a
            // parent map that leaves one empty is not a hierarchy the encoder wrote.
            if let Some(&above) = sizes.get(j + 1) {
                let mut used = vec![false; above as usize];
                for &p in &key.bands[j].parent {
                    if let Some(u) = used.get_mut(p as usize) {
                        *u = true;
                    }
                }
                if let Some(p) = used.iter().position(|&u| !u) {
                    return Err(ContainerError::Corrupt { what, detail: format!("level {} node {p} has no children", j + 1) });
                }
            }
        }
        let mut below = None;
        if self.min_level > 0 {
            let j = self.min_level;
            let raw = self.chunk(ChunkKind::Faces, frame, j)?;
            if crate::derive::is_derived(&raw) {
                let b = self.derive_below(frame)?;
                key.bands[j].faces = b.faces();
                self.fine = Some(b.triangles());
                below = Some(b);
            } else {
                key.bands[j].faces =
                    payload::read_faces(&raw, &format!("frame {frame} band {j} faces"), sizes[j], h.triangle_count, self.reader.version())?;
            }
        }
        if self.min_level == 0 && self.triangles.is_none() {
            let triangles = self.read_triangles()?;
            let h = self.reader.header();
            self.lower = LowerNeighbours::new(h.vertex_count as usize, &triangles, h.order);
            self.triangles = Some(triangles);
        }
        self.below = below;
        let pose = self.read_pose(frame, true)?;
        let h = self.reader.header();
        let fail = |source| ContainerError::Delta { what: format!("frame {frame} keyframe"), source };
        // A replay of this file is reused (no allocation); a failed load leaves none.
        match self.replay.take() {
            Some(mut r) => {
                r.reload(&key, self.triangles.as_deref()).map_err(fail)?;
                self.replay = Some(r);
            }
            None => {
                let tris = self.triangles.as_deref();
                let r = Replay::from_keyframe(sizes, h.branching, &key, self.min_level, h.triangle_count as usize, tris).map_err(fail)?;
                self.replay = Some(r);
            }
        }
        self.commit_pose(pose);
        self.decode_positions(frame, true)?;
        self.keyframe_weights();
        self.frame = Some(frame);
        self.invalidate_derived();
        Ok(())
    }

    fn step(&mut self, frame: u32) -> Result<(), ContainerError> {
        let h = self.reader.header();
        let (sizes, triangles) = (h.level_sizes.clone(), h.triangle_count);
        // Read everything first: the replay changes only once the frame's data is known good.
        let mut moves = Vec::with_capacity(sizes.len());
        for j in (self.min_level..sizes.len()).rev() {
            let raw = self.chunk(ChunkKind::Delta, frame, j)?;
            moves.push((j, payload::read_delta(&raw, &format!("frame {frame} band {j} delta"), &sizes, j)?));
        }
        let below_moves = self.below_moves(frame)?;
        let pose = self.read_pose(frame, false)?;
        let mut delta = FrameDelta::default();
        let j = self.min_level;
        if let Some(below) = self.below.as_mut() {
            // A derived interval: the moves below the level give its corner updates.
            delta.corners.extend(below.apply(&below_moves).into_iter().map(|(t, corners)| CornerUpdate { level: j as u32, t, corners }));
        } else if self.min_level > 0 {
            let j = self.min_level;
            let raw = self.chunk(ChunkKind::Corners, frame, j)?;
            let what = format!("frame {frame} band {j} corners");
            let updates = if self.reader.version() >= 5 {
                let replay = self.replay.as_ref().ok_or_else(|| ContainerError::Options("no keyframe loaded".into()))?;
                payload::read_corner_updates(&raw, &what, sizes[j], replay.corners())?
            } else {
                payload::read_faces(&raw, &what, sizes[j], triangles, self.reader.version())?
            };
            delta.corners.extend(updates.into_iter().map(|(t, corners)| CornerUpdate { level: j as u32, t, corners }));
        }
        let replay = self.replay.as_mut().ok_or_else(|| ContainerError::Options("no keyframe loaded".into()))?;
        for (j, band) in moves {
            for (v, to) in band {
                // `from` is whatever the replay holds: net changes carry no history.
                let from = replay.h.parent.get(j).and_then(|p| p.get(v as usize)).copied().unwrap_or(NONE);
                delta.swaps.push(Swap { level: j as u32, v, from, to });
            }
        }
        replay.apply(&delta).map_err(|source| ContainerError::Delta { what: format!("frame {frame} delta"), source })?;
        self.commit_pose(pose);
        std::mem::swap(&mut self.previous, &mut self.current);
        self.decode_positions(frame, false)?;
        self.frame = Some(frame);
        self.invalidate_derived();
        Ok(())
    }

    /// Reads the skin of every node of bands `min_level..` from the bind chunks.
    fn load_skin(&self) -> Result<SkinState, ContainerError> {
        let h = self.reader.header();
        let palette = h.skin.as_ref().map_or(0, |s| s.palette_len);
        let mut offset = 0usize;
        let mut state = SkinState { nodes: vec![NodeSkin::default(); h.node_count() as usize], ..Default::default() };
        for (j, &size) in h.level_sizes.iter().enumerate() {
            if j >= self.min_level {
                let raw = self.chunk(ChunkKind::Bind, 0, j)?;
                let nodes = read_binds(&raw, &format!("band {j} bind"), size, palette)?;
                state.nodes[offset..offset + size as usize].copy_from_slice(&nodes);
            }
            offset += size as usize;
        }
        // Files written since the Palette chunk have no Pose chunks; since the Joints chunk,
        // Joints chunks where they had Palette chunks.
        let chunks = &self.reader.index().chunks;
        state.joints = chunks.iter().any(|e| e.kind == ChunkKind::Joints);
        if !chunks.iter().any(|e| e.kind == ChunkKind::Pose) {
            let mut offsets = vec![0u32];
            for &n in &h.level_sizes {
                offsets.push(offsets.last().copied().unwrap_or(0).saturating_add(n));
            }
            state.bands = Some(band_entries(&state.nodes, &offsets, self.min_level, palette));
        }
        Ok(state)
    }

    /// Reads frame `frame`'s pose chunk (skinned files): the palette it gives and its band
    /// mask, applied by [`Decoder::commit_pose`] once the rest of the frame is read.
    fn read_pose(&self, frame: u32, intra: bool) -> Result<Option<ReadPose>, ContainerError> {
        let (Some(sh), Some(state)) = (self.reader.header().skin.as_ref(), self.skin.as_ref()) else { return Ok(None) };
        let levels = self.reader.header().levels();
        let Some(bands) = state.bands.as_ref() else {
            let raw = self.chunk(ChunkKind::Pose, frame, 0)?;
            let mut palette = Vec::new();
            let mask = read_pose(&raw, &format!("frame {frame} pose"), (sh.palette_len, levels), state.prediction(intra), &mut palette)?;
            return Ok(Some((palette, (Vec::new(), Vec::new()), mask, intra)));
        };
        // Entries of bands this decoder does not read stay 0: none of its nodes uses them.
        let mut palette = vec![0i64; sh.palette_len as usize * crate::skin::ENTRY];
        let mut rig = if state.joints { vec![None; sh.palette_len as usize] } else { Vec::new() };
        let mut links = if state.joints { vec![crate::skin::Link::NONE; sh.palette_len as usize] } else { Vec::new() };
        let mut mask = None;
        for j in (self.min_level..levels).rev().filter(|&j| has_palette_chunk(bands, j)) {
            let (m, what) = if state.joints {
                let raw = self.chunk(ChunkKind::Joints, frame, j)?;
                let what = format!("frame {frame} band {j} joints");
                (read_joints(&raw, &what, (bands, j), levels, &state.joint_prediction(intra), (&mut palette, &mut rig, &mut links))?, what)
            } else {
                let raw = self.chunk(ChunkKind::Palette, frame, j)?;
                let what = format!("frame {frame} band {j} palette");
                (read_palette(&raw, &what, &bands[j], levels, state.prediction(intra), &mut palette)?, what)
            };
            if mask.is_some_and(|before| before != m) {
                return Err(ContainerError::Corrupt { what, detail: format!("band mask {m:#x} where the band above says otherwise") });
            }
            mask = Some(m);
        }
        Ok(Some((palette, (rig, links), mask.unwrap_or(0), intra)))
    }

    fn commit_pose(&mut self, pose: Option<ReadPose>) {
        if let (Some(s), Some((palette, rig, mask, intra))) = (self.skin.as_mut(), pose) {
            s.advance_rig(palette, rig, intra, mask);
        }
    }

    /// With keyframe affine motion, the stencil weights of the keyframe just decoded (in
    /// `current`), which band 0 of the frames up to the next keyframe moves by.
    fn keyframe_weights(&mut self) {
        let h = self.reader.header();
        if h.motion == Motion::KeyframeAffine && self.min_level == 0 {
            self.weights.compute(&self.lower, &self.current, h.vertex_count as usize);
        }
    }

    /// Decodes the positions chunks of `frame` (bands top..min_level) into `current`.
    fn decode_positions(&mut self, frame: u32, from_key: bool) -> Result<(), ContainerError> {
        let h = self.reader.header();
        let intra = from_key || h.is_keyframe(frame);
        let replay = self.replay.as_ref().ok_or_else(|| ContainerError::Options("no keyframe loaded".into()))?;
        let (sizes, offsets) = (&replay.h.level_sizes, &replay.h.offsets);
        for j in (self.min_level..sizes.len()).rev() {
            let what = format!("frame {frame} band {j} positions");
            let raw = self.chunk(ChunkKind::Positions, frame, j)?;
            let (shift, residuals) = payload::read_positions(&raw, &what, sizes[j])?;
            if from_key && !h.is_keyframe(frame) {
                return Err(ContainerError::Corrupt { what, detail: "keyframe positions on a frame that is not a keyframe".into() });
            }
            let base = offsets[j] as usize;
            let parents = replay.h.parent.get(j).map(Vec::as_slice).unwrap_or(&[]);
            // Parents exist below the top band only (offsets has one entry more than sizes).
            let up = if j + 1 < sizes.len() { offsets.get(j + 1).map(|&o| o as usize) } else { None };
            self.siblings.reset(sizes.get(j + 1).map_or(0, |&n| n as usize));
            let n0 = sizes[0] as usize;
            let motion = Band0Motion::select(h.motion, j == 0 && !intra, &self.lower, &self.previous, n0, &mut self.fits, &self.weights);
            // Band 0 in its decoding order (a permutation of the input vertices, as many as
            // the band has), coarser bands in node order.
            let sequence = if j == 0 { Some(self.lower.sequence()) } else { None };
            let skinned = self.skin.as_ref().filter(|s| s.uses(j));
            let mut before = None;
            for (k, r) in residuals.iter().enumerate() {
                let v = match sequence {
                    Some(s) => *s.get(k).ok_or_else(|| ContainerError::Corrupt {
                        what: what.clone(),
                        detail: "more input vertices than the triangles chunk's decoding order holds".into(),
                    })? as usize,
                    None => k,
                };
                let g = base + v;
                let parent = match (up, parents.get(v)) {
                    (Some(o), Some(&p)) => Some((o + p as usize, p as usize)),
                    _ => None,
                };
                let p = match skinned {
                    Some(s) => predict_skinned(&s.nodes[g], &s.palette, &s.previous, intra, self.previous[g]),
                    None => predict(j, v, g, before, parent, &self.lower, motion, &self.siblings, intra, &self.current, &self.previous),
                };
                let q = [
                    p[0].wrapping_add(r[0].wrapping_shl(shift)),
                    p[1].wrapping_add(r[1].wrapping_shl(shift)),
                    p[2].wrapping_add(r[2].wrapping_shl(shift)),
                ];
                self.current[g] = q;
                before = Some(g);
                if let Some((_, local)) = parent {
                    self.siblings.add(local, q, self.previous[g]);
                }
            }
        }
        Ok(())
    }

    /// Quantized positions of every node (global ids; zero below the finest level).
    pub fn quantized(&self) -> &[[i32; 3]] {
        &self.current
    }

    /// The skin of a skinned file at the current frame: every node's bind position and
    /// influences (by global id; nodes of bands below the decoder's level are default) and the
    /// frame's palette (`ENTRY` fixed-point values per entry, proto/container.md "Skinning";
    /// [`crate::palette_transforms`] turns it into transforms). `None` in files without a
    /// skin and before the first frame.
    pub fn skin(&self) -> Option<(&[NodeSkin], &[i64])> {
        self.skin.as_ref().map(|s| (s.nodes.as_slice(), s.palette.as_slice()))
    }

    /// Dequantized positions of every node (global ids).
    pub fn positions(&self) -> Vec<Vec3> {
        let mut out = Vec::new();
        self.positions_into(&mut out);
        out
    }

    /// [`Decoder::positions`] into a buffer the caller keeps, so a loop over frames allocates once.
    pub fn positions_into(&self, out: &mut Vec<Vec3>) {
        let h = self.reader.header();
        let lo = Vec3::from_array(h.bbox_min);
        let step = h.quantization.step;
        out.clear();
        out.extend(self.current.iter().map(|q| lo + Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32) * step));
    }

    /// Marks the derived data stale (the decoder moved, or may have failed half-way), keeping
    /// its buffers for the next frame.
    fn invalidate_derived(&mut self) {
        if let Some(d) = self.derived.as_mut() {
            d.frame = None;
        }
    }
}
