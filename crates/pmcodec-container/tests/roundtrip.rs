//! Round trips on real sequences and generated fixtures: the decoded hierarchy equals the
//! encoder's, positions are within the stated bound, keyframe seeks agree with playback, and a
//! level-limited reader fetches only its bands.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_container::*;
use pmcodec_hierarchy::base::base_quadrics;
use pmcodec_hierarchy::progressive::Encoder;
use pmcodec_hierarchy::{FineTopology, build};
use pmcodec_mesh::Sequence;
use std::path::PathBuf;

fn data(name: &str, frames: usize) -> Option<Sequence> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data")).join(name);
    if !dir.exists() {
        panic!("{} is absent: these tests read the real meshes in ../shared/data beside the repository", dir.display());
    }
    let mut paths = pmcodec_mesh::obj::frame_paths(&dir).expect("frames");
    paths.truncate(frames);
    Some(pmcodec_mesh::obj::load_obj_files(&paths, 30.0).expect("load"))
}

/// Replays the encoder beside the decoder and compares every frame.
fn round_trip(seq: &Sequence, opts: &EncodeOptions) -> Vec<u8> {
    let bytes = encode(seq, opts, |_| {}).expect("encode");
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let h = reader.header();
    assert_eq!(h.frame_count as usize, seq.frame_count());
    let diag = {
        let (lo, hi) = seq.bounds().unwrap();
        (hi - lo).length()
    };
    let bound = match opts.quantization {
        QuantizationChoice::MaxError(e) => e as f32 * diag * 1.0001,
        QuantizationChoice::Bits(_) => h.quantization.step * 0.5 * 3f32.sqrt() * 1.0001,
    };
    // The encoder's own hierarchy, rebuilt the same way.
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let base = build(&topo, &base_quadrics(seq, &topo, &opts.base), &opts.build).unwrap();
    let mut enc = Encoder::new(base, topo, seq.triangles.clone(), opts.recluster.clone());
    let mut d = Decoder::new(reader.borrowed(), 0).unwrap();
    for (f, frame) in seq.frames.iter().enumerate() {
        enc.encode_frame(frame);
        d.seek(f as u32).unwrap();
        let r = d.replay().unwrap();
        assert_eq!(&r.h, enc.hierarchy(), "frame {f}: parent maps");
        assert_eq!(r.degeneration(), enc.degeneration(), "frame {f}: degenerate sets");
        let pos = d.positions();
        for (v, p) in frame.iter().enumerate() {
            assert!((pos[v] - *p).length() <= bound, "frame {f} vertex {v}: {} > {bound}", (pos[v] - *p).length());
        }
        // Coarser nodes sit on a grid of 2^shift quanta around their prediction; in a skinned
        // file, or at their skinned position within the cluster's reach (SkinnedCoarse).
        let skinned = h.skin.as_ref().and(opts.skinned_coarse);
        for (g, p) in pos.iter().enumerate().skip(seq.vertex_count()) {
            let (k, _) = enc.hierarchy().local(g as u32);
            let s = pmcodec_container::coarse_shift(h, k, opts.coarse_grid);
            let b = if s == 0 { bound } else { h.quantization.step * (1u32 << s) as f32 * 0.5 * 3f32.sqrt() * 1.0001 };
            let d = (*p - enc.node_positions()[g]).length();
            let reach = skinned.map_or(0.0, |t| {
                let area = enc.nodes().quadrics[g].area.max(0.0);
                let grid = t.cells * h.quantization.step as f64 * (1u64 << s) as f64;
                (t.reach * t.reach * area + grid * grid).sqrt() as f32 + h.quantization.step
            });
            assert!(d <= b.max(reach), "frame {f} node {g}: {d} from its optimal point (grid {b}, skinned reach {reach})");
        }
    }
    // Level 0 is the input, in input order.
    let m = d.mesh(CutTarget::Level(0)).unwrap();
    assert_eq!(m.triangles, seq.triangles);
    assert_eq!(m.positions.len(), seq.vertex_count());
    bytes
}

