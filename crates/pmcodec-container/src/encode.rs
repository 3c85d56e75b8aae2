//! Encoding a sequence: build H_0, recluster frame by frame, and write keyframes, deltas and
//! quantized, predicted node positions by band, coarse first.

mod coding;
mod options;
mod posed;
mod positions;
mod rate;
mod skin_choice;

pub use options::{EncodeOptions, PaletteCoding, QuantizationChoice, SkinPlacement};
use posed::check_frame;
pub use posed::encode_posed;
pub use positions::EncodeReport;
pub use skin_choice::{SkinTrial, skin_trial};

use crate::ContainerError;
pub use crate::derive::DerivedTopology;
use crate::format::*;
use crate::predict::{LowerNeighbours, coarse_shift};
use crate::skin::{
    CoarseQuadrics, JointsFrame, SkinFit, SkinState, band_entries, fit_skin, has_palette_chunk, write_binds, write_joints,
    write_joints_best, write_palette,
};
use crate::{payload, topology};
use coding::code_frames;
use glam::Vec3;
use pmcodec_hierarchy::base::{PoseSet, VertexWeights, base_quadrics};
use pmcodec_hierarchy::progressive::{Encoder, FrameDelta, Keyframe};
use pmcodec_hierarchy::{FineTopology, Hierarchy, Quadric, build};
use pmcodec_mesh::Sequence;
use positions::{PositionCoder, Skinning, Surface};
use std::collections::HashMap;
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// Net parent changes of one level from a frame's swaps: (node, new parent) where the last
/// swap of a node leaves it elsewhere than before the frame, ascending by node.
fn net_moves(delta: &FrameDelta, level: usize) -> Vec<(u32, u32)> {
    let mut first_from: HashMap<u32, u32> = HashMap::new();
    let mut last_to: HashMap<u32, u32> = HashMap::new();
    for s in delta.swaps.iter().filter(|s| s.level as usize == level) {
        first_from.entry(s.v).or_insert(s.from);
        last_to.insert(s.v, s.to);
    }
    let mut moves: Vec<(u32, u32)> = last_to.into_iter().filter(|(v, to)| first_from.get(v) != Some(to)).collect();
    moves.sort_unstable();
    moves
}

fn pose_name(p: PoseSet) -> String {
    match p {
        PoseSet::FirstFrame => "first-frame".into(),
        PoseSet::AllFrames => "all-frames".into(),
        PoseSet::Sampled(n) => format!("sampled-{n}"),
    }
}

/// Encodes a sequence; `progress(f)` is called after each frame.
pub fn encode(seq: &Sequence, opts: &EncodeOptions, mut progress: impl FnMut(usize)) -> Result<Vec<u8>, ContainerError> {
    encode_until(seq, opts, |f| {
        progress(f);
        ControlFlow::Continue(())
    })
}

/// The quantization step `opts` asks for over the bounding box `lo..hi`.
fn quantization_step(opts: &EncodeOptions, lo: Vec3, hi: Vec3) -> Result<f32, ContainerError> {
    let diag = (hi - lo).length().max(f32::MIN_POSITIVE);
    let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
    let step = match opts.quantization {
        QuantizationChoice::MaxError(e) if e.is_finite() && e > 0.0 => (2.0 * e * diag as f64 / 3f64.sqrt()) as f32,
        QuantizationChoice::Bits(b) if (4..=24).contains(&b) => extent / ((1u32 << b) - 1) as f32,
        q => return Err(ContainerError::Options(format!("quantization {q:?}: use a positive error or 4..=24 bits"))),
    };
    if !(step.is_finite() && step > 0.0) || (extent / step) as f64 > (1u64 << 30) as f64 {
        return Err(ContainerError::Options(format!("quantization step {step} does not fit 30 bits over the bounding box")));
    }
    Ok(step)
}

