//! The coding side of the encoder ([`code_frames`]): every reclustered frame, in order, into
//! chunks, on two threads. The coding thread makes each frame's predictions and residuals
//! (each frame's from the one before, so this is sequential); a chunk-writing thread makes the
//! payloads nothing later depends on and compresses the chunks, a few frames behind.

use super::*;

/// A chunk the coding side of [`code_frames`] hands to its chunk-writing thread: its place,
/// and its payload or what makes it.
struct Piece<'a> {
    kind: ChunkKind,
    frame: u32,
    band: u32,
    payload: Payload<'a>,
}

/// A [`Piece`]'s payload: made already, a band's residuals (in units of `2^shift` quanta) to
/// write in their shortest coding, or a payload to make. What the writing thread makes is
/// what no later coding depends on: the payload codings compared (each sized by compressing
/// it at the file's zstd level, or by its length for the pose chunks, from a copy of the
/// palettes the decoder holds before the frame) and the compression of what is stored.
enum Payload<'a> {
    Raw(Vec<u8>),
    Positions(u32, Vec<[i32; 3]>),
    Make(Box<dyn FnOnce() -> Vec<u8> + Send + 'a>),
}

impl<'a> Piece<'a> {
    fn raw(kind: ChunkKind, frame: usize, band: usize, raw: Vec<u8>) -> Self {
        Piece { kind, frame: frame as u32, band: band as u32, payload: Payload::Raw(raw) }
    }

    fn make(kind: ChunkKind, frame: usize, band: usize, make: impl FnOnce() -> Vec<u8> + Send + 'a) -> Self {
        Piece { kind, frame: frame as u32, band: band as u32, payload: Payload::Make(Box::new(make)) }
    }
}

/// The chunk-writing thread of [`code_frames`]: every frame's pieces, in order, made and
/// compressed into chunks, until `stop` is set.
fn write_pieces(frames: std::sync::mpsc::Receiver<Vec<Piece>>, flags: u16, stop: &AtomicBool) -> Result<Chunks, ContainerError> {
    let mut chunks = Chunks(Vec::new(), flags);
    for frame in frames {
        if stop.load(Ordering::Relaxed) {
            return Err(ContainerError::Cancelled);
        }
        for p in frame {
            let raw = match p.payload {
                Payload::Raw(raw) => raw,
                Payload::Positions(shift, residuals) => payload::write_positions(shift, &residuals),
                Payload::Make(make) => make(),
            };
            chunks.push(p.kind, p.frame, p.band, raw)?;
        }
    }
    Ok(chunks)
}

/// The coding side of [`encode_until`]: every reclustered frame, in order, into chunks (the
/// appearance chunks, observed on the reclustering side, are put in after). Returns early
/// (dropping `frames`, which stops the reclustering) on an error.
///
/// Two threads: this one codes the frames (the predictions and residuals, each frame's from
/// the one before), and a second one makes the payloads nothing later depends on and
/// compresses the chunks ([`write_pieces`]), a few frames behind; the chunks are the same,
/// in the same order. On the 34,102-vertex character of scripts/benchmarks.py the coding
/// thread was the longest of the encoder's two, and these were two fifths of its work.
pub(super) fn code_frames(
    seq: &Sequence,
    opts: &EncodeOptions,
    header: Header,
    held_corners: Vec<Vec<[u32; 3]>>,
    grid: (Vec3, f32, &[f64], bool),
    // The reclustered frames, where to send them back, and whether the work was cancelled.
    (frames, recycle, stop): (std::sync::mpsc::Receiver<Reclustered>, std::sync::mpsc::Sender<Reclustered>, &AtomicBool),
) -> Result<(Header, Chunks, EncodeReport), ContainerError> {
    let flags = opts.chunk_flags & crate::format::KNOWN_FLAGS;
    let (to_writer, pieces) = std::sync::mpsc::sync_channel::<Vec<Piece>>(AHEAD);
    let (coded, written) = std::thread::scope(|scope| {
        let writer = scope.spawn(move || write_pieces(pieces, flags, stop));
        let coded = code_pieces(seq, opts, header, held_corners, grid, (frames, recycle, stop), to_writer);
        let written = match writer.join() {
            Ok(r) => r,
            Err(panic) => std::panic::resume_unwind(panic),
        };
        (coded, written)
    });
    // The writer's error first: the coding side stops with `Cancelled` once it cannot send.
    let mut chunks = written?;
    let (header, report) = coded?;
    derive_bands(&mut chunks, header.keyframe_interval, opts.derived_topology)?;
    Ok((header, chunks, report))
}

