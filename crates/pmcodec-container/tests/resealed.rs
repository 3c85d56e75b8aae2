//! Damage that passes the checksums: valid files taken apart, their header, index and
//! decompressed payloads damaged, and sealed again with every CRC, length and offset made
//! true (`pmcodec_container::testing`). A seeded, deterministic run of the fuzz target's
//! mutations, cheap enough for every test run; and the fuzzer's minimized corpus and crashers
//! (`tests/resealed/`), each of which must give the outcome recorded for it.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::testing::{Rng, Unsealed, exercise, mutate, reseal, stopped_at_the_door, variant};
use pmcodec_container::{ContainerError, Reader};
use std::path::Path;

fn seeds() -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .expect("tests/corpus")
        .filter_map(|e| {
            let p = e.expect("entry").path();
            let name = p.file_name()?.to_string_lossy().into_owned();
            name.starts_with("valid-").then(|| (name, std::fs::read(&p).expect("read")))
        })
        .collect();
    out.sort();
    assert!(out.len() >= 5, "{} valid seed files in {}", out.len(), dir.display());
    out
}

#[test]
fn sealing_an_untouched_file_gives_a_valid_file() {
    for (name, bytes) in seeds() {
        let again = reseal(&bytes, |_| {}).unwrap_or_else(|e| panic!("{name}: {e}"));
        exercise(&again).unwrap_or_else(|e| panic!("{name} resealed: {e}"));
        // Same header, same index but for the recompressed chunks' sizes and CRCs.
        let (a, b) = (Reader::open(bytes.as_slice()).expect("open"), Reader::open(again.as_slice()).expect("open"));
        assert_eq!(a.header(), b.header(), "{name}");
        assert_eq!(a.index().chunks.len(), b.index().chunks.len(), "{name}");
        for (x, y) in a.index().chunks.iter().zip(&b.index().chunks) {
            assert_eq!((x.kind, x.frame, x.band, x.raw_len), (y.kind, y.frame, y.band, y.raw_len), "{name}");
            assert_eq!(a.read_chunk(x).expect("chunk"), b.read_chunk(y).expect("chunk"), "{name}");
        }
    }
}

/// 400 resealed mutations of each seed file: every one gives `Ok` or a typed error (a panic
/// fails the test), and most get past the checksums to the parsers and the decoder.
#[test]
fn resealed_damage_is_refused_with_typed_errors() {
    let mut past_the_door = 0usize;
    let mut errors = 0usize;
    let mut total = 0usize;
    let mut by_variant = std::collections::BTreeMap::new();
    for (k, (name, bytes)) in seeds().into_iter().enumerate() {
        let base = Unsealed::open(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        for i in 0..400u64 {
            let mut rng = Rng::new((k as u64) << 32 | i);
            let mut u = base.clone();
            mutate(&mut u, &mut rng);
            let file = u.seal();
            total += 1;
            if let Err(e) = exercise(&file) {
                errors += 1;
                *by_variant.entry(variant(&e)).or_insert(0usize) += 1;
                if !stopped_at_the_door(&e) {
                    past_the_door += 1;
                }
            }
        }
    }
    eprintln!("{total} resealed mutations: {errors} refused, {past_the_door} past the checksums; {by_variant:?}");
    // Some damage is harmless (a flags field, a frame rate, a position residual), but most is
    // not; and nearly all of what is refused must be refused by the parsers or the decoder,
    // not the CRCs (the only way to fail a CRC after resealing is an index entry that lies
    // about where its chunk is).
    assert!(errors * 10 >= total * 6, "only {errors} of {total} mutations refused");
    assert!(past_the_door * 10 >= errors * 9, "only {past_the_door} of {errors} refusals got past the checksums");
}

#[test]
fn trailing_bytes_and_a_second_container_are_refused() {
    for (name, bytes) in seeds() {
        let mut junk = bytes.clone();
        junk.extend_from_slice(b"garbage");
        match Reader::open(junk.as_slice()) {
            Err(ContainerError::TrailingBytes { bytes: 7 }) => {}
            Err(e) => panic!("{name} + 7 bytes: {e}"),
            Ok(_) => panic!("{name} + 7 bytes: accepted"),
        }
        let twice = [bytes.as_slice(), bytes.as_slice()].concat();
        match Reader::open(twice.as_slice()) {
            Err(ContainerError::TrailingBytes { bytes: n }) => assert_eq!(n, bytes.len() as u64, "{name}"),
            Err(e) => panic!("{name} twice: {e}"),
            Ok(_) => panic!("{name} twice: accepted"),
        }
        // The same through resealing: a trailing part the index does not cover.
        let resealed = reseal(&bytes, |u| u.trailing.push(0)).expect("reseal");
        assert!(matches!(Reader::open(resealed.as_slice()), Err(ContainerError::TrailingBytes { bytes: 1 })), "{name}");
    }
}

/// One line per file of `tests/resealed/outcomes.txt`: `NAME OUTCOME`, where OUTCOME is `ok`
/// or the variant of the error the file must give.
#[test]
fn fuzz_corpus_and_crashers_give_their_recorded_outcome() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/resealed");
    let manifest = std::fs::read_to_string(dir.join("outcomes.txt")).expect("tests/resealed/outcomes.txt");
    let mut checked = 0;
    let mut refused = 0;
    for line in manifest.lines().filter(|l| !l.trim().is_empty() && !l.starts_with('#')) {
        let (name, expected) = line.split_once(' ').unwrap_or_else(|| panic!("outcomes.txt: bad line {line:?}"));
        let bytes = std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("tests/resealed/{name}: {e}"));
        let got = match exercise(&bytes) {
            Ok(()) => "ok",
            Err(e) => {
                refused += 1;
                variant(&e)
            }
        };
        assert_eq!(got, expected.trim(), "tests/resealed/{name}");
        checked += 1;
    }
    let files = std::fs::read_dir(&dir)
        .expect("tests/resealed")
        .filter(|e| e.as_ref().is_ok_and(|e| e.path().extension().is_some_and(|x| x == "pmc")))
        .count();
    assert_eq!(checked, files, "every .pmc file of tests/resealed has a line in outcomes.txt");
    assert!(refused * 2 >= checked, "{refused} of {checked} corpus files refused");
}

