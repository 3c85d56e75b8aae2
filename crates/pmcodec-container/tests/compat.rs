//! Older format versions still read: `tests/compat/v3-cloth-k1.pmc` was written by the version 3
//! encoder (the fuzz corpus's `valid-cloth-k1` before version 4). It must verify and decode to
//! exactly what today's encoder makes of the same input with the mean motion, frame by frame.

use pmcodec_container::{Decoder, EncodeOptions, MeshTarget, Motion, QuantizationChoice, Reader, encode, verify};

#[test]
fn version_3_files_decode_as_they_did() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/compat/v3-cloth-k1.pmc");
    let old = std::fs::read(&path).expect("tests/compat/v3-cloth-k1.pmc");
    assert_eq!(u16::from_le_bytes([old[8], old[9]]), 3, "the file is version 3");
    let seq = pmcodec_mesh::samples::waving_cloth(6, 5, 4);
    let opts = EncodeOptions { keyframe_interval: 1, quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let new = encode(&seq, &opts, |_| {}).expect("encode");
    let (a, b) = (Reader::open(old.as_slice()).expect("open v3"), Reader::open(new.as_slice()).expect("open v4"));
    verify(&a).expect("verify v3");
    assert_eq!(a.header().motion, Motion::Mean);
    // The headers differ only in what names the encoder.
    assert_eq!(
        (&a.header().level_sizes, a.header().quantization, a.header().frame_count),
        (&b.header().level_sizes, b.header().quantization, 4)
    );
    let (mut da, mut db) = (Decoder::new(a.borrowed(), 0).expect("decoder"), Decoder::new(b.borrowed(), 0).expect("decoder"));
    for f in 0..4 {
        da.seek(f).expect("v3 frame");
        db.seek(f).expect("v4 frame");
        assert_eq!(da.replay().expect("replay").h, db.replay().expect("replay").h, "frame {f}: hierarchy");
        assert_eq!(da.quantized(), db.quantized(), "frame {f}: positions");
        assert_eq!(da.mesh(MeshTarget::Triangles(60)).expect("cut"), db.mesh(MeshTarget::Triangles(60)).expect("cut"), "frame {f}");
    }
    // Versions outside the readable range are refused by name.
    let mut future = new.clone();
    future[8] = 9;
    let e = Reader::open(future.as_slice()).err().expect("version 9 refused").to_string();
    assert!(e.contains("version 9 is not supported") && e.contains("3 to 4"), "{e}");
}