/// [`code_frames`]' coding thread: sends each frame's pieces to `to_writer`.
fn code_pieces<'a>(
    seq: &'a Sequence,
    opts: &EncodeOptions,
    mut header: Header,
    mut held_corners: Vec<Vec<[u32; 3]>>,
    // The grid's origin and step, each level's frame-0 error (see [`band_shift`]), and
    // whether the report's `plain_bits` must be exact.
    (lo, step, level_error, exact): (Vec3, f32, &[f64], bool),
    (frames, recycle, stop): (std::sync::mpsc::Receiver<Reclustered>, std::sync::mpsc::Sender<Reclustered>, &AtomicBool),
    to_writer: std::sync::mpsc::SyncSender<Vec<Piece<'a>>>,
) -> Result<(Header, EncodeReport), ContainerError> {
    let levels = header.levels();
    let n = seq.vertex_count() as u32;
    let triangles = &seq.triangles;
    let send = |pieces: Vec<Piece<'a>>| to_writer.send(pieces).map_err(|_| ContainerError::Cancelled);
    send(vec![Piece::make(ChunkKind::Triangles, 0, 0, move || payload::write_triangles_best(triangles, n))])?;
    let total = header.level_sizes.iter().map(|&n| n as usize).sum();
    let mut coder = PositionCoder::new(
        opts.motion,
        LowerNeighbours::new(seq.vertex_count(), &seq.triangles, opts.order),
        (0..levels).map(|j| band_shift(&header, j, opts.coarse_grid, level_error.get(j).copied())).collect(),
        total,
    );
    coder.exact_plain = exact;
    let skin_input = seq.skin.as_ref().zip(opts.skin);
    let mut skin: Option<SkinFit> = None;
    // The palette entries each band's Joints chunk carries.
    let mut bands: std::sync::Arc<Vec<Vec<u32>>> = std::sync::Arc::default();
    // The palettes the decoder holds (the previous frame's and the one before), and this frame's.
    let (mut held, mut palette) = (SkinState::default(), JointsFrame::default());
    let inv = 1.0 / step as f64;
    let mut corners: Vec<(u32, [u32; 3])> = Vec::new();
    // Frame 0's parent maps, which later keyframes' Key chunks may code their changes from.
    let mut first_keys: Vec<std::sync::Arc<Vec<u32>>> = vec![std::sync::Arc::default(); levels];
    let sizes = header.level_sizes.clone();
    for mut r in frames {
        if stop.load(Ordering::Relaxed) {
            return Err(ContainerError::Cancelled);
        }
        let mut out = Vec::new();
        let key = r.key.take();
        let (f, delta, h, positions) = (r.frame, &r.delta, &r.h, &r.positions);
        if let (0, Some((input, placement))) = (f, skin_input) {
            // The skeleton once, before the first frame, top band first.
            // Coarse levels keep fewer joints only where coarse nodes may sit at their skinned
            // positions (the skeleton's level of detail, `skin::skeleton`).
            let keep = opts.skinned_coarse.map_or(0.0, |c| c.joints);
            let fit = fit_skin(input, h, positions, (lo, step), (placement, keep))?;
            let offsets = &h.offsets;
            for j in (0..levels).rev() {
                out.push(Piece::raw(ChunkKind::Bind, 0, j, write_binds(&fit.nodes[offsets[j] as usize..offsets[j + 1] as usize])));
            }
            header.skin = Some(fit.header.clone());
            bands = std::sync::Arc::new(band_entries(&fit.nodes, offsets, 0, fit.header.palette_len));
            skin = Some(fit);
        }
        let intra = header.is_keyframe(f as u32);
        if let Some(fit) = &skin {
            palette = frame_joints(fit, opts.palette_coding, &header, f, (&held, intra), &bands)?;
        }
        let truth = |g: usize| {
            let p = positions[g] - lo;
            [p.x as f64 * inv, p.y as f64 * inv, p.z as f64 * inv]
        };
        // First what only a client stopping at band j reads (faces on keyframes, corner
        // updates), finest band first; then the bands every client from there down reads, top
        // first. So a full-resolution client's part of a frame is one contiguous span, and a
        // level-j client's span holds only the (smaller) faces and corners of coarser bands.
        // Bands every one of which `derive_bands` will derive need not be coded first.
        let mut key_bands = key.map(|k| k.bands);
        faces_and_corners(&mut out, (f, delta, h), key_bands.as_deref_mut(), &mut held_corners, opts.derived_topology, &mut corners);
        let n0 = h.level_sizes[0] as usize;
        let coarse = opts.skinned_coarse.map(|t| CoarseQuadrics::new(&r.quadrics, n0, (lo, step), t));
        let skinning = skin.as_ref().map(|s| Skinning {
            nodes: &s.nodes,
            palette: &palette.palette,
            previous: &held.palette,
            coarse: coarse.as_ref(),
        });
        // The frame's pose goes before its bands, once they say which bands skinning predicts.
        let mut band_pieces = Vec::new();
        let mut mask = 0u64;
        for j in (0..levels).rev() {
            if let Some(k) = key_bands.as_mut() {
                let parent = std::mem::take(&mut k[j].parent);
                let limit = sizes.get(j + 1).copied().unwrap_or(0);
                let first = (f != 0).then(|| first_keys[j].clone());
                if f == 0 {
                    first_keys[j] = std::sync::Arc::new(parent.clone());
                }
                band_pieces.push(Piece::make(ChunkKind::Key, f, j, move || {
                    payload::write_key_best(&parent, limit, first.as_deref().map(Vec::as_slice))
                }));
            }
            let (moves, nodes, parents) = (net_moves(delta, j), sizes[j], sizes.get(j + 1).copied().unwrap_or(0));
            band_pieces.push(Piece::make(ChunkKind::Delta, f, j, move || payload::write_delta_best(&moves, nodes, parents)));
            let surface = opts.surface_grid.then_some(Surface { quadrics: &r.quadrics, first: n0, lo: lo.as_dvec3(), step: step as f64 });
            let (shift, residuals, skinned) = coder.band_residuals(j, intra, h, truth, (skinning, surface));
            mask |= (skinned as u64) << j;
            band_pieces.push(Piece {
                kind: ChunkKind::Positions,
                frame: f as u32,
                band: j as u32,
                payload: Payload::Positions(shift, residuals),
            });
        }
        if skin.is_some() {
            pose_pieces(&mut out, (f, intra, mask, levels), opts.palette_coding, &held, &palette, &bands);
            let JointsFrame { palette, rig, links, .. } = std::mem::take(&mut palette);
            held.advance_rig(palette, (rig, links), intra, mask);
        }
        out.append(&mut band_pieces);
        send(out)?;
        coder.next_frame();
        // The reclustering side may have finished: then there is nothing to refill.
        let _ = recycle.send(r);
    }
    Ok((header, std::mem::take(&mut coder.report)))
}

