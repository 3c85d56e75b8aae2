//! The bit coding of the topology chunks (proto/container.md, Key, Faces, Delta and Corners,
//! coding 1) on generated sequences: a cloth (boundaries), rigid parts (many disconnected
//! pieces) and a twisting tube. A client stopping at level L, which reads the coded Faces and
//! Corners of band L, must show at every frame the very level-L mesh a full-resolution client
//! (which reads neither) shows; seeking back to a keyframe too.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{ChunkKind, CutTarget, Decoder, EncodeOptions, QuantizationChoice, Reader, encode, verify};
use std::collections::BTreeSet;

#[test]
fn coded_topology_decodes_at_every_level_as_a_full_client_sees_it() {
    let opts = EncodeOptions { keyframe_interval: 8, quantization: QuantizationChoice::Bits(12), ..Default::default() };
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
                assert_eq!(raw[1], 1, "{name}: coding 1");
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
    let opts = EncodeOptions { keyframe_interval: 8, quantization: QuantizationChoice::Bits(12), ..Default::default() };
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