/// A keyframe whose parent map leaves a cluster empty is refused by name (the replay would
/// otherwise play a hierarchy no encoder wrote).
#[test]
fn a_keyframe_with_an_empty_cluster_is_refused() {
    use pmcodec_container::{ChunkKind, payload};
    let (name, bytes) = seeds().into_iter().find(|(n, _)| n.contains("tube-k2")).expect("valid-tube-k2.pmc");
    let file = reseal(&bytes, |u| {
        let sizes = u.parsed_header().expect("header").level_sizes;
        let version = u.version;
        let c =
            u.chunks.iter_mut().find(|c| c.entry.kind == ChunkKind::Key && c.entry.frame == 0 && c.entry.band == 0).expect("key band 0");
        let n = payload::read_key(&c.raw, "t", &sizes, 0, version).expect("key").len();
        c.raw = payload::write_key(&vec![0; n], version);
    })
    .expect("reseal");
    match exercise(&file) {
        Err(ContainerError::Corrupt { what, detail }) => {
            assert_eq!(what, "frame 0 band 0 keyframe", "{name}");
            assert!(detail.contains("level 1 node 1 has no children"), "{name}: {detail}");
        }
        other => panic!("{name}: {other:?}"),
    }
}

/// The triangles chunk is frame 0 band 0, and there is one (the TypeScript decoder looks it up
/// so, and a file that plays in one decoder must play in the other).
#[test]
fn a_misplaced_or_second_triangles_chunk_is_refused() {
    use pmcodec_container::ChunkKind;
    let (name, bytes) = seeds().into_iter().next().expect("a seed");
    let moved = reseal(&bytes, |u| {
        let c = u.chunks.iter_mut().find(|c| c.entry.kind == ChunkKind::Triangles).expect("triangles");
        c.entry.band = 1;
    })
    .expect("reseal");
    let e = Reader::open(moved.as_slice()).err().unwrap_or_else(|| panic!("{name}: accepted"));
    assert!(e.to_string().contains("where the triangles chunk is frame 0 band 0"), "{name}: {e}");
    let twice = reseal(&bytes, |u| {
        let c = u.chunks.iter().find(|c| c.entry.kind == ChunkKind::Triangles).expect("triangles").clone();
        u.chunks.insert(0, c);
    })
    .expect("reseal");
    let e = Reader::open(twice.as_slice()).err().unwrap_or_else(|| panic!("{name}: accepted"));
    assert!(e.to_string().contains("a second triangles chunk"), "{name}: {e}");
}