/// The options as the header records them.
fn encoded_with(opts: &EncodeOptions) -> EncodedWith {
    EncodedWith {
        base_poses: pose_name(opts.base.poses),
        base_weights: match opts.base.weights {
            VertexWeights::None => "none".into(),
            VertexWeights::Tertiles => "tertiles".into(),
            VertexWeights::Smooth => "smooth".into(),
        },
        beta: opts.recluster.beta,
        min_relative_benefit: opts.recluster.min_relative_benefit,
        max_passes: opts.recluster.max_passes,
        homeomorphism: opts.recluster.homeomorphism,
        exact_benefit: opts.recluster.exact_benefit,
        max_error: match opts.quantization {
            QuantizationChoice::MaxError(e) => Some(e),
            _ => None,
        },
        quant_bits: match opts.quantization {
            QuantizationChoice::Bits(b) => Some(b),
            _ => None,
        },
    }
}

/// The header of `seq` encoded with `opts` over the bounding box `lo..hi` at `step`, with a
/// hierarchy of `level_sizes`.
fn header(seq: &Sequence, frame_count: usize, opts: &EncodeOptions, (lo, hi): (Vec3, Vec3), step: f32, level_sizes: Vec<u32>) -> Header {
    Header {
        vertex_count: seq.vertex_count() as u32,
        triangle_count: seq.triangles.len() as u32,
        frame_count: frame_count as u32,
        frame_rate: seq.frame_rate,
        level_sizes,
        branching: opts.build.branching,
        bbox_min: lo.to_array(),
        bbox_max: hi.to_array(),
        quantization: Quantization { step },
        keyframe_interval: opts.keyframe_interval,
        encoded_with: encoded_with(opts),
        generator: format!("pmcodec {}", env!("CARGO_PKG_VERSION")),
        frame_names: seq.frame_names.clone(),
        motion: opts.motion,
        order: opts.order,
        appearance: None,
        skin: None,
    }
}

/// The chunks written so far, compressed, in file order.
struct Chunks(Vec<(ChunkEntry, Vec<u8>)>, u16);

impl Chunks {
    fn push(&mut self, kind: ChunkKind, frame: u32, band: u32, raw: Vec<u8>) -> Result<(), ContainerError> {
        // Nothing to say: left out (FLAG_SPARSE), and read as empty.
        if crate::format::sparse_kind(kind, self.1) && crate::format::leaves_out(kind, &raw) {
            return Ok(());
        }
        let stored = crate::format::store_chunk(&raw, crate::format::zstd_level(kind, &raw), self.1)
            .map_err(|e| ContainerError::Io(format!("zstd: {e}")))?;
        let entry = ChunkEntry {
            kind,
            frame,
            band,
            offset: 0,
            stored_len: stored.len() as u32,
            raw_len: raw.len() as u32,
            crc32: crc32fast::hash(&stored),
        };
        self.0.push((entry, stored));
        Ok(())
    }
}