#[test]
fn horse_gallop_round_trips() {
    // Every frame of the sequence.
    let Some(seq) = data("horse-gallop", 48) else { return };
    assert_eq!(seq.frame_count(), 48);
    let bytes = round_trip(&seq, &EncodeOptions { keyframe_interval: 8, ..Default::default() });
    let reader = Reader::open(bytes.as_slice()).unwrap();
    verify(&reader).expect("verify");
    // Seeking to a frame from its keyframe equals playing up to it, and budget cuts agree.
    let mut played = Decoder::new(reader.borrowed(), 0).unwrap();
    for f in 0..=13 {
        played.seek(f).unwrap();
    }
    let mut sought = Decoder::new(reader.borrowed(), 0).unwrap();
    sought.seek(13).unwrap();
    assert_eq!(played.replay().unwrap().h, sought.replay().unwrap().h);
    assert_eq!(played.quantized(), sought.quantized());
    for budget in [500, 2000, 8000] {
        let a = played.mesh(CutTarget::Triangles(budget)).unwrap();
        let b = sought.mesh(CutTarget::Triangles(budget)).unwrap();
        assert_eq!(a, b, "budget {budget}");
        assert!(a.triangles.len() as u32 <= budget && a.triangles.len() as u32 > budget / 2, "{}", a.triangles.len());
        // The same cut as node triples: as many, each three distinct nodes.
        let nodes = played.cut_triangles(CutTarget::Triangles(budget)).unwrap();
        assert_eq!(nodes.len(), a.triangles.len(), "budget {budget}");
        assert!(nodes.iter().all(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]));
    }
}

