//! Older format versions still read. `tests/compat/v3-cloth-k1.pmc` was written by the version
//! 3 encoder (the fuzz corpus's `valid-cloth-k1` before version 4), `v4-cloth-affine-k4.pmc` by
//! the version 4 encoder with affine motion, `v5-cloth-k4.pmc` by the version 5 encoder with
//! its defaults (keyframe affine motion, breadth-first order). Each must verify, decode every
//! frame to the input within its quantization step, and cut as today's files do; today's
//! encoder, given the options those versions had, writes the same header choices. (Their
//! hierarchies are not compared: the encoder's clustering has changed since, levels anchored
//! by triangles and contractions checked for validity, which no decoder depends on.)
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{CutTarget, Decoder, EncodeOptions, Motion, QuantizationChoice, Reader, VertexOrder, encode, verify};

/// Decodes `old` (of format `version`) frame by frame against the cloth it was made from
/// (`frames` frames), and today's encoding of it with `opts`; returns today's bytes.
fn decodes_as_today(file: &str, version: u16, frames: u32, opts: &EncodeOptions) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compat").join(file);
    let old = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(u16::from_le_bytes([old[8], old[9]]), version, "{file} is version {version}");
    let seq = pmcodec_mesh::samples::waving_cloth(6, 5, frames);
    let new = encode(&seq, opts, |_| {}).expect("encode");
    let (a, b) = (Reader::open(old.as_slice()).expect("open old"), Reader::open(new.as_slice()).expect("open new"));
    verify(&a).expect("verify old");
    assert_eq!((a.header().motion, a.header().order), (opts.motion, opts.order));
    assert_eq!((a.header().quantization, a.header().frame_count), (b.header().quantization, frames));
    assert_eq!(a.header().level_sizes[0], b.header().level_sizes[0]);
    // Stored positions lie on the grid within a step of the true ones on every axis.
    let tolerance = a.header().quantization.step * 1.01;
    let (mut da, mut db) = (Decoder::new(a.borrowed(), 0).expect("decoder"), Decoder::new(b.borrowed(), 0).expect("decoder"));
    for f in 0..frames {
        da.seek(f).expect("old frame");
        db.seek(f).expect("new frame");
        for d in [&mut da, &mut db] {
            let full = d.mesh(CutTarget::Level(0)).expect("level 0");
            assert_eq!(full.triangles, seq.triangles, "{file} frame {f}: triangles");
            for (v, (p, t)) in full.positions.iter().zip(&seq.frames[f as usize]).enumerate() {
                assert!((*p - *t).abs().max_element() <= tolerance, "{file} frame {f} vertex {v}: {p} for {t}");
            }
            let cut = d.mesh(CutTarget::Triangles(60)).expect("cut");
            assert!(!cut.triangles.is_empty() && cut.triangles.len() <= 60, "{file} frame {f}: {} triangles", cut.triangles.len());
        }
    }
    new
}

#[test]
fn version_5_files_decode_as_they_did() {
    let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    assert_eq!((opts.motion, opts.order), (Motion::KeyframeAffine, VertexOrder::BreadthFirst));
    decodes_as_today("v5-cloth-k4.pmc", 5, 6, &opts);
}

#[test]
fn version_4_affine_files_decode_as_they_did() {
    let opts = EncodeOptions {
        keyframe_interval: 4,
        quantization: QuantizationChoice::Bits(12),
        motion: Motion::Affine,
        order: VertexOrder::Input,
        ..Default::default()
    };
    decodes_as_today("v4-cloth-affine-k4.pmc", 4, 6, &opts);
}

#[test]
fn version_3_files_decode_as_they_did() {
    let opts = EncodeOptions {
        keyframe_interval: 1,
        quantization: QuantizationChoice::Bits(12),
        motion: Motion::Mean,
        order: VertexOrder::Input,
        ..Default::default()
    };
    let new = decodes_as_today("v3-cloth-k1.pmc", 3, 4, &opts);
    // Versions outside the readable range are refused by name.
    let mut future = new.clone();
    future[8] = 9;
    let e = Reader::open(future.as_slice()).err().expect("version 9 refused").to_string();
    assert!(e.contains("version 9 is not supported") && e.contains("3 to 7"), "{e}");
}