/// The file: preamble, header, index and chunks.
fn assemble(header: &Header, chunks: Chunks) -> Result<Vec<u8>, ContainerError> {
    let Chunks(made, mut flags) = chunks;
    let entries: Vec<ChunkEntry> = made.iter().map(|(e, _)| *e).collect();
    // The banded index (FLAG_BANDS) only where it is no longer than the frame-by-frame one: its
    // table (a row per group, 1 + 3 per level) can outweigh the per-frame counts it saves on a
    // small file of few frames. (Neither's length depends on the offsets.)
    if flags & crate::format::FLAG_BANDS != 0 {
        let banded = crate::format::banded_index(&entries, header.levels())?.0.len();
        let plain = Index { chunks: entries.clone() }
            .to_bytes(VERSION, header.frame_count)
            .map_err(|e| ContainerError::Io(format!("index: {e}")))?
            .len();
        if banded > plain {
            flags &= !crate::format::FLAG_BANDS;
        }
    }
    // A banded index lays the chunks out group after group.
    let order = crate::format::file_order(&entries, flags, header.levels());
    let mut slots: Vec<Option<(ChunkEntry, Vec<u8>)>> = made.into_iter().map(Some).collect();
    let mut chunks: Vec<(ChunkEntry, Vec<u8>)> = order.iter().filter_map(|&i| slots.get_mut(i).and_then(Option::take)).collect();
    // Offsets are relative to the chunk area, so the index's own length does not feed back.
    let mut offset = 0u64;
    let mut index = Index::default();
    for (e, bytes) in &mut chunks {
        e.offset = offset;
        offset += bytes.len() as u64;
        index.chunks.push(*e);
    }
    // Frame names front-coded under FLAG_NAMES (proto/container.md, "Header").
    let named;
    let header = if flags & FLAG_NAMES != 0 {
        named = Header { frame_names: crate::format::front_code(&header.frame_names), ..header.clone() };
        &named
    } else {
        header
    };
    let hb = postcard::to_stdvec(header).map_err(|e| ContainerError::Io(format!("header: {e}")))?;
    let (ib, table_len) = if flags & crate::format::FLAG_BANDS != 0 {
        crate::format::banded_index(&index.chunks, header.levels())?
    } else {
        (index.to_bytes(VERSION, header.frame_count).map_err(|e| ContainerError::Io(format!("index: {e}")))?, 0)
    };
    // A banded index's CRC in the preamble covers its table; the table holds each group's.
    let covered = if table_len > 0 { &ib[..table_len as usize] } else { &ib[..] };
    let pre = Preamble {
        version: VERSION,
        flags,
        header_len: hb.len() as u32,
        index_len: ib.len() as u32,
        header_crc: crc32fast::hash(&hb),
        index_crc: crc32fast::hash(covered),
        table_len,
    };
    let mut out = Vec::with_capacity(PREAMBLE_LEN + hb.len() + ib.len() + offset as usize);
    out.extend_from_slice(&pre.to_bytes());
    out.extend_from_slice(&hb);
    out.extend_from_slice(&ib);
    for (_, bytes) in &chunks {
        out.extend_from_slice(bytes);
    }
    Ok(out)
}

/// What the coding side needs of one reclustered frame: its swaps and corner updates, its
/// keyframe on keyframes, the hierarchy H_f and every node's position. Sent from the
/// reclustering thread to the coding thread, and sent back to be refilled (no allocation per
/// frame once the first few have gone round).
struct Reclustered {
    frame: usize,
    delta: FrameDelta,
    key: Option<Keyframe>,
    h: Hierarchy,
    positions: Vec<Vec3>,
    /// The quadrics of the coarse nodes (levels 1 and up), when they place them (on their
    /// surfaces, or where skinning may place them).
    quadrics: Vec<Quadric>,
}

impl Reclustered {
    fn new(enc: &Encoder) -> Self {
        Reclustered {
            frame: 0,
            delta: FrameDelta::default(),
            key: None,
            h: enc.hierarchy().clone(),
            positions: Vec::new(),
            quadrics: Vec::new(),
        }
    }

    /// This frame's state of `enc`, into the allocations already held (`quadrics`: with the
    /// coarse nodes' quadrics).
    fn fill(&mut self, frame: usize, delta: FrameDelta, enc: &Encoder, intra: bool, quadrics: bool) {
        let h = enc.hierarchy();
        self.frame = frame;
        self.delta = delta;
        self.key = intra.then(|| enc.keyframe());
        self.h.branching = h.branching;
        self.h.level_sizes.clone_from(&h.level_sizes);
        self.h.offsets.clone_from(&h.offsets);
        self.h.parent.resize_with(h.parent.len(), Vec::new);
        for (to, from) in self.h.parent.iter_mut().zip(&h.parent) {
            to.clone_from(from);
        }
        self.positions.clear();
        self.positions.extend_from_slice(enc.node_positions());
        self.quadrics.clear();
        if quadrics {
            let n0 = h.level_sizes.first().copied().unwrap_or(0) as usize;
            self.quadrics.extend_from_slice(enc.nodes().quadrics.get(n0..).unwrap_or_default());
        }
    }
}

