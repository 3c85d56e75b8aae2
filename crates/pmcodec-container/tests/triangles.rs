//! The Triangles chunk's coding 1 (proto/container.md, "Triangles"): a Faces chunk's bit coding
//! of every input triangle, which the encoder keeps where it stores shorter than the varint
//! differences. Generated meshes: a cloth, a twisting tube, rigid parts (many disconnected
//! pieces), a Loop-subdivided tube (edge vertices numbered after the old ones, which is where
//! coding 1 pays) and a tube with its vertices renumbered at random; each must read back as the
//! very triangles written, a whole file must decode, and damaged payloads must be refused.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::payload::{read_triangles, write_triangles_best};
use pmcodec_container::{ChunkKind, EncodeOptions, QuantizationChoice, Reader, encode, verify};
use pmcodec_mesh::Sequence;

/// A tube whose vertex ids are shuffled (a fixed linear congruential permutation).
fn shuffled_tube() -> Sequence {
    let mut seq = pmcodec_mesh::samples::twisting_tube(24, 12, 3);
    let n = seq.vertex_count();
    let mut order: Vec<usize> = (0..n).collect();
    let mut s = 12345u64;
    for i in (1..n).rev() {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        order.swap(i, (s >> 33) as usize % (i + 1));
    }
    let mut new_id = vec![0u32; n];
    for (new, &old) in order.iter().enumerate() {
        new_id[old] = new as u32;
    }
    for t in &mut seq.triangles {
        for c in t.iter_mut() {
            *c = new_id[*c as usize];
        }
    }
    for f in &mut seq.frames {
        let old = f.clone();
        for (i, &o) in order.iter().enumerate() {
            f[i] = old[o];
        }
    }
    seq
}

fn meshes() -> Vec<(&'static str, Sequence)> {
    vec![
        ("cloth", pmcodec_mesh::samples::waving_cloth(14, 12, 3)),
        ("parts", pmcodec_mesh::samples::rigid_parts(9, 3)),
        ("tube", pmcodec_mesh::samples::twisting_tube(16, 10, 3)),
        ("subdivided tube", pmcodec_eval::made::loop_subdivide(&pmcodec_mesh::samples::twisting_tube(12, 8, 3))),
        ("shuffled tube", shuffled_tube()),
    ]
}

#[test]
fn triangles_read_back_in_the_coding_the_encoder_keeps() {
    let mut coded = Vec::new();
    for (name, seq) in meshes() {
        let (t, v) = (seq.triangles.len() as u32, seq.vertex_count() as u32);
        let raw = write_triangles_best(&seq.triangles, v);
        assert_eq!(read_triangles(&raw, "t", t, v, 7).unwrap(), seq.triangles, "{name}");
        if raw[0] == 0 {
            assert_eq!(raw[1], 1, "{name}: coding 1");
            coded.push(name);
        }
        // A reader told of another triangle count or fewer vertices refuses it.
        assert!(read_triangles(&raw, "t", t + 1, v, 7).is_err(), "{name}");
        assert!(read_triangles(&raw, "t", t - 1, v, 7).is_err(), "{name}");
        let top = seq.triangles.iter().flatten().copied().max().unwrap();
        assert!(read_triangles(&raw, "t", t, top, 7).is_err(), "{name}");
    }
    // Where numbering jumps, the recently used vertices pay.
    assert!(coded.contains(&"subdivided tube") && coded.contains(&"shuffled tube"), "coded: {coded:?}");
}

#[test]
fn files_with_coded_triangles_decode() {
    let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    for (name, seq) in meshes().into_iter().skip(3) {
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let r = Reader::open(bytes.as_slice()).expect("open");
        let e = r.index().chunks.iter().find(|e| e.kind == ChunkKind::Triangles).unwrap();
        let raw = r.read_chunk(e).unwrap();
        assert_eq!(&raw[..2], &[0, 1], "{name}: coding 1");
        let h = r.header();
        assert_eq!(read_triangles(&raw, "t", h.triangle_count, h.vertex_count, r.version()).unwrap(), seq.triangles, "{name}");
        verify(&r).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn damaged_coded_triangles_are_refused() {
    let seq = shuffled_tube();
    let (t, v) = (seq.triangles.len() as u32, seq.vertex_count() as u32);
    let raw = write_triangles_best(&seq.triangles, v);
    assert_eq!(&raw[..2], &[0, 1]);
    // Another coding byte.
    for coding in [0u8, 2, 3, 0x81] {
        let mut bad = raw.clone();
        bad[1] = coding;
        assert!(read_triangles(&bad, "t", t, v, 7).is_err(), "coding {coding}");
    }
    // Cut short anywhere, or with a byte after its end: an error, never a panic.
    for len in 2..raw.len() {
        assert!(read_triangles(&raw[..len], "t", t, v, 7).is_err(), "cut at {len}");
    }
    let mut long = raw.clone();
    long.push(1);
    assert!(read_triangles(&long, "t", t, v, 7).is_err());
    // Flipped bits never panic; most are refused, any accepted reads its triangle count.
    for i in 2..raw.len() {
        for b in 0..8 {
            let mut bad = raw.clone();
            bad[i] ^= 1 << b;
            if let Ok(tris) = read_triangles(&bad, "t", t, v, 7) {
                assert_eq!(tris.len(), t as usize);
                assert!(tris.iter().flatten().all(|&c| c < v));
            }
        }
    }
}