/// `tests/compat/v6-textured-cloth-k4.pmc`: the version 6 encoder's textured cloth (UVs,
/// colours, two materials, a PNG), the file the TypeScript decoder's appearance is checked on
/// (web/test/container.test.ts). It must verify and decode, appearance included, to what
/// today's encoder makes of the same input; but for coarse nodes' texture coordinates and
/// colours: since the represented values (proto/container.md, "Attributes", mode | 16) a coarse
/// value is one of its children's input values where version 6 stored their mean, so cuts
/// showing nodes above level 0 compare all but those values. Today's file is made with
/// `surface_grid` off, as the coarse positions were chosen then.
#[test]
fn version_6_textured_files_decode_as_they_did() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compat/v6-textured-cloth-k4.pmc");
    let seq = pmcodec_mesh::samples::textured_cloth(10, 7, 6, 8);
    // Coarse nodes where version 6 stored them (the surface grid chooses other grid points,
    // which the decoder reads alike): the same positions, so the cuts compare whole.
    let opts =
        EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), surface_grid: false, ..Default::default() };
    let new = encode(&seq, &opts, |_| {}).expect("encode");
    let old = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(u16::from_le_bytes([old[8], old[9]]), 6);
    let (a, b) = (Reader::open(old.as_slice()).expect("open old"), Reader::open(new.as_slice()).expect("open new"));
    verify(&a).expect("verify");
    assert_eq!(a.header().appearance, b.header().appearance);
    for level in [0, 1] {
        let (mut da, mut db) = (Decoder::new(a.borrowed(), level).unwrap(), Decoder::new(b.borrowed(), level).unwrap());
        for f in 0..6 {
            da.seek(f).unwrap();
            db.seek(f).unwrap();
            for target in [CutTarget::Triangles(40), CutTarget::Level(level)] {
                let (mut old, mut new) = (da.textured_mesh(target).expect("old"), db.textured_mesh(target).expect("new"));
                if target != CutTarget::Level(0) {
                    for app in [&mut old.1, &mut new.1] {
                        assert_eq!(app.uv0.len(), app.colors.len(), "level {level} frame {f} {target:?}");
                        app.uv0.clear();
                        app.colors.clear();
                    }
                }
                assert_eq!(old, new, "level {level} frame {f} {target:?}");
            }
        }
    }
}

/// Today's file as version 6 wrote it: the header and the chunks are the same but for the
/// Triangles and Key chunks (plain ids) and the index (postcard, every entry whole).
fn as_version_6(v7: &[u8]) -> Vec<u8> {
    use pmcodec_container::format::{FLAGS, Index, PREAMBLE_LEN, Preamble, ZSTD_LEVEL, store_chunk};
    use pmcodec_container::{ChunkKind, payload};
    let r = Reader::open(v7).expect("open");
    let h = r.header();
    let pre = Preamble::parse(v7).expect("preamble");
    let header = &v7[PREAMBLE_LEN..PREAMBLE_LEN + pre.header_len as usize];
    let (mut area, mut entries) = (Vec::new(), Vec::new());
    let mut first_keys = std::collections::HashMap::new();
    for e in &r.index().chunks {
        let mut raw = r.read_chunk(e).expect("chunk");
        if e.kind == ChunkKind::Triangles {
            let t = payload::read_triangles(&raw, "t", h.triangle_count, h.vertex_count, 7).expect("triangles");
            raw = payload::write_triangles(&t, 6);
        }
        if e.kind == ChunkKind::Key {
            // Later keyframes may list their changes from frame 0's parents (Key coding 3).
            let first = first_keys.get(&e.band).map(Vec::as_slice);
            let parent = payload::read_key_from(&raw, "t", &h.level_sizes, e.band as usize, 7, first).expect("key");
            if e.frame == 0 {
                first_keys.insert(e.band, parent.clone());
            }
            raw = payload::write_key(&parent, 6);
        }
        let stored = store_chunk(&raw, ZSTD_LEVEL, FLAGS).expect("zstd");
        let offset = area.len() as u64;
        entries.push(pmcodec_container::ChunkEntry {
            offset,
            stored_len: stored.len() as u32,
            raw_len: raw.len() as u32,
            crc32: crc32fast::hash(&stored),
            ..*e
        });
        area.extend_from_slice(&stored);
    }
    let index = Index { chunks: entries }.to_bytes(6, h.frame_count).expect("index");
    let pre = Preamble { version: 6, index_len: index.len() as u32, index_crc: crc32fast::hash(&index), ..pre };
    [&pre.to_bytes()[..], header, &index, &area].concat()
}