/// Frames reclustered ahead of the coding thread at most: enough to ride out a slow frame
/// on either side, few enough that their hierarchies and positions stay small beside the input.
const AHEAD: usize = 4;

/// Encodes a sequence, asking `progress(f)` after each frame whether to go on: a
/// [`ControlFlow::Break`] stops the work at once with [`ContainerError::Cancelled`] (a
/// server's cancelled job), and nothing is returned.
pub fn encode_until(
    seq: &Sequence,
    opts: &EncodeOptions,
    progress: impl FnMut(usize) -> ControlFlow<()>,
) -> Result<Vec<u8>, ContainerError> {
    encode_sequence(seq, opts, progress, false).map(|(bytes, _)| bytes)
}

/// [`encode_until`], with what the encoder found about skinning's prediction.
pub fn encode_with_report(
    seq: &Sequence,
    opts: &EncodeOptions,
    progress: impl FnMut(usize) -> ControlFlow<()>,
) -> Result<(Vec<u8>, EncodeReport), ContainerError> {
    encode_sequence(seq, opts, progress, true)
}

/// [`encode_with_report`], its report's `plain_bits` exact or not (`exact`; the bytes are the
/// same either way).
fn encode_sequence(
    seq: &Sequence,
    opts: &EncodeOptions,
    progress: impl FnMut(usize) -> ControlFlow<()>,
    exact: bool,
) -> Result<(Vec<u8>, EncodeReport), ContainerError> {
    seq.validate()?;
    let (lo, hi) = seq.bounds().ok_or_else(|| ContainerError::Options("empty sequence".into()))?;
    quantization_step(opts, lo, hi)?;
    encode_frames(seq, seq.frame_count(), seq.frames.iter(), || Ok((lo, hi)), opts, (progress, exact))
}

/// Encodes a sequence whose frames after the first are still to be read: `head` holds frame 0
/// (with the triangles, appearance, skin and every frame's name) and `rest` reads frames 1..
/// (`frame_count` in all), each as it is asked for. `rest` runs on a thread of its own, ahead
/// of the encoding, so reading (OBJ parsing) overlaps the hierarchy build and the
/// reclustering, and each frame is dropped once it is reclustered. The bytes are those
/// [`encode_until`] writes for the whole sequence.
///
/// What is still held: the frames read but not yet reclustered. The quantization grid is the
/// bounding box of every frame (the header's), so no position is coded before the last frame
/// is read; reading must finish first, and it is faster than reclustering.
///
/// With base poses other than the first frame, the base hierarchy needs every frame: `rest` is
/// read whole first.
pub fn encode_stream<E: Send>(
    head: &Sequence,
    frame_count: usize,
    rest: impl Iterator<Item = Result<Vec<Vec3>, E>> + Send,
    opts: &EncodeOptions,
    progress: impl FnMut(usize) -> ControlFlow<()>,
) -> Result<Vec<u8>, StreamError<E>> {
    if opts.base.poses != PoseSet::FirstFrame || head.frames.len() != 1 {
        let mut seq = head.clone();
        for frame in rest {
            seq.frames.push(frame.map_err(StreamError::Input)?);
        }
        return encode_until(&seq, opts, progress).map_err(StreamError::Encode);
    }
    head.validate().map_err(|e| StreamError::Encode(e.into()))?;
    let (lo, hi) = head.bounds().ok_or_else(|| StreamError::Encode(ContainerError::Options("empty sequence".into())))?;
    // An option out of range is refused before any work, as the whole sequence's would be.
    quantization_step(opts, lo, hi).map_err(StreamError::Encode)?;
    let n = head.vertex_count();
    let (to_encoder, frames) = std::sync::mpsc::channel::<Vec<Vec3>>();
    let (to_coder, bounds) = std::sync::mpsc::sync_channel::<Result<(Vec3, Vec3), ContainerError>>(1);
    let input_error = std::sync::Mutex::new(None);
    let out = std::thread::scope(|scope| {
        let input_error = &input_error;
        scope.spawn(move || {
            let mut bb = (lo, hi);
            for (f, frame) in (1..).zip(rest) {
                let bad = match frame {
                    Ok(p) => match check_frame(head, f, n, &p) {
                        Ok(()) => {
                            if let Some((a, b)) = pmcodec_mesh::bounds_of(&p) {
                                bb = (bb.0.min(a), bb.1.max(b));
                            }
                            // The encoder stops taking frames only once it failed: its error wins.
                            if to_encoder.send(p).is_err() {
                                return;
                            }
                            continue;
                        }
                        Err(e) => e,
                    },
                    Err(input) => {
                        if let Ok(mut slot) = input_error.lock() {
                            *slot = Some(input);
                        }
                        ContainerError::Options("the input stopped".into())
                    }
                };
                let _ = to_coder.send(Err(bad));
                return;
            }
            let _ = to_coder.send(Ok(bb));
        });
        let first = std::borrow::Cow::Borrowed(head.frames[0].as_slice());
        let all = std::iter::once(first).chain(frames.into_iter().map(std::borrow::Cow::Owned));
        encode_frames(head, frame_count, all, move || bounds.recv().unwrap_or(Err(ContainerError::Cancelled)), opts, (progress, false))
            .map(|(bytes, _)| bytes)
    });
    match input_error.into_inner().ok().flatten() {
        Some(e) => Err(StreamError::Input(e)),
        None => out.map_err(StreamError::Encode),
    }
}