/// Band 0's motions and orders: the decoder follows the encoder frame by frame (every vertex
/// within the bound, hierarchies equal) and seeking agrees with playing for each; on the
/// galloping horse the affine motions store clearly fewer position bits than the mean motion,
/// keyframe weights cost little against weights fitted every frame, and breadth-first order
/// saves bits over input order.
#[test]
fn band_0_motions_round_trip_and_save_bits() {
    let Some(seq) = data("horse-gallop", 20) else { return };
    let base = EncodeOptions { keyframe_interval: 8, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let mut bits = Vec::new();
    for (motion, order) in [
        (Motion::KeyframeAffine, VertexOrder::BreadthFirst),
        (Motion::KeyframeAffine, VertexOrder::Input),
        (Motion::Affine, VertexOrder::BreadthFirst),
        (Motion::Mean, VertexOrder::Input),
    ] {
        let bytes = round_trip(&seq, &EncodeOptions { motion, order, ..base.clone() });
        let reader = Reader::open(bytes.as_slice()).unwrap();
        assert_eq!((reader.header().motion, reader.header().order), (motion, order));
        // Band 0's bits: motions and orders are band 0's (coarser bands' grids follow their
        // levels' errors and would dilute the comparison).
        let band0 = summary(&reader).positions_bytes[0] as f64 * 8.0 / (seq.vertex_count() * seq.frame_count()) as f64;
        bits.push(band0);
        let mut played = Decoder::new(reader.borrowed(), 0).unwrap();
        for f in 0..=13 {
            played.seek(f).unwrap();
        }
        let mut sought = Decoder::new(reader.borrowed(), 0).unwrap();
        sought.seek(13).unwrap();
        assert_eq!(played.quantized(), sought.quantized(), "{motion:?} {order:?}");
    }
    let [keyed, keyed_input, affine, mean] = bits[..] else { unreachable!() };
    assert!(keyed < 0.85 * mean, "keyframe affine {keyed:.2} vs mean {mean:.2} bits/vertex/frame");
    assert!(keyed < 1.03 * affine, "keyframe affine {keyed:.2} vs affine {affine:.2} bits/vertex/frame");
    assert!(keyed < 0.98 * keyed_input, "breadth first {keyed:.2} vs input order {keyed_input:.2} bits/vertex/frame");
    if let Some(seq) = data("samba-60", 6) {
        round_trip(&seq, &EncodeOptions { keyframe_interval: 4, ..base.clone() });
        round_trip(&seq, &EncodeOptions { motion: Motion::Affine, keyframe_interval: 4, ..base });
    }
}

/// One decoder sent back and forth across keyframes (which reloads its replay in place, or
/// restores a kept keyframe state) agrees with a fresh decoder at every stop, at full
/// resolution and at level 1.
#[test]
fn seeking_back_and_forth_equals_fresh_decoding() {
    let Some(seq) = data("horse-gallop", 20) else { return };
    let bytes = encode(&seq, &EncodeOptions { keyframe_interval: 4, ..Default::default() }, |_| {}).unwrap();
    let reader = Reader::open(bytes.as_slice()).unwrap();
    for (level, keep) in [(0, 0), (1, 0), (0, 2), (1, 3)] {
        let mut d = Decoder::new(reader.borrowed(), level).unwrap();
        d.keep_keyframes(keep);
        // With kept keyframes, the later stops revisit keyframes 0, 8 and 16 (restored).
        for f in [17u32, 3, 9, 2, 19, 0, 8, 7, 12, 1, 18, 10, 3, 17] {
            d.seek(f).unwrap();
            let mut fresh = Decoder::new(reader.borrowed(), level).unwrap();
            fresh.seek(f).unwrap();
            let (a, b) = (d.replay().unwrap(), fresh.replay().unwrap());
            assert_eq!(a.h.parent[level..], b.h.parent[level..], "level {level} frame {f}");
            assert_eq!(a.degeneration(), b.degeneration(), "level {level} frame {f}");
            assert_eq!(d.quantized(), fresh.quantized(), "level {level} frame {f}");
            assert_eq!(
                d.mesh(CutTarget::Triangles(1500)).unwrap(),
                fresh.mesh(CutTarget::Triangles(1500)).unwrap(),
                "level {level} frame {f}"
            );
        }
    }
}

#[test]
fn samba_and_cat_round_trip() {
    if let Some(seq) = data("samba-60", 60) {
        assert_eq!(seq.frame_count(), 60);
        round_trip(&seq, &EncodeOptions { quantization: QuantizationChoice::Bits(12), ..Default::default() });
    }
    if let Some(seq) = data("samba-60", 6) {
        // Coarse nodes on a grid: residual shifts, coarse nodes within half a grid step.
        round_trip(
            &seq,
            &EncodeOptions { quantization: QuantizationChoice::Bits(12), keyframe_interval: 4, coarse_grid: Some(2), ..Default::default() },
        );
    }
    if let Some(seq) = data("cat-poses", 10) {
        assert_eq!(seq.frame_count(), 10);
        round_trip(&seq, &EncodeOptions { keyframe_interval: 0, ..Default::default() });
    }
}

/// Options for the small glTF models: a coarsest level of a few nodes, keyframes every 3.
fn gltf_options() -> EncodeOptions {
    EncodeOptions {
        build: pmcodec_hierarchy::BuildOptions { min_coarsest: 4, ..EncodeOptions::default().build },
        keyframe_interval: 3,
        ..Default::default()
    }
}

/// The first 8 frames of a glTF's first animation round trip.
fn gltf_round_trip(path: &std::path::Path) {
    let mut seq = pmcodec_mesh::gltf_input::load_gltf(path, &Default::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    seq.frames.truncate(8);
    let bytes = round_trip(&seq, &gltf_options());
    assert_eq!(Reader::open(bytes.as_slice()).unwrap().header().frame_count as usize, seq.frame_count(), "{}", path.display());
}

/// Every glTF in the data folder round trips: skinned (Fox), morph targets (Horse), both
/// (RobotExpressive, 19 primitives), and morph targets under Draco compression (the Parrot,
/// read directly: `draco_parrot_round_trips`).
#[test]
fn every_gltf_round_trips() {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf"));
    for name in ["Fox", "Horse", "RobotExpressive"] {
        let path = dir.join(format!("{name}.glb"));
        assert!(path.exists(), "{} is absent: these tests read the real meshes in ../shared/data beside the repository", path.display());
        gltf_round_trip(&path);
    }
}

/// The Draco-compressed Parrot round trips, read straight from its GLB.
#[test]
fn draco_parrot_round_trips() {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf/Parrot.glb"));
    assert!(path.exists(), "{} is absent: these tests read the real meshes in ../shared/data beside the repository", path.display());
    gltf_round_trip(&path);
}

/// Counts the bytes a reader fetches.
struct Counting<'a> {
    bytes: &'a [u8],
    fetched: std::cell::Cell<u64>,
}
impl ByteSource for Counting<'_> {
    fn len(&self) -> Result<u64, ContainerError> {
        Ok(self.bytes.len() as u64)
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        self.fetched.set(self.fetched.get() + len as u64);
        self.bytes.read_at(offset, len)
    }
}

