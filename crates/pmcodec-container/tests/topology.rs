//! The bit coding of the topology chunks (proto/container.md, Key, Faces, Delta and Corners,
//! coding 1) on generated sequences: a cloth (boundaries), rigid parts (many disconnected
//! pieces) and a twisting tube. A client stopping at level L, which reads the coded Faces and
//! Corners of band L, must show at every frame the very level-L mesh a full-resolution client
//! (which reads neither) shows; seeking back to a keyframe too.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{ChunkKind, CutTarget, Decoder, DerivedTopology, EncodeOptions, QuantizationChoice, Reader, encode, verify};
use std::collections::BTreeSet;

#[test]
fn coded_topology_decodes_at_every_level_as_a_full_client_sees_it() {
    // Every band's faces and corners sent, so that the codings of those chunks are exercised.
    let opts = EncodeOptions {
        keyframe_interval: 8,
        quantization: QuantizationChoice::Bits(12),
        derived_topology: DerivedTopology::Never,
        ..Default::default()
    };
    let mut coded_kinds = BTreeSet::new();
    for (name, seq) in [
        ("cloth", pmcodec_mesh::samples::waving_cloth(14, 12, 20)),
        ("parts", pmcodec_mesh::samples::rigid_parts(7, 20)),
        ("tube", pmcodec_mesh::samples::twisting_tube(16, 10, 20)),
    ] {
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let r = Reader::open(bytes.as_slice()).expect("open");
        verify(&r).expect("verify");
        for e in &r.index().chunks {
            if !matches!(e.kind, ChunkKind::Key | ChunkKind::Delta | ChunkKind::Faces | ChunkKind::Corners) {
                continue;
            }
            let raw = r.read_chunk(e).expect("chunk");
            if raw.len() >= 2 && raw[0] == 0 {
                // Key chunks of later keyframes may list their changes from frame 0's (coding 3).
                let coding3 = e.kind == ChunkKind::Key && e.frame > 0 && raw[1] == 3;
                assert!(raw[1] == 1 || coding3, "{name}: coding 1");
                coded_kinds.insert(u32::from(e.kind));
            }
        }
        let levels = r.header().levels();
        assert!(levels >= 3, "{name}: {levels} levels");
        let frames = r.header().frame_count;
        let mut full = Decoder::new(r.borrowed(), 0).expect("full");
        for level in 1..levels {
            let mut part = Decoder::new(r.borrowed(), level).expect("level-limited");
            // Every frame in order, then back to the middle of a keyframe interval.
            for f in (0..frames).chain([13, 3]) {
                full.seek(f).expect("full frame");
                part.seek(f).expect("level-limited frame");
                let (a, b) = (full.mesh(CutTarget::Level(level)).expect("full"), part.mesh(CutTarget::Level(level)).expect("part"));
                assert_eq!(a.triangles, b.triangles, "{name} level {level} frame {f}: triangles");
                assert_eq!(a.positions, b.positions, "{name} level {level} frame {f}: positions");
            }
        }
    }
    for kind in [ChunkKind::Key, ChunkKind::Delta, ChunkKind::Faces, ChunkKind::Corners] {
        assert!(coded_kinds.contains(&u32::from(kind)), "no {} chunk was bit-coded: {coded_kinds:?}", kind.name());
    }
}

/// Damaged coded chunks are refused with a typed error naming the chunk, never a panic: every
/// truncation and a flipped bit in each byte of the coded Corners chunks.
#[test]
fn damaged_coded_corners_are_refused() {
    use pmcodec_container::payload;
    let seq = pmcodec_mesh::samples::waving_cloth(14, 12, 12);
    let opts = EncodeOptions {
        keyframe_interval: 8,
        quantization: QuantizationChoice::Bits(12),
        derived_topology: DerivedTopology::Never,
        ..Default::default()
    };
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    let r = Reader::open(bytes.as_slice()).expect("open");
    let h = r.header();
    let mut tried = 0;
    for level in 1..h.levels() {
        let mut d = Decoder::new(r.borrowed(), level).expect("decoder");
        d.seek(0).expect("frame 0");
        for f in 1..h.frame_count.min(8) {
            let held = d.replay().expect("replay").corners().to_vec();
            if let Some(e) = r.index().chunks.iter().find(|e| e.kind == ChunkKind::Corners && e.frame == f && e.band as usize == level) {
                let raw = r.read_chunk(e).expect("chunk");
                if raw.len() >= 2 && raw[0] == 0 {
                    let size = h.level_sizes[level];
                    let updates = payload::read_corner_updates(&raw, "c", size, &held).expect("intact");
                    assert!(!updates.is_empty());
                    for cut in 0..raw.len() {
                        let got = payload::read_corner_updates(&raw[..cut], "c", size, &held);
                        assert!(got.is_err() || cut < 2, "cut at {cut} accepted");
                    }
                    for i in 2..raw.len() {
                        let mut bad = raw.clone();
                        bad[i] ^= 0x10;
                        // Either refused, or other updates (a flipped bit may still spell a valid chunk).
                        if let Ok(u) = payload::read_corner_updates(&bad, "c", size, &held) {
                            assert_ne!(u, updates, "flip in byte {i} changed nothing");
                        }
                    }
                    tried += 1;
                }
            }
            d.seek(f).expect("frame");
        }
    }
    assert!(tried > 0, "no coded Corners chunk");
}