/// Frames the reclustering runs ahead of the coding side at most (so at most these many
/// reclustered frames' hierarchies and positions are held besides the one being made).
pub const FRAMES_AHEAD: usize = AHEAD;

/// What [`encode_stream`] can fail on: reading the input, or encoding it.
#[derive(Debug, thiserror::Error)]
pub enum StreamError<E> {
    /// The frame source failed; the encode stopped and wrote nothing.
    #[error("reading the input: {0}")]
    Input(E),
    /// The encoder failed (invalid input, options, or cancellation).
    #[error(transparent)]
    Encode(ContainerError),
}

/// The work of [`encode_until`] and [`encode_stream`]: `head` gives frame 0 and what is not
/// per frame, `frames` every frame in order (`frame_count` of them; fewer when the input
/// stopped, which `bounds` then reports), `bounds` the bounding box of them all, asked for by
/// the coding side before it codes anything.
///
/// Two threads: this one reclusters frame after frame (each frame's hierarchy depends on the
/// one before, so this is the sequential spine of the work), and a second one codes each
/// reclustered frame into chunks (positions, swaps, corners, keyframes) and compresses them,
/// a few frames behind. The bytes are the same as coding each frame right after its
/// reclustering: the coding side reads only what the frame's [`Reclustered`] carries.
fn encode_frames<F: AsRef<[Vec3]>>(
    head: &Sequence,
    frame_count: usize,
    frames: impl Iterator<Item = F>,
    bounds: impl FnOnce() -> Result<(Vec3, Vec3), ContainerError> + Send,
    opts: &EncodeOptions,
    // `exact`: whether the report's `plain_bits` must be exact (see [`EncodeReport`]).
    (mut progress, exact): (impl FnMut(usize) -> ControlFlow<()>, bool),
) -> Result<(Vec<u8>, EncodeReport), ContainerError> {
    let topo = FineTopology::new(head.vertex_count() as u32, &head.triangles);
    let q = base_quadrics(head, &topo, &opts.base);
    let base = build(&topo, &q, &opts.build)?;
    // Grids held under each level's own error serve an error bound; a file quantized to a
    // bit count keeps the grids its quantization gives (12-bit fitted horse: finer grids cost
    // 9% of the file, 5.55 -> 6.46 position bits per vertex per frame).
    let level_error = match opts.quantization {
        QuantizationChoice::MaxError(_) => level_errors(head, &topo, &base, opts),
        QuantizationChoice::Bits(_) => Vec::new(),
    };
    let mut enc = Encoder::new(base, topo, head.triangles.clone(), opts.recluster.clone());
    let level_sizes = enc.hierarchy().level_sizes.clone();
    // Each level's corners before the frame: what a reader stopping there holds, against which
    // corner updates are coded. The coding side keeps them by applying each frame's updates,
    // as a reader does (every corner that changes on a live triangle is in the updates).
    let held_corners: Vec<Vec<[u32; 3]>> = (0..enc.hierarchy().levels()).map(|j| enc.corners_at(j).to_vec()).collect();
    if opts.derived_topology == DerivedTopology::Always {
        // No band sends faces or corner updates (see `code_frames`): the reclustering thread,
        // the longer of the two, need not follow them.
        enc.stop_corners();
    }
    let first = Reclustered::new(&enc);
    let quadrics = opts.surface_grid || (head.skin.is_some() && opts.skin.is_some() && opts.skinned_coarse.is_some());
    // Appearance is the same in every frame: its tables cover the pairs every frame's
    // hierarchy shows, so each frame's is observed here, right after its reclustering (the
    // coding side was the longer of the two threads by about this much on a 34,102-vertex
    // character), and they are written once all frames are seen, after the triangles.
    let mut looks = head.appearance.as_ref().map(|a| crate::appearance::builder(head, a, level_sizes.len()));
    let looks_info = looks.as_ref().map(|l| l.info().clone());
    // Set once the work is cancelled: the coding side stops at its next frame rather than
    // coding what was reclustered ahead of it.
    let stop = std::sync::atomic::AtomicBool::new(false);
    let stop = &stop;
    std::thread::scope(|scope| {
        let (to_coder, reclustered) = std::sync::mpsc::sync_channel::<Reclustered>(AHEAD);
        let (recycle, recycled) = std::sync::mpsc::channel::<Reclustered>();
        let coder = scope.spawn(move || -> Result<(Header, Chunks, EncodeReport), ContainerError> {
            let (lo, hi) = bounds()?;
            let step = quantization_step(opts, lo, hi)?;
            let mut header = header(head, frame_count, opts, (lo, hi), step, level_sizes);
            header.appearance = looks_info;
            code_frames(head, opts, header, held_corners, (lo, step, &level_error, exact), (reclustered, recycle, stop))
        });
        let mut spare = Some(first);
        let mut cancelled = false;
        let every = if head.skin.is_some() && opts.skin.is_some() { opts.skinned_recluster_every.max(1) as usize } else { 1 };
        let budget = opts.recluster.max_swaps_per_frame;
        // The hierarchy last seen by the appearance tables, and how many frames showed it.
        let mut same_clusters: Option<(Vec<Vec<u32>>, u32)> = None;
        for (f, frame) in frames.enumerate() {
            if every > 1 {
                // A swap budget of 0 skips the swap search; node positions still follow the frame.
                enc.recluster_options_mut().max_swaps_per_frame = if f % every == 0 { budget } else { 0 };
            }
            let (delta, _) = enc.encode_frame(frame.as_ref());
            drop(frame);
            if let Some(l) = looks.as_mut() {
                match same_clusters.as_mut() {
                    // No swap: the clusters of the frame before, counted once more and observed
                    // once when they change (a skinned character reclustered every few frames,
                    // or never, spent 9% of its encode observing the same hierarchy again).
                    Some((_, times)) if delta.swaps.is_empty() => *times += 1,
                    _ => {
                        if let Some((parent, times)) = same_clusters.take() {
                            l.observe_times(&parent, times);
                        }
                        same_clusters = Some((enc.hierarchy().parent.clone(), 1));
                    }
                }
            }
            let mut r = match spare.take().or_else(|| recycled.try_recv().ok()) {
                Some(r) => r,
                None => Reclustered::new(&enc),
            };
            r.fill(f, delta, &enc, is_keyframe(opts, f), quadrics);
            // A closed channel means the coding side stopped on an error, which join reports.
            if to_coder.send(r).is_err() {
                break;
            }
            if progress(f).is_break() {
                cancelled = true;
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                break;
            }
        }
        drop(to_coder);
        if let (Some(l), Some((parent, times))) = (looks.as_mut(), same_clusters.take()) {
            l.observe_times(&parent, times);
        }
        let coded = match coder.join() {
            Ok(r) => r,
            Err(panic) => std::panic::resume_unwind(panic),
        };
        if cancelled {
            return Err(ContainerError::Cancelled);
        }
        let (header, mut chunks, report) = coded?;
        if let Some(l) = looks {
            put_appearance(&header, &mut chunks, l)?;
        }
        Ok((assemble(&header, chunks)?, report))
    })
}