/// A full-resolution client reads swaps and positions, never the faces and corners kept for
/// coarser clients (it derives degenerate sets and corners itself).
#[test]
fn full_resolution_decoding_skips_faces_and_corners() {
    // One keyframe (frame 0): playing through reads every other chunk once.
    let bytes = encode(&wave(6), &EncodeOptions::default(), |_| {}).unwrap();
    let src = Counting { bytes: &bytes, fetched: Default::default() };
    let reader = Reader::open(&src).unwrap();
    let mut d = Decoder::new(reader.borrowed(), 0).unwrap();
    for f in 0..6 {
        d.seek(f).unwrap();
    }
    let skipped: u64 =
        reader.index().chunks.iter().filter(|e| matches!(e.kind, ChunkKind::Faces | ChunkKind::Corners)).map(|e| e.stored_len as u64).sum();
    // Frame 0's swaps are in its keyframe already.
    let frame0_swaps: u64 =
        reader.index().chunks.iter().filter(|e| e.kind == ChunkKind::Delta && e.frame == 0).map(|e| e.stored_len as u64).sum();
    let chunks: u64 = reader.index().chunks.iter().map(|e| e.stored_len as u64).sum();
    assert!(skipped > 0);
    assert_eq!(src.fetched.get() - reader.data_start(), chunks - skipped - frame0_swaps);
}

#[test]
fn level_limited_decoding_reads_only_its_bands() {
    level_limited_decoding(DerivedTopology::Never);
    // Derived faces (proto/container.md, "Faces", coding 2): the same corners, and what the
    // client reads is what `Reader::reads` names (the Key and Delta chunks below it too).
    level_limited_decoding(DerivedTopology::Always);
}

fn level_limited_decoding(derived_topology: DerivedTopology) {
    let Some(seq) = data("horse-gallop", 10) else { return };
    let bytes = encode(&seq, &EncodeOptions { derived_topology, ..Default::default() }, |_| {}).unwrap();
    let full_reader = Reader::open(bytes.as_slice()).unwrap();
    let mut full = Decoder::new(full_reader.borrowed(), 0).unwrap();
    let src = Counting { bytes: &bytes, fetched: Default::default() };
    let reader = Reader::open(&src).unwrap();
    let level = 2;
    let mut part = Decoder::new(reader.borrowed(), level).unwrap();
    // The encoder's own level-2 corners, to check the faces and corner updates against.
    let opts = EncodeOptions::default();
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let base = build(&topo, &base_quadrics(&seq, &topo, &opts.base), &opts.build).unwrap();
    let mut enc = Encoder::new(base, topo, seq.triangles.clone(), opts.recluster.clone());
    let alive = |c: &[u32; 3]| c[0] != c[1] && c[1] != c[2] && c[0] != c[2];
    for f in 0..10 {
        enc.encode_frame(&seq.frames[f as usize]);
        full.seek(f).unwrap();
        part.seek(f).unwrap();
        let (a, b) = (full.replay().unwrap(), part.replay().unwrap());
        assert_eq!(&a.h.parent[level..], &b.h.parent[level..], "frame {f}");
        let off = a.h.offsets[level] as usize;
        assert_eq!(&full.quantized()[off..], &part.quantized()[off..], "frame {f}: positions above level {level}");
        // Every triangle alive at the level has the encoder's corners there, and no other is.
        let (mut shown, theirs) = (0, enc.corners_at(level));
        for (t, (mine, truth)) in b.corners().iter().zip(theirs).enumerate() {
            assert_eq!(alive(mine), alive(truth), "frame {f} triangle {t}");
            if alive(truth) {
                assert_eq!(mine, truth, "frame {f} triangle {t}");
                shown += 1;
            }
        }
        assert!(shown > 1000, "frame {f}: {shown} triangles alive at level {level}");
    }
    // Everything fetched: preamble, header, index and chunks of bands >= level only, and of
    // the faces and corners chunks only those of band `level`.
    let allowed: u64 =
        reader.data_start() + reader.index().chunks.iter().filter(|e| reader.reads(e, level)).map(|e| e.stored_len as u64).sum::<u64>();
    let derived = derived_topology == DerivedTopology::Always;
    assert_eq!(reader.derives(5, level), derived);
    assert!(
        derived || reader.index().chunks.iter().any(|e| e.kind == ChunkKind::Corners && e.band as usize > level),
        "the file has corner chunks a level-{level} client skips"
    );
    if !derived {
        assert!(reader.index().chunks.iter().all(|e| reader.reads(e, level) == e.kind.read_at(e.band as usize, level)));
    }
    assert!(src.fetched.get() <= allowed, "{} > {allowed}", src.fetched.get());
    // Deriving, it reads the input triangles and the parent maps below its level too (on ten
    // frames with one keyframe, a third of the file).
    let part_of = if derived { 2 } else { 4 };
    assert!(src.fetched.get() * part_of < bytes.len() as u64, "a level-{level} client read {} of {} bytes", src.fetched.get(), bytes.len());
    let m = part.mesh(CutTarget::Triangles(1000)).unwrap();
    assert!(!m.triangles.is_empty() && m.triangles.len() <= 1000);
}