/// `tests/compat/v6-cloth-k4.pmc`: the version 6 encoder's cloth with its defaults and both
/// preamble flags (small chunks stored as they are, empty Delta and Corners chunks left out),
/// its index postcard, its triangles and parents plain ids (version 7 codes them compactly, issue 17). It
/// must read as it did; and today's file rewritten as version 6 reads as the same entries,
/// chunks and meshes.
/// (`PMCODEC_WRITE_V6_FIXTURE=1` writes it anew from today's encoding, its index as version 6's.)
#[test]
fn version_6_files_decode_as_they_did() {
    let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compat/v6-cloth-k4.pmc");
    if std::env::var_os("PMCODEC_WRITE_V6_FIXTURE").is_some() {
        let new = encode(&pmcodec_mesh::samples::waving_cloth(6, 5, 6), &opts, |_| {}).expect("encode");
        std::fs::write(&path, as_version_6(&new)).expect("write the fixture");
    }
    let new = decodes_as_today("v6-cloth-k4.pmc", 6, 6, &opts);
    let old = std::fs::read(&path).expect("fixture");
    use pmcodec_container::format::{FLAG_SPARSE, FLAG_STORED};
    assert_eq!(u16::from_le_bytes([old[10], old[11]]), FLAG_STORED | FLAG_SPARSE, "both flags");
    let a = Reader::open(old.as_slice()).expect("open old");
    assert!(a.index().chunks.len() < 4 * 6 * a.header().levels(), "empty chunks left out: {}", a.index().chunks.len());
    // The same entries through either index; the version 7 one is the smaller.
    let b = Reader::open(new.as_slice()).expect("open new");
    assert_eq!(b.version(), 7);
    let v6 = as_version_6(&new);
    let c = Reader::open(v6.as_slice()).expect("open as version 6");
    assert_eq!(c.version(), 6);
    assert_eq!(c.index().chunks.len(), b.index().chunks.len());
    for (x, y) in c.index().chunks.iter().zip(&b.index().chunks) {
        assert_eq!((x.kind, x.frame, x.band), (y.kind, y.frame, y.band));
        if !matches!(x.kind, pmcodec_container::ChunkKind::Triangles | pmcodec_container::ChunkKind::Key) {
            assert_eq!(c.read_chunk(x).expect("old chunk"), b.read_chunk(y).expect("new chunk"));
        }
    }
    verify(&c).expect("verify as version 6");
    let (mut dc, mut db) = (Decoder::new(c.borrowed(), 0).expect("decoder"), Decoder::new(b.borrowed(), 0).expect("decoder"));
    dc.seek(5).expect("old frame");
    db.seek(5).expect("new frame");
    // The keyframe's parent maps too: a cut through the hierarchy is the same.
    for target in [CutTarget::Level(0), CutTarget::Triangles(60)] {
        assert_eq!(dc.mesh(target).expect("old"), db.mesh(target).expect("new"), "{target:?}");
    }
    assert!(v6.len() > new.len() + 4 * b.index().chunks.len(), "{} against {} bytes", v6.len(), new.len());
    let v6_triangles = c.index().chunks[0].stored_len;
    assert!(v6_triangles > b.index().chunks[0].stored_len, "triangles: {v6_triangles} against {}", b.index().chunks[0].stored_len);
}

/// `tests/compat/v6-skinned-palette-tube-k4.pmc`: a skinned bending tube written with Palette
/// chunks (kind 12), as the encoder wrote skinned files before the Joints chunk; the TypeScript
/// decoder reads it too (web/test/container.test.ts). It must verify, hold Palette chunks and
/// no Joints chunk, decode every frame to the input within the quantization bound, and a
/// level-1 client must decode the bands it reads as a full one does.
/// Written by the encoder of commit 3219420 (format version 6, `PaletteCoding::Palette`); today's
/// encoder writes version 7, so the file cannot be made anew and is not: it is what old readers' files look like.
#[test]
fn version_6_palette_chunk_files_decode_as_they_did() {
    use pmcodec_container::ChunkKind;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compat/v6-skinned-palette-tube-k4.pmc");
    let seq = pmcodec_mesh::skin::bending_tube(8, 12, 10);
    let old = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(u16::from_le_bytes([old[8], old[9]]), 6, "the palette fixture is version 6");
    let a = Reader::open(old.as_slice()).expect("open");
    verify(&a).expect("verify");
    assert!(a.index().chunks.iter().any(|e| e.kind == ChunkKind::Palette));
    assert!(a.index().chunks.iter().all(|e| !matches!(e.kind, ChunkKind::Joints | ChunkKind::Pose)));
    let h = a.header().clone();
    let bound = h.quantization.step * 0.5 * 3f32.sqrt() * 1.01;
    let (mut full, mut coarse) = (Decoder::new(a.borrowed(), 0).expect("decoder"), Decoder::new(a.borrowed(), 1).expect("decoder"));
    let from = h.level_sizes[0] as usize;
    for f in 0..h.frame_count {
        full.seek(f).expect("frame");
        coarse.seek(f).expect("coarse frame");
        let mesh = full.mesh(CutTarget::Level(0)).expect("mesh");
        for (v, (p, t)) in mesh.positions.iter().zip(&seq.frames[f as usize]).enumerate() {
            assert!((*p - *t).abs().max_element() <= bound, "frame {f} vertex {v}: {p} for {t}");
        }
        assert_eq!(coarse.quantized()[from..], full.quantized()[from..], "frame {f}");
    }
}