/// Puts the appearance chunks `looks` observed in after the Triangles chunk.
fn put_appearance(header: &Header, chunks: &mut Chunks, looks: crate::appearance::tables::TableBuilder) -> Result<(), ContainerError> {
    // Every client reads the triangles and frame 0's Key chunks below its level where every
    // band above 0 derives its faces somewhere (`derive::reads`).
    let derived = |b: usize| chunks.0.iter().any(|(e, _)| e.band as usize == b && crate::derive::entry_is_derived(e));
    let triangles_read = (1..header.levels()).all(derived);
    let bind = bind_positions(header, chunks)?;
    let mut after = chunks.0.split_off(1);
    for (kind, band, raw) in crate::appearance::chunks(looks, triangles_read, bind.as_deref())? {
        chunks.push(kind, 0, band, raw)?;
    }
    chunks.0.append(&mut after);
    Ok(())
}

/// A skinned file's bind positions of the level-0 nodes, read back from its Bind chunk of band
/// 0 as a decoder reads them (band 0's texture coordinates may be predicted from them).
fn bind_positions(header: &Header, chunks: &Chunks) -> Result<Option<Vec<[i64; 3]>>, ContainerError> {
    let (Some(skin), Some(&count)) = (&header.skin, header.level_sizes.first()) else { return Ok(None) };
    let Some((e, stored)) = chunks.0.iter().find(|(e, _)| e.kind == ChunkKind::Bind && e.frame == 0 && e.band == 0) else {
        return Ok(None);
    };
    let raw = if chunks.1 & crate::format::FLAG_STORED != 0 && e.stored_len == e.raw_len {
        stored.clone()
    } else {
        zstd::bulk::decompress(stored, e.raw_len as usize).map_err(|err| ContainerError::Io(format!("zstd: {err}")))?
    };
    let nodes = crate::skin::read_binds(&raw, "band 0 bind", count, skin.palette_len)?;
    Ok(Some(nodes.iter().map(|n| n.bind).collect()))
}