fn wave(frames: usize) -> Sequence {
    let (w, h) = (12u32, 9u32);
    let mut seq = Sequence { frame_rate: 24.0, triangles: pmcodec_mesh::samples::grid_triangles(w, h), ..Default::default() };
    for f in 0..frames {
        seq.frames.push((0..w * h).map(|i| Vec3::new((i % w) as f32, (i / w) as f32, ((i % w) as f32 * 0.7 + f as f32).sin())).collect());
    }
    seq
}

#[test]
fn corruption_is_an_error_naming_the_region() {
    let bytes = encode(&wave(5), &EncodeOptions { keyframe_interval: 2, ..Default::default() }, |_| {}).unwrap();
    let reader = Reader::open(bytes.as_slice()).unwrap();
    let start = reader.data_start() as usize;
    // Chunks stored as they are may be a byte or two long: one long enough to damage inside.
    let some_chunk = *reader.index().chunks.iter().skip(5).find(|e| e.stored_len > 2).unwrap();
    let check = |bad: &[u8], expect: &str| {
        let err = match Reader::open(bad) {
            Err(e) => e.to_string(),
            Ok(r) => match verify(&r) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("corruption not detected ({expect})"),
            },
        };
        assert!(err.contains(expect), "{err} (expected {expect})");
    };
    let mut b = bytes.clone();
    b[0] ^= 1;
    check(&b, "magic");
    let mut b = bytes.clone();
    b[8] = 9;
    check(&b, "version 9");
    let mut b = bytes.clone();
    b[40] ^= 0x55;
    check(&b, "header");
    let mut b = bytes.clone();
    b[start - 3] ^= 0x55;
    check(&b, "index");
    let mut b = bytes.clone();
    b[start + some_chunk.offset as usize + 2] ^= 0x55;
    check(&b, &some_chunk.describe());
    // Truncation anywhere: an error, never a panic.
    for cut in (0..bytes.len()).step_by(37) {
        let r = Reader::open(&bytes[..cut]);
        if let Ok(r) = r {
            assert!(verify(&r).is_err(), "truncated at {cut} passed");
        }
    }
}

