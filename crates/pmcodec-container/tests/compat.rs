//! Older format versions still read. `tests/compat/v3-cloth-k1.pmc` was written by the version
//! 3 encoder (the fuzz corpus's `valid-cloth-k1` before version 4), `v4-cloth-affine-k4.pmc` by
//! the version 4 encoder with affine motion, `v5-cloth-k4.pmc` by the version 5 encoder with
//! its defaults (keyframe affine motion, breadth-first order). Each must verify and decode to
//! exactly what today's encoder makes of the same input with the options those versions had
//! (band 0 in input order and mean motion or affine; version 5's defaults), frame by frame.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{Decoder, EncodeOptions, MeshTarget, Motion, QuantizationChoice, Reader, VertexOrder, encode, verify};

/// Decodes `old` (of format `version`) and today's encoding of the cloth (`frames` frames) with
/// `opts`, and compares them frame by frame.
fn decodes_as_today(file: &str, version: u16, frames: u32, opts: &EncodeOptions) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compat").join(file);
    let old = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(u16::from_le_bytes([old[8], old[9]]), version, "{file} is version {version}");
    let seq = pmcodec_mesh::samples::waving_cloth(6, 5, frames);
    let new = encode(&seq, opts, |_| {}).expect("encode");
    let (a, b) = (Reader::open(old.as_slice()).expect("open old"), Reader::open(new.as_slice()).expect("open new"));
    verify(&a).expect("verify old");
    assert_eq!((a.header().motion, a.header().order), (opts.motion, opts.order));
    // The headers differ only in what names the encoder.
    assert_eq!(
        (&a.header().level_sizes, a.header().quantization, a.header().frame_count),
        (&b.header().level_sizes, b.header().quantization, frames)
    );
    let (mut da, mut db) = (Decoder::new(a.borrowed(), 0).expect("decoder"), Decoder::new(b.borrowed(), 0).expect("decoder"));
    for f in 0..frames {
        da.seek(f).expect("old frame");
        db.seek(f).expect("new frame");
        assert_eq!(da.replay().expect("replay").h, db.replay().expect("replay").h, "{file} frame {f}: hierarchy");
        assert_eq!(da.quantized(), db.quantized(), "{file} frame {f}: positions");
        assert_eq!(da.mesh(MeshTarget::Triangles(60)).expect("cut"), db.mesh(MeshTarget::Triangles(60)).expect("cut"), "frame {f}");
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
    assert!(e.contains("version 9 is not supported") && e.contains("3 to 5"), "{e}");
}