/// A frame's Faces (keyframes) and Corners pieces of bands 1 and up, finest first, and each
/// band's held corners brought up to date; `corners` is scratch. Where every band is derived
/// (`DerivedTopology::Always`) their payloads are the empty ones `derive_bands` rewrites.
fn faces_and_corners<'a>(
    out: &mut Vec<Piece<'a>>,
    (f, delta, h): (usize, &FrameDelta, &Hierarchy),
    mut key_bands: Option<&mut [pmcodec_hierarchy::progressive::KeyBand]>,
    held_corners: &mut [Vec<[u32; 3]>],
    policy: DerivedTopology,
    corners: &mut Vec<(u32, [u32; 3])>,
) {
    let all_derived = policy == DerivedTopology::Always;
    for (j, held) in held_corners.iter_mut().enumerate().skip(1) {
        if let Some(k) = key_bands.as_deref_mut() {
            if all_derived {
                out.push(Piece::raw(ChunkKind::Faces, f, j, vec![0]));
            } else {
                let (faces, size, triangles) = (std::mem::take(&mut k[j].faces), h.level_sizes[j], held.len() as u32);
                out.push(Piece::make(ChunkKind::Faces, f, j, move || payload::write_faces_best(&faces, size, triangles)));
            }
        }
        corners.clear();
        corners.extend(delta.corners.iter().filter(|c| c.level as usize == j).map(|c| (c.t, c.corners)));
        let raw = if all_derived { vec![0] } else { topology::corners_chunk(h, j, corners, held) };
        out.push(Piece::raw(ChunkKind::Corners, f, j, raw));
        for &(t, c) in corners.iter() {
            held[t as usize] = c;
        }
    }
}

/// A frame's pose pieces (Joints, Palette or Pose chunks by `coding`), top band first as the
/// bands themselves, made on the writing thread from a copy of what the decoder holds before
/// this frame (its palettes, rigid parameters and links) and the frame's palette.
fn pose_pieces(
    out: &mut Vec<Piece<'_>>,
    (f, intra, mask, levels): (usize, bool, u64, usize),
    coding: PaletteCoding,
    held: &SkinState,
    palette: &JointsFrame,
    bands: &std::sync::Arc<Vec<Vec<u32>>>,
) {
    let before = SkinState {
        palette: held.palette.clone(),
        previous: held.previous.clone(),
        rig: held.rig.clone(),
        rig_before: held.rig_before.clone(),
        links: held.links.clone(),
        ..Default::default()
    };
    let pose = std::sync::Arc::new((before, palette.clone(), std::sync::Arc::clone(bands)));
    let kind = pose_kind(coding);
    for j in (0..levels).rev().filter(|&j| has_palette_chunk(bands, j)) {
        let pose = std::sync::Arc::clone(&pose);
        out.push(Piece::make(kind, f, j, move || {
            let (held, palette, bands) = &*pose;
            pose_chunk(coding, mask, (bands, j), palette, (held, intra))
        }));
    }
}

/// Frame `f`'s joints of skin `fit` against the palettes the decoder holds (`held`; `intra`
/// on keyframes): linked through the keyframe interval for the Joints chunk, whose links reach
/// the interval's end, else each frame alone.
fn frame_joints(
    fit: &SkinFit,
    coding: PaletteCoding,
    header: &Header,
    f: usize,
    (held, intra): (&SkinState, bool),
    bands: &[Vec<u32>],
) -> Result<JointsFrame, ContainerError> {
    // The header's count: a streamed sequence's head holds frame 0 only.
    let frames_total = header.frame_count as usize;
    match coding {
        PaletteCoding::Joints => {
            let next = (f / header.keyframe_interval.max(1) as usize + 1) * header.keyframe_interval as usize;
            let until = if header.keyframe_interval == 0 { frames_total } else { next.min(frames_total) };
            fit.joints_linked(f, held, intra, bands, until)
        }
        _ => fit.joints(f, held, intra),
    }
}
