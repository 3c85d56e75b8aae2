//! Key coding 3 (proto/container.md, "Key"): a later keyframe's parent map as its changes from
//! frame 0's. On generated sequences (rigid parts, whose clusters hardly change; a waving cloth
//! and a twisting tube, whose clusters follow the motion), a decoder that seeks straight to a
//! late frame (reading frame 0's Key chunks besides its keyframe's) shows what one that played
//! every frame shows, at every level; what `chunks_for` lists suffices; damaged or misplaced
//! coding 3 payloads are refused with typed errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::payload::{key_from_first, read_key, read_key_from, write_key_best, write_key_changes};
use pmcodec_container::{ChunkKind, CutTarget, Decoder, EncodeOptions, QuantizationChoice, Reader, encode, verify};

#[test]
fn later_keyframes_list_their_changes_and_decode_as_played() {
    let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let mut coded = 0;
    for (name, seq) in [
        ("parts", pmcodec_mesh::samples::rigid_parts(9, 14)),
        ("cloth", pmcodec_mesh::samples::waving_cloth(14, 12, 14)),
        ("tube", pmcodec_mesh::samples::twisting_tube(16, 10, 14)),
    ] {
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let r = Reader::open(bytes.as_slice()).expect("open");
        verify(&r).unwrap_or_else(|e| panic!("{name}: {e}"));
        let h = r.header();
        for e in r.index().chunks.iter().filter(|e| e.kind == ChunkKind::Key) {
            let raw = r.read_chunk(e).unwrap();
            if key_from_first(&raw) {
                assert!(e.frame > 0, "{name}: coding 3 in frame 0");
                coded += 1;
                // Without frame 0's parents it is an error that says what it needs.
                let err = read_key(&raw, "k", &h.level_sizes, e.band as usize, 7).unwrap_err().to_string();
                assert!(err.contains("frame 0"), "{err}");
            }
        }
        let frames = h.frame_count;
        for level in 0..h.levels() {
            let mut played = Decoder::new(r.borrowed(), level).expect("decoder");
            let mut shown = Vec::new();
            for f in 0..frames {
                played.seek(f).expect("frame");
                shown.push(played.mesh(CutTarget::Level(level)).expect("mesh"));
            }
            for f in [frames - 1, 9, 5] {
                let mut seeker = Decoder::new(r.borrowed(), level).expect("decoder");
                let wanted = seeker.chunks_for(f);
                assert!(
                    (level..h.top()).all(|j| wanted.iter().any(|e| e.kind == ChunkKind::Key && e.frame == 0 && e.band as usize == j)),
                    "{name} level {level}: frame 0's Key chunks fetched"
                );
                seeker.seek(f).expect("seek");
                let m = seeker.mesh(CutTarget::Level(level)).expect("mesh");
                assert_eq!(m.triangles, shown[f as usize].triangles, "{name} level {level} frame {f}");
                assert_eq!(m.positions, shown[f as usize].positions, "{name} level {level} frame {f}");
            }
        }
    }
    assert!(coded > 0, "no Key chunk took coding 3");
}

#[test]
fn coding_3_reads_back_and_damage_is_refused() {
    // 40 nodes under 9 parents; a later keyframe moves a few.
    let first: Vec<u32> = (0..40).map(|v| v / 5 + (v % 7 == 0) as u32).collect();
    let mut later = first.clone();
    for (v, p) in [(3usize, 8u32), (17, 0), (39, 2)] {
        later[v] = p;
    }
    let sizes = [40, 9, 1];
    let raw = write_key_best(&later, 9, Some(&first));
    assert!(key_from_first(&raw), "a few changes take coding 3");
    assert_eq!(read_key_from(&raw, "k", &sizes, 0, 7, Some(&first)).unwrap(), later);
    // No change at all: three bytes.
    let same = write_key_changes(&first, &first);
    assert_eq!(same.len(), 3);
    assert_eq!(read_key_from(&same, "k", &sizes, 0, 7, Some(&first)).unwrap(), first);
    // Frame 0's parents missing, of another band's length, or the top band: refused.
    assert!(read_key_from(&raw, "k", &sizes, 0, 7, None).is_err());
    assert!(read_key_from(&raw, "k", &sizes, 0, 7, Some(&first[1..])).is_err());
    assert!(read_key_from(&raw, "k", &[40, 9], 1, 7, Some(&first)).is_err());
    // A parent beyond the level above, or a node beyond the band.
    assert!(read_key_from(&raw, "k", &[40, 8, 1], 0, 7, Some(&first)).is_err());
    assert!(read_key_from(&raw, "k", &[39, 9, 1], 0, 7, Some(&first[..39])).is_err());
    // Cut short, or a byte after its end.
    for len in 3..raw.len() {
        assert!(read_key_from(&raw[..len], "k", &sizes, 0, 7, Some(&first)).is_err(), "cut at {len}");
    }
    let mut long = raw.clone();
    long.push(1);
    assert!(read_key_from(&long, "k", &sizes, 0, 7, Some(&first)).is_err());
    // Flipped bits never panic; any payload accepted reads as a parent map in range.
    for i in 2..raw.len() {
        for b in 0..8 {
            let mut bad = raw.clone();
            bad[i] ^= 1 << b;
            if let Ok(p) = read_key_from(&bad, "k", &sizes, 0, 7, Some(&first)) {
                assert_eq!(p.len(), 40);
                assert!(p.iter().all(|&x| x < 9));
            }
        }
    }
}