#[test]
fn header_snapshot() {
    let bytes = encode(&wave(3), &EncodeOptions::default(), |_| {}).unwrap();
    // Preamble: magic, version 7, flags 7 (stored and sparse chunks, front-coded names).
    assert_eq!(&bytes[..12], b"\x89PMC\r\n\x1a\n\x07\x00\x07\x00");
    let reader = Reader::open(bytes.as_slice()).unwrap();
    let h = reader.header();
    assert_eq!((h.vertex_count, h.triangle_count, h.frame_count), (108, 176, 3));
    // Levels anchored at 25% and 10% of the input's triangles (at least 44 and 18 of 176: on
    // this small open grid that takes 36 and 20 of the 108 vertices), then every 4x in
    // vertices while above 8 (20 / 4 is not).
    assert_eq!(h.level_sizes, vec![108, 36, 20]);
    assert_eq!(h.keyframe_interval, 16);
    assert_eq!((h.motion, h.order), (Motion::KeyframeAffine, VertexOrder::BreadthFirst));
    // Version 4 had no keyframe affine motion: such a header under version 4 is refused.
    let mut as_v4 = bytes.clone();
    as_v4[8] = 4;
    let e = Reader::open(as_v4.as_slice()).err().expect("keyframe affine under version 4").to_string();
    assert!(e.contains("header"), "{e}");
    // Deterministic output: encoding twice gives the same bytes.
    assert_eq!(bytes, encode(&wave(3), &EncodeOptions::default(), |_| {}).unwrap());
    // Index order: triangles, then frame 0: the faces only a client stopping at band 1..
    // reads (band 1 first; derived, so two bytes each, and no Corners chunks), then bands
    // top..0, each key, delta, positions; empty Delta chunks are left out (the sparse flag):
    // frame 0 swaps nothing in bands 2 and 1.
    let kinds: Vec<(ChunkKind, u32, u32)> = reader.index().chunks.iter().take(15).map(|e| (e.kind, e.frame, e.band)).collect();
    assert_eq!(
        kinds,
        vec![
            (ChunkKind::Triangles, 0, 0),
            (ChunkKind::Faces, 0, 1),
            (ChunkKind::Faces, 0, 2),
            (ChunkKind::Key, 0, 2),
            (ChunkKind::Positions, 0, 2),
            (ChunkKind::Key, 0, 1),
            (ChunkKind::Positions, 0, 1),
            (ChunkKind::Key, 0, 0),
            (ChunkKind::Delta, 0, 0),
            (ChunkKind::Positions, 0, 0),
            (ChunkKind::Positions, 1, 2),
            (ChunkKind::Delta, 1, 1),
            (ChunkKind::Positions, 1, 1),
            (ChunkKind::Delta, 1, 0),
            (ChunkKind::Positions, 1, 0),
        ]
    );
    assert!(reader.index().chunks.iter().filter(|e| e.kind == ChunkKind::Faces).all(|e| e.raw_len == 2));
}

mod props {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
        #[test]
        fn encode_decode_compare(frames in 1usize..6, key in 0u32..4, bits in 6u8..16, seed in 0u32..1000) {
            let mut seq = wave(frames);
            for (f, frame) in seq.frames.iter_mut().enumerate() {
                for (i, p) in frame.iter_mut().enumerate() {
                    p.z += (((i as u32).wrapping_mul(2654435761u32) ^ seed ^ f as u32) % 97) as f32 * 0.01;
                }
            }
            let opts = EncodeOptions { keyframe_interval: key, quantization: QuantizationChoice::Bits(bits), ..Default::default() };
            round_trip(&seq, &opts);
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
            if let Ok(r) = Reader::open(bytes.as_slice()) {
                let _ = verify(&r);
            }
        }
    }
}

#[test]
fn encoding_stops_when_progress_says_so() {
    let seq = wave(6);
    let mut seen = Vec::new();
    let r = encode_until(&seq, &EncodeOptions::default(), |f| {
        seen.push(f);
        if f == 2 { std::ops::ControlFlow::Break(()) } else { std::ops::ControlFlow::Continue(()) }
    });
    assert!(matches!(r, Err(ContainerError::Cancelled)), "{r:?}");
    assert_eq!(seen, [0, 1, 2], "no frame is encoded after the break");
    let all = encode_until(&seq, &EncodeOptions::default(), |_| std::ops::ControlFlow::Continue(())).unwrap();
    assert_eq!(all, encode(&seq, &EncodeOptions::default(), |_| {}).unwrap());
}