/// Derived topology (proto/container.md, "Faces", coding 2): a file whose bands derive their
/// faces and corner updates decodes at every level, every frame (in order, and seeking back
/// into an interval), exactly as the file that sends them: same level meshes, same positions.
/// On a cloth (boundaries), rigid parts (many disconnected pieces), a twisting tube, and a
/// skinned generated sequence; with and without the sparse and stored flags (with them, the
/// Positions chunks of bands skinning predicts exactly are left out).
#[test]
fn derived_topology_decodes_as_sent_topology() {
    let base = EncodeOptions { keyframe_interval: 6, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let skinned = pmcodec_mesh::skin::bending_tube(16, 40, 18);
    assert!(skinned.skin.is_some());
    for (name, seq) in [
        ("cloth", pmcodec_mesh::samples::waving_cloth(14, 12, 18)),
        ("parts", pmcodec_mesh::samples::rigid_parts(7, 18)),
        ("tube", pmcodec_mesh::samples::twisting_tube(16, 10, 18)),
        ("skinned", skinned),
    ] {
        let sent = encode(&seq, &EncodeOptions { derived_topology: DerivedTopology::Never, ..base.clone() }, |_| {}).expect("encode");
        let sent = Reader::open(sent.as_slice()).expect("open");
        let levels = sent.header().levels();
        assert!(levels >= 3, "{name}: {levels} levels");
        for (policy, flags) in [
            (DerivedTopology::Always, pmcodec_container::format::FLAGS),
            (DerivedTopology::Always, 0),
            (DerivedTopology::WhenCheaper, pmcodec_container::format::FLAGS),
        ] {
            let opts = EncodeOptions { derived_topology: policy, chunk_flags: flags, ..base.clone() };
            let bytes = encode(&seq, &opts, |_| {}).expect("encode");
            let r = Reader::open(bytes.as_slice()).expect("open");
            verify(&r).expect("verify");
            let derived: Vec<_> = r.index().chunks.iter().filter(|e| e.kind == ChunkKind::Faces && e.raw_len == 2).collect();
            if policy == DerivedTopology::Always {
                // Every band of every keyframe derived, and no corner update sent.
                assert_eq!(derived.len(), r.index().chunks.iter().filter(|e| e.kind == ChunkKind::Faces).count(), "{name}");
                assert!(!derived.is_empty());
                for e in r.index().chunks.iter().filter(|e| e.kind == ChunkKind::Corners) {
                    assert_eq!(r.read_chunk(e).expect("chunk"), [0], "{name}: {}", e.describe());
                }
                // (`sent` is written with today's flags.)
                assert!(
                    flags == 0 || bytes.len() < sent.source().len(),
                    "{name}: derived {} B, sent {} B",
                    bytes.len(),
                    sent.source().len()
                );
            }
            if name == "skinned" && flags != 0 {
                // Bands skinning predicts exactly: their Positions chunks left out (zero
                // residuals, the sparse flag), decoding as the file that holds them (flags 0).
                let positions = r.index().chunks.iter().filter(|e| e.kind == ChunkKind::Positions).count();
                assert!(positions < (levels as u32 * r.header().frame_count) as usize, "{positions} Positions chunks");
            }
            for level in 0..levels {
                let derives = r.derives(0, level);
                assert_eq!(
                    derives,
                    level > 0 && (policy == DerivedTopology::Always || derived.iter().any(|e| e.frame == 0 && e.band as usize == level))
                );
                // What a level-limited client fetches covers what it reads (a decoder over
                // exactly those chunks decodes every frame).
                let chunks = Decoder::new(r.borrowed(), level).expect("decoder").chunks_for(r.header().frame_count - 1);
                let key_below = chunks.iter().any(|e| e.kind == ChunkKind::Key && (e.band as usize) < level);
                assert_eq!(key_below, level > 0 && r.derives(r.header().frame_count - 1, level), "{name} level {level}");
                let mut a = Decoder::new(sent.borrowed(), level).expect("sent");
                let mut b = Decoder::new(r.borrowed(), level).expect("derived");
                b.keep_keyframes(2);
                for f in (0..r.header().frame_count).chain([13, 3, 8, 14]) {
                    a.seek(f).expect("sent frame");
                    b.seek(f).expect("derived frame");
                    assert_eq!(a.replay().expect("a").corners(), b.replay().expect("b").corners(), "{name} level {level} frame {f}");
                    let (x, y) = (a.mesh(CutTarget::Level(level)).expect("a"), b.mesh(CutTarget::Level(level)).expect("b"));
                    assert_eq!(x.triangles, y.triangles, "{name} level {level} frame {f}: triangles");
                    assert_eq!(x.positions, y.positions, "{name} level {level} frame {f}: positions");
                }
            }
        }
    }
}

/// A derived interval's damage is refused by name, never a panic: a Corners chunk that says
/// something where the faces are derived, a derived Faces payload with a byte more, and a Key
/// chunk below the band (which a derived band reads) out of range.
#[test]
fn damaged_derived_bands_are_refused() {
    use pmcodec_container::testing::reseal;
    let seq = pmcodec_mesh::samples::waving_cloth(10, 9, 6);
    // Flags 0: every Corners chunk present (the empty payload), so one can be damaged.
    let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), chunk_flags: 0, ..Default::default() };
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    let fails = |bytes: &[u8], frame: u32| -> String {
        let r = Reader::open(bytes).expect("open");
        let mut d = Decoder::new(r.borrowed(), 1).expect("decoder");
        (0..=frame).map(|f| d.seek(f)).find_map(Result::err).expect("damage detected").to_string()
    };
    let damaged = |kind: ChunkKind, frame: u32, band: u32, f: fn(&mut Vec<u8>)| {
        reseal(&bytes, |u| {
            let c = u.chunks.iter_mut().find(|c| c.entry.kind == kind && c.entry.frame == frame && c.entry.band == band).expect("chunk");
            f(&mut c.raw);
        })
        .expect("reseal")
    };
    // One update in the varint coding: triangle 0's corners.
    let e = fails(&damaged(ChunkKind::Corners, 2, 1, |raw| *raw = vec![1, 0, 0, 1, 2]), 2);
    assert!(e.contains("frame 2 band 1 corners") && e.contains("derived"), "{e}");
    let e = fails(&damaged(ChunkKind::Faces, 0, 1, |raw| raw.push(0)), 0);
    assert!(e.contains("frame 0 band 1 faces") && e.contains("coding"), "{e}");
    // 90 parents in the varint coding, the first 60 (beyond level 1).
    let e = fails(&damaged(ChunkKind::Key, 4, 0, |raw| *raw = [90, 120].into_iter().chain([0; 89]).collect()), 4);
    assert!(e.contains("frame 4 band 0 keyframe"), "{e}");
    // The intact file decodes.
    assert!(
        Reader::open(bytes.as_slice()).is_ok_and(|r| Decoder::new(r.borrowed(), 1).is_ok_and(|mut d| (0..6).all(|f| d.seek(f).is_ok())))
    );
}

/// Front-coded frame names (preamble flag 4, proto/container.md "Header"): read back as given,
/// in a smaller header than plain names.
#[test]
fn front_coded_frame_names_read_back() {
    use pmcodec_container::format::{FLAG_NAMES, FLAGS, Preamble};
    let mut seq = pmcodec_mesh::samples::waving_cloth(6, 5, 24);
    seq.frame_names[3] = "été@3".into();
    seq.frame_names[4] = String::new();
    let header_len = |flags: u16| {
        let bytes = encode(&seq, &EncodeOptions { chunk_flags: flags, ..Default::default() }, |_| {}).expect("encode");
        let r = Reader::open(bytes.as_slice()).expect("open");
        assert_eq!(r.header().frame_names, seq.frame_names, "flags {flags}");
        Preamble::parse(&bytes).expect("preamble").header_len
    };
    let (front, plain) = (header_len(FLAGS), header_len(FLAGS & !FLAG_NAMES));
    assert!(front + 200 < plain, "header {front} B front-coded, {plain} B plain");
}
