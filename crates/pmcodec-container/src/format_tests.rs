//! Tests of the file format's building blocks (`format`).
use super::*;

#[test]
fn frame_names_front_code_and_decode() {
    let long = "x".repeat(300);
    let names: Vec<String> = [
        "waving-cloth@9",
        "waving-cloth@10",
        "",
        "Dance@1.233s",
        "Dance@1.267s",
        "été@1",
        "été@2",
        "\u{7f}odd",
        &long,
        &(long.clone() + "y"),
        "éx",
        "éy",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let coded = front_code(&names);
    assert_eq!(front_decode(&coded), names);
    // The vectors web/test/container.test.ts decodes.
    let x173 = "x".repeat(173);
    let want = [
        "waving-cloth@9".to_string(),
        "\u{d}10".into(),
        "\u{0}".into(),
        "\u{0}Dance@1.233s".into(),
        "\u{9}67s".into(),
        "\u{0}été@1".into(),
        "\u{6}2".into(),
        "\u{0}\u{7f}odd".into(),
        format!("\u{0}{long}"),
        format!("\u{7f}{x173}y"),
        "\u{0}éx".into(),
        "\u{2}y".into(),
    ];
    assert_eq!(coded, want);
    assert_eq!(coded[4], "\u{9}67s");
    // At most 127 shared bytes; a name sharing part of a character shares none of it.
    assert_eq!(coded[9].len(), 1 + 300 - 127 + 1);
    assert_eq!(coded[11], "\u{2}y");
    // Damaged entries decode to names, never a panic: a count beyond the name before, a
    // count inside one of its characters, a first character that is no count.
    let damaged: Vec<String> = ["é", "\u{7f}a", "\u{1}b", "ßc"].iter().map(|s| s.to_string()).collect();
    assert_eq!(front_decode(&damaged), ["é", "éa", "b", "ßc"]);
}

fn entry(kind: ChunkKind, frame: u32, band: u32, offset: u64, stored_len: u32, raw_len: u32) -> ChunkEntry {
    ChunkEntry { kind, frame, band, offset, stored_len, raw_len, crc32: 0xDEAD_BEEF ^ offset as u32 }
}

#[test]
fn version_7_index_round_trips_and_refuses_damage() {
    // Frame 0 with the triangles and two bands, an empty frame 1, frame 2 with a band-5 and
    // an image-like large band; offsets follow from the lengths.
    let chunks = vec![
        entry(ChunkKind::Triangles, 0, 0, 0, 40, 90),
        entry(ChunkKind::Positions, 0, 1, 40, 7, 7),
        entry(ChunkKind::Positions, 0, 0, 47, 300, 200),
        entry(ChunkKind::Delta, 2, 5, 347, 3, 3),
        entry(ChunkKind::Image, 2, 4000, 350, 1, 1),
    ];
    let index = Index { chunks };
    let v7 = index.to_bytes(7, 3).unwrap();
    let v6 = index.to_bytes(6, 3).unwrap();
    assert_eq!(Index::from_bytes(&v7, 7, 3).unwrap(), index);
    assert_eq!(Index::from_bytes(&v6, 6, 3).unwrap(), index);
    // Entries whose raw length is their stored length write it once: 6 bytes and up.
    assert_eq!(v7.len(), 3 + (1 + 1 + 1 + 4) + (1 + 1 + 4) + (1 + 2 + 2 + 4) + (2 + 1 + 4) + (3 + 1 + 4));
    assert!(v7.len() * 4 < v6.len() * 3, "{} against {}", v7.len(), v6.len());
    // Fewer frames than groups: bytes left over; more: ends early; a cut anywhere: an error.
    assert!(Index::from_bytes(&v7, 7, 2).unwrap_err().to_string().contains("left over"));
    assert!(Index::from_bytes(&v7, 7, 4).is_err());
    for cut in 0..v7.len() {
        assert!(Index::from_bytes(&v7[..cut], 7, 3).is_err(), "cut at {cut}");
    }
    // A count beyond what the bytes can hold is refused before anything is sized from it.
    let e = Index::from_bytes(&[0xff, 0xff, 0xff, 0xff, 0x0f, 1, 2, 3], 7, 1).unwrap_err().to_string();
    assert!(e.contains("chunks in 3 bytes"), "{e}");
    // An unknown kind is named.
    let e = Index::from_bytes(&[1, 31, 1, 0, 0, 0, 0], 7, 1).unwrap_err().to_string();
    assert!(e.contains("unknown chunk kind 31"), "{e}");
}

/// An entry's frame beyond the header's count (damage the test support makes on purpose) joins
/// the last frame: the index stays the size of its entries, where a count per frame up to the
/// entry's frame took gigabytes for a frame near 2^32.
#[test]
fn version_7_index_of_entries_beyond_the_frames_stays_small() {
    let chunks = vec![entry(ChunkKind::Positions, 0, 0, 0, 5, 5), entry(ChunkKind::Positions, u32::MAX - 1, 0, 5, 5, 5)];
    let index = Index { chunks };
    for frames in [0, 1, 3] {
        let v7 = index.to_bytes(7, frames).unwrap();
        assert!(v7.len() <= 3 + 2 * (1 + 1 + 4), "{frames} frames: {} bytes", v7.len());
        // Both entries are written, the second in the last frame.
        let back = Index::from_bytes(&v7, 7, frames.max(1)).unwrap();
        assert_eq!(back.chunks.len(), 2, "{frames} frames");
        assert_eq!(back.chunks[1].frame, frames.max(1) - 1, "{frames} frames");
    }
}