/// Budgets between levels cut by partial splits (an option, proto/container.md, "Partial
/// splits"): on generated meshes
/// every vertex budget from the coarsest level to full resolution gets exactly that many
/// vertices (whole splits add a cluster's children less one at a time, three on these 4-ary
/// hierarchies, and missed most budgets), every triangle budget at most that many triangles,
/// and the vertices of `cut_clusters` are the mesh's.
#[test]
fn vertex_budgets_between_levels_are_met_exactly() {
    for (name, seq) in
        [("cloth", pmcodec_mesh::samples::waving_cloth(30, 24, 4)), ("tube", pmcodec_mesh::samples::twisting_tube(24, 20, 4))]
    {
        let bytes = encode(&seq, &EncodeOptions::default(), |_| {}).expect("encode");
        let reader = Reader::open(bytes.as_slice()).expect("open");
        let sizes = reader.header().level_sizes.clone();
        let mut d = Decoder::new(reader, 0).expect("decoder");
        d.set_budget_cut(BudgetCut::PartialSplits(BudgetPriorities::Frame)).expect("cut");
        d.seek(3).expect("seek");
        let (top, fine) = (*sizes.last().expect("levels"), sizes[0]);
        let mut partial = 0;
        for n in (top..=fine).step_by(7) {
            let m = d.mesh(CutTarget::Vertices(n)).expect("cut");
            let (triangles, nodes) = d.cut_clusters(CutTarget::Vertices(n)).expect("clusters");
            assert_eq!(triangles.len(), m.triangles.len(), "{name}: budget {n}");
            let mut distinct = nodes.clone();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(distinct.len() as u32, n, "{name}: budget {n} (levels {sizes:?}): drawn nodes");
            // A drawn node all of whose fine triangles stand on it twice (a corner of the open
            // cloth) is no vertex of the mesh: rare.
            assert!(
                m.positions.len() as u32 <= n && m.positions.len() as u32 + 3 >= n,
                "{name}: budget {n}: {} vertices",
                m.positions.len()
            );
            partial += usize::from(!sizes.contains(&n));
            let t = 2 * n;
            assert!(d.mesh(CutTarget::Triangles(t)).expect("cut").triangles.len() as u32 <= t, "{name}: budget {t} triangles");
        }
        assert!(partial > 10, "{name}: {partial} budgets between levels");
    }
}

/// Shown triangles by node ids, as sets of sorted corner triples, for churn.
fn triangle_keys(triangles: &[[u32; 3]]) -> std::collections::HashSet<[u32; 3]> {
    triangles
        .iter()
        .map(|t| {
            let mut k = *t;
            k.sort_unstable();
            k
        })
        .collect()
}

/// Partial-split cuts ranked by the keyframe's positions through its interval
/// (proto/container.md, "Partial splits") are stateless (a decoder that seeks straight to a
/// frame, one that plays up to it and one that comes back to it from a later interval cut
/// alike, and so does one that chooses the cut at the frame), the same as ranking by the
/// frame's own positions on a keyframe, and steadier than
/// it within an interval: on generated cloths and tubes fewer shown triangles change per frame,
/// summed over budgets between levels. The default cut (whole splits) differs from both.
#[test]
fn partial_splits_held_through_a_keyframe_interval_are_stateless_and_steadier() {
    for (name, seq) in
        [("cloth", pmcodec_mesh::samples::waving_cloth(24, 20, 12)), ("tube", pmcodec_mesh::samples::twisting_tube(20, 16, 12))]
    {
        let bytes = encode(&seq, &EncodeOptions { keyframe_interval: 6, ..Default::default() }, |_| {}).expect("encode");
        let reader = Reader::open(bytes.as_slice()).expect("open");
        let tris = reader.header().triangle_count;
        // Between levels: a quarter, a third and half of the triangles.
        let budgets = [tris / 4, tris / 3, tris / 2];
        let (mut held_churn, mut fresh_churn) = (0usize, 0usize);
        let held = BudgetCut::PartialSplits(BudgetPriorities::Keyframe);
        let mut playing = Decoder::new(reader.borrowed(), 0).expect("decoder");
        playing.set_budget_cut(held).expect("cut");
        let mut per_frame = Decoder::new(reader.borrowed(), 0).expect("decoder");
        per_frame.set_budget_cut(BudgetCut::PartialSplits(BudgetPriorities::Frame)).expect("cut");
        let mut whole = Decoder::new(reader.borrowed(), 0).expect("decoder");
        let mut differs = 0;
        let mut last: Vec<Option<[std::collections::HashSet<[u32; 3]>; 2]>> = vec![None; budgets.len()];
        for f in 0..seq.frame_count() as u32 {
            playing.seek(f).expect("seek");
            per_frame.seek(f).expect("seek");
            whole.seek(f).expect("seek");
            let mut straight = Decoder::new(reader.borrowed(), 0).expect("decoder");
            straight.set_budget_cut(held).expect("cut");
            straight.seek(f).expect("seek");
            let mut back = Decoder::new(reader.borrowed(), 0).expect("decoder");
            back.set_budget_cut(held).expect("cut");
            back.seek(seq.frame_count() as u32 - 1).expect("seek");
            back.seek(f).expect("seek");
            // Chosen at the frame: the decoder goes back for the keyframe's positions.
            let mut late = Decoder::new(reader.borrowed(), 0).expect("decoder");
            late.seek(f).expect("seek");
            late.set_budget_cut(held).expect("cut");
            assert_eq!(late.frame(), Some(f));
            for (i, &b) in budgets.iter().enumerate() {
                let target = CutTarget::Triangles(b);
                let m = playing.mesh(target).expect("cut");
                assert_eq!(m, straight.mesh(target).expect("cut"), "{name} frame {f} budget {b}: played against seeked");
                assert_eq!(m, back.mesh(target).expect("cut"), "{name} frame {f} budget {b}: played against seeked back");
                assert_eq!(m, late.mesh(target).expect("cut"), "{name} frame {f} budget {b}: cut chosen at the frame");
                if f % 6 == 0 {
                    assert_eq!(m, per_frame.mesh(target).expect("cut"), "{name} keyframe {f} budget {b}");
                }
                differs += usize::from(m != whole.mesh(target).expect("cut"));
                let keys = [
                    triangle_keys(&playing.cut_triangles(target).expect("cut")),
                    triangle_keys(&per_frame.cut_triangles(target).expect("cut")),
                ];
                if let Some(prev) = &last[i] {
                    held_churn += keys[0].difference(&prev[0]).count();
                    fresh_churn += keys[1].difference(&prev[1]).count();
                }
                last[i] = Some(keys);
            }
        }
        assert!(held_churn < fresh_churn, "{name}: {held_churn} triangles changed with held priorities, {fresh_churn} with each frame's");
        assert!(differs > 0, "{name}: partial splits cut as whole splits at every budget");
    }
}

