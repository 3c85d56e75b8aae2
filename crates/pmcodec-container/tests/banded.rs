//! The banded index (preamble flag `FLAG_BANDS`, proto/container.md "Index"): a file with it
//! decodes at every level exactly as the same file without it; a client opened for a level
//! fetches only its levels' groups of entries (fewer bytes) and decodes alike; damage to the
//! group table or to any group is refused by name, and a reader opened for a level does not
//! serve a finer one.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::format::{FLAG_BANDS, FLAGS, PREAMBLE_LEN, group_count, parse_table};

/// Today's flags and the banded index.
const BANDED: u16 = FLAGS | FLAG_BANDS;
use pmcodec_container::{ContainerError, CutTarget, Decoder, DerivedTopology, EncodeOptions, QuantizationChoice, Reader, encode, verify};
use pmcodec_mesh::Sequence;

fn options(derived: DerivedTopology) -> EncodeOptions {
    EncodeOptions {
        build: pmcodec_hierarchy::BuildOptions { min_coarsest: 4, ..EncodeOptions::default().build },
        keyframe_interval: 4,
        quantization: QuantizationChoice::Bits(12),
        derived_topology: derived,
        chunk_flags: BANDED,
        ..Default::default()
    }
}

/// A plain cloth and a skinned tube, each with topology derived and sent.
fn inputs() -> Vec<(String, Sequence, DerivedTopology)> {
    let mut out = Vec::new();
    for d in [DerivedTopology::Always, DerivedTopology::Never] {
        out.push((format!("cloth {d:?}"), pmcodec_mesh::samples::waving_cloth(14, 11, 30), d));
        let mut tube = pmcodec_mesh::skin::bending_tube(12, 24, 24);
        if d == DerivedTopology::Never {
            tube.skin = None;
        }
        out.push((format!("tube {d:?}"), tube, d));
    }
    out
}

/// A mesh's triangles and positions.
type Mesh = (Vec<[u32; 3]>, Vec<[f32; 3]>);

/// Every frame's mesh at `level` (its whole level, and a cut), played through.
fn meshes(r: Reader<&[u8]>, level: usize) -> Vec<Mesh> {
    let frames = r.header().frame_count;
    let mut d = Decoder::new(r, level).expect("decoder");
    let mut out = Vec::new();
    for f in 0..frames {
        d.seek(f).expect("frame");
        for target in [CutTarget::Level(level), CutTarget::Triangles(40)] {
            let m = d.mesh(target).expect("mesh");
            out.push((m.triangles, m.positions.iter().map(|p| p.to_array()).collect()));
        }
    }
    out
}

#[test]
fn banded_files_decode_as_unbanded_ones_and_coarse_clients_read_less_index() {
    assert_eq!(EncodeOptions::default().chunk_flags, FLAGS | FLAG_BANDS, "the banded index is the default");
    let mut tested = 0;
    for (name, seq, derived) in inputs() {
        let opts = options(derived);
        let banded = encode(&seq, &opts, |_| {}).expect("encode");
        let plain = encode(&seq, &EncodeOptions { chunk_flags: FLAGS, ..opts.clone() }, |_| {}).expect("encode plain");
        assert_eq!(u16::from_le_bytes([plain[10], plain[11]]) & FLAG_BANDS, 0, "{name}");
        // Banded where that is no longer (every input here but the smallest).
        assert!(banded.len() <= plain.len(), "{name}: banded {} bytes, unbanded {}", banded.len(), plain.len());
        if u16::from_le_bytes([banded[10], banded[11]]) & FLAG_BANDS == 0 {
            assert_eq!(banded, plain, "{name}: unbanded where banded is longer");
            continue;
        }
        tested += 1;
        let (b, p) = (Reader::open(banded.as_slice()).unwrap(), Reader::open(plain.as_slice()).unwrap());
        verify(&b).expect("verify banded");
        // The same chunks, wherever they lie.
        let key = |r: &Reader<&[u8]>| {
            let mut v: Vec<_> = r.index().chunks.iter().map(|e| (e.frame, e.band, u32::from(e.kind), r.read_chunk(e).unwrap())).collect();
            v.sort();
            v
        };
        assert_eq!(key(&b), key(&p), "{name}: chunks");
        let levels = b.header().levels();
        assert!(levels >= 3, "{name}: {levels} levels");
        for level in 0..levels {
            let part = Reader::open_at(banded.as_slice(), level).expect("open at level");
            if level > 0 {
                assert!(
                    part.bytes_read() < b.data_start(),
                    "{name} level {level}: {} of {} index bytes",
                    part.bytes_read(),
                    b.data_start()
                );
                assert!(Decoder::new(Reader::open_at(banded.as_slice(), level).unwrap(), level - 1).is_err(), "{name} level {level}");
            }
            // The entries it holds are exactly those a client of its level reads, and more only
            // where a group holds some it does not.
            for e in b.index().chunks.iter().filter(|e| b.reads(e, level)) {
                assert!(part.index().chunks.contains(e), "{name} level {level}: {} missing", e.describe());
            }
            assert_eq!(meshes(part, level), meshes(Reader::open(plain.as_slice()).unwrap(), level), "{name} level {level}");
        }
    }
    assert!(tested >= 3, "{tested} inputs banded");
}