/// Whether frame `f` is a keyframe under `opts` (as [`Header::is_keyframe`] says it).
fn is_keyframe(opts: &EncodeOptions, f: usize) -> bool {
    f == 0 || (opts.keyframe_interval > 0 && (f as u64).is_multiple_of(opts.keyframe_interval as u64))
}

/// How coarse a band's grid may be against its level's own error: a grid of step `s` adds
/// an error of RMS `s / sqrt(12)` along the surface normal, and the level's own error (sampled
/// surface RMS about 0.65 of the quadric RMS of [`level_errors`], measured on horse, cat and the
/// waving cloth) absorbs it in quadrature: `s` at most the quadric RMS keeps the grid's share
/// under about 0.45 of the level's error. The default levels of horse, samba and cat at the
/// default error bound keep the grids of [`coarse_shift`] (their files are unchanged); the
/// waving cloth's two finest coarse levels get finer ones. Only under an error bound
/// (`QuantizationChoice::MaxError`, the default): a bit count keeps its grids.
const GRID_OF_LEVEL_ERROR: f64 = 1.0;

/// Frame 0's simplification error of each level of `base`, as one length (see
/// [`pmcodec_hierarchy::NodeState::level_rms_errors`]), from frame 0's own quadrics.
fn level_errors(head: &Sequence, topo: &FineTopology, base: &Hierarchy, opts: &EncodeOptions) -> Vec<f64> {
    let Some(first) = head.frames.first() else { return Vec::new() };
    let mut q = Vec::new();
    pmcodec_hierarchy::quadric::vertex_quadrics(first, &head.triangles, &topo.boundary, &opts.recluster.quadric, &mut q);
    pmcodec_hierarchy::NodeState::compute(base, &q, first).level_rms_errors(base)
}