/// A mesh's triangles as corner positions (bit patterns), each rotated to start at its
/// smallest corner, sorted: equal iff the same triangles on the same positions.
fn triangle_set(m: &pmcodec_mesh::TriMesh) -> Vec<[[u32; 3]; 3]> {
    let key = |i: u32| m.positions[i as usize].to_array().map(f32::to_bits);
    let mut out: Vec<[[u32; 3]; 3]> = m
        .triangles
        .iter()
        .map(|t| {
            let c = t.map(key);
            let r = (0..3).min_by_key(|&i| c[i]).unwrap_or(0);
            [c[r], c[(r + 1) % 3], c[(r + 2) % 3]]
        })
        .collect();
    out.sort_unstable();
    out
}

/// Level-major whole splits (the option `BudgetCut::LevelSplits`, proto/container.md
/// "Level-major whole splits"): on generated meshes, a vertex budget at exactly a level's size
/// and a triangle budget at exactly its triangle count draw that level's mesh, and the spec's
/// greedy cut does not always.
#[test]
fn level_major_budgets_at_a_level_draw_that_level() {
    let mut greedy_differs = 0;
    for (name, seq) in
        [("cloth", pmcodec_mesh::samples::waving_cloth(30, 24, 4)), ("tube", pmcodec_mesh::samples::twisting_tube(24, 20, 4))]
    {
        let bytes = encode(&seq, &EncodeOptions::default(), |_| {}).expect("encode");
        let reader = Reader::open(bytes.as_slice()).expect("open");
        let sizes = reader.header().level_sizes.clone();
        assert!(sizes.len() >= 4, "{name}: levels {sizes:?}");
        let mut d = Decoder::new(reader, 0).expect("decoder");
        for frame in [0, 3] {
            d.seek(frame).expect("seek");
            for (level, &size) in sizes.iter().enumerate().take(sizes.len() - 1).skip(1) {
                let want = triangle_set(&d.mesh(CutTarget::Level(level)).expect("level"));
                let targets = [CutTarget::Vertices(size), CutTarget::Triangles(want.len() as u32)];
                for target in targets {
                    d.set_budget_cut(BudgetCut::WholeSplits).expect("cut");
                    greedy_differs += usize::from(triangle_set(&d.mesh(target).expect("cut")) != want);
                    d.set_budget_cut(BudgetCut::LevelSplits).expect("cut");
                    assert!(triangle_set(&d.mesh(target).expect("cut")) == want, "{name} frame {frame} {target:?}: not level {level}");
                }
            }
        }
    }
    assert!(greedy_differs > 0, "the greedy cut is every level here: the test shows nothing");
}