/// The table's rows as written: (first varint, chunk bytes, CRC).
fn write_table(rows: &[pmcodec_container::format::GroupRow]) -> Vec<u8> {
    let mut out = Vec::new();
    pmcodec_container::payload::put(&mut out, rows.len() as u32);
    for r in rows {
        pmcodec_container::payload::put(&mut out, r.body_len << 1 | u32::from(r.derived));
        pmcodec_container::payload::put(&mut out, r.chunks_len);
        if r.body_len > 0 {
            out.extend_from_slice(&r.crc32.to_le_bytes());
        }
    }
    out
}

fn refused(bytes: &[u8]) -> ContainerError {
    match Reader::open(bytes) {
        Ok(_) => panic!("a damaged file opened"),
        Err(e) => e,
    }
}

#[test]
fn damage_to_the_table_or_a_group_is_refused_by_name() {
    let seq = pmcodec_mesh::skin::bending_tube(12, 24, 24);
    let bytes = encode(&seq, &options(DerivedTopology::Always), |_| {}).expect("encode");
    let u32_at = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]) as usize;
    let (header_len, table_len) = (u32_at(12), u32_at(28));
    let table_at = PREAMBLE_LEN + header_len;
    let levels = Reader::open(bytes.as_slice()).unwrap().header().levels();
    let rows = parse_table(&bytes[table_at..table_at + table_len], levels).unwrap();
    assert_eq!(rows.len(), group_count(levels));
    // A flipped bit in the table: its CRC, in the preamble.
    let mut b = bytes.clone();
    b[table_at + 1] ^= 4;
    assert!(matches!(refused(&b), ContainerError::Checksum { ref what } if what == "index table"));
    // A flipped bit in each group with entries: that group's CRC, by its name; a client opened
    // for a level whose groups do not include it does not see it.
    let mut at = table_at + table_len;
    let mut damaged = 0;
    for (g, row) in rows.iter().enumerate() {
        if row.body_len > 0 {
            let mut b = bytes.clone();
            b[at + row.body_len as usize - 1] ^= 1;
            let e = refused(&b);
            assert!(
                matches!(e, ContainerError::Checksum { ref what } if what.starts_with(&format!("index group {g} ("))),
                "group {g}: {e}"
            );
            let blind = (1..levels).find(|&l| {
                let derived = rows[pmcodec_container::format::group_of(pmcodec_container::ChunkKind::Faces, l as u32, levels)].derived;
                !pmcodec_container::format::groups_for(levels, l, derived).contains(&g)
            });
            if let Some(l) = blind {
                Reader::open_at(b.as_slice(), l).expect("a group the level does not read");
            }
            damaged += 1;
        }
        at += row.body_len as usize;
    }
    assert!(damaged > 3);
    // A table whose CRCs hold but whose lengths lie, one group's chunks a byte longer and the
    // next's a byte shorter: the group's own entries disagree, and the error names it.
    let g = rows.iter().position(|r| r.chunks_len > 0).unwrap();
    let h = (g + 1..rows.len()).find(|&h| rows[h].chunks_len > 0).unwrap();
    let mut lying = rows.clone();
    lying[g].chunks_len += 1;
    lying[h].chunks_len -= 1;
    let table = write_table(&lying);
    assert_eq!(table.len(), table_len, "same varint lengths");
    let mut b = bytes.clone();
    b[table_at..table_at + table_len].copy_from_slice(&table);
    b[24..28].copy_from_slice(&crc32fast::hash(&table).to_le_bytes());
    let e = refused(&b);
    assert!(matches!(e, ContainerError::Corrupt { ref what, .. } if what.starts_with(&format!("index group {g} ("))), "{e}");
    // Groups that do not add up to the chunk area: trailing bytes or a truncated file.
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(refused(&longer), ContainerError::TrailingBytes { bytes: 1 }));
    let e = refused(&bytes[..bytes.len() - 1]);
    assert!(matches!(e, ContainerError::Truncated { .. }), "{e}");
    // A derived bit that the group's entries contradict.
    if let Some(f) = rows.iter().position(|r| r.derived) {
        let mut lying = rows.clone();
        lying[f].derived = false;
        let table = write_table(&lying);
        let mut b = bytes.clone();
        b[table_at..table_at + table_len].copy_from_slice(&table);
        b[24..28].copy_from_slice(&crc32fast::hash(&table).to_le_bytes());
        let e = refused(&b);
        assert!(matches!(e, ContainerError::Corrupt { ref what, .. } if what.starts_with(&format!("index group {f} ("))), "{e}");
    }
}