/// Band `j`'s residual step: [`coarse_shift`]'s, made finer until the grid is at most
/// [`GRID_OF_LEVEL_ERROR`] times the level's own error. On a smooth, finely tessellated mesh
/// a level's error falls below the grid the level's size alone suggests (the waving cloth's
/// 25% level: 0.0096% of the diagonal, and its 2-quanta grid made frame 0's cut 1.20x plain
/// QEM's where 1-quantum positions give 1.05x). The shift is stored in each Positions chunk,
/// so readers need nothing new.
fn band_shift(header: &Header, j: usize, grid: Option<u32>, level_error: Option<f64>) -> u32 {
    let mut s = coarse_shift(header, j, grid);
    if let Some(e) = level_error {
        let step = header.quantization.step as f64;
        while s > 0 && ((1u64 << s) as f64) * step > GRID_OF_LEVEL_ERROR * e {
            s -= 1;
        }
    }
    s
}

/// Leaves the faces and corner updates of the bands `policy` derives to their readers
/// (proto/container.md, "Faces", coding 2).
fn derive_bands(chunks: &mut Chunks, interval: u32, policy: DerivedTopology) -> Result<(), ContainerError> {
    let flags = chunks.1;
    let keyframe_before = |f: u32| if interval == 0 { 0 } else { f - f % interval };
    let store = |raw: &[u8]| crate::format::store_chunk(raw, ZSTD_LEVEL, flags).map_err(|e| ContainerError::Io(format!("zstd: {e}")));
    crate::derive::choose(&mut chunks.0, policy, keyframe_before, crate::format::sparse_kind(ChunkKind::Corners, flags), store)
}

/// The kind of the pose chunks of the palette coding `coding`.
fn pose_kind(coding: PaletteCoding) -> ChunkKind {
    match coding {
        PaletteCoding::Joints | PaletteCoding::JointsPlain => ChunkKind::Joints,
        PaletteCoding::Palette => ChunkKind::Palette,
    }
}

/// Band j's pose chunk (carrying palette `entries`) in the coding the options ask for (its kind
/// [`pose_kind`]), against the palettes the decoder holds.
fn pose_chunk(
    coding: PaletteCoding,
    mask: u64,
    (bands, j): (&[Vec<u32>], usize),
    palette: &JointsFrame,
    (held, intra): (&SkinState, bool),
) -> Vec<u8> {
    let entries: &[u32] = bands.get(j).map(Vec::as_slice).unwrap_or_default();
    match coding {
        PaletteCoding::Joints => write_joints_best(mask, (bands, j), palette, &held.joint_prediction(intra)),
        PaletteCoding::JointsPlain => write_joints(mask, entries, palette, &held.joint_prediction(intra)),
        PaletteCoding::Palette => write_palette(mask, entries, &palette.palette, held.prediction(intra)),
    }
}

/// Writes a file through a temporary file in the same folder and a rename, so a failed or
/// killed write never leaves a half file under the final name.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ContainerError> {
    pmcodec_mesh::write::write_atomic(path, bytes).map_err(ContainerError::from)
}
