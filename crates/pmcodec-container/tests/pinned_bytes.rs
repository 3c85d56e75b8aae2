//! The encoder's bytes on generated sequences, pinned: changes made for speed (the surface
//! grid's pruned search, each node posed once per palette, remembered compressions) must
//! write the same files. The pins were taken from the encoder before those changes; a change
//! that means to alter the bytes updates them and says why in its commit.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{EncodeOptions, QuantizationChoice, encode, encode_with_report};
use pmcodec_mesh::skin::bending_tube;
use pmcodec_mesh::skin_fit::{FitOptions, fit_skin};
use pmcodec_mesh::{Sequence, samples};

fn options(keyframe_interval: u32) -> EncodeOptions {
    EncodeOptions {
        build: pmcodec_hierarchy::BuildOptions { min_coarsest: 4, ..EncodeOptions::default().build },
        keyframe_interval,
        quantization: QuantizationChoice::Bits(12),
        // The frame-by-frame index these were pinned with (the banded one, the default since,
        // lays out the same chunks; "default options" below follows the default).
        chunk_flags: pmcodec_container::format::FLAGS,
        ..Default::default()
    }
}

fn fitted(mut seq: Sequence, bones: u32) -> Sequence {
    let (skin, _) = fit_skin(&seq, &FitOptions { bones: Some(bones), ..Default::default() }).expect("fit");
    seq.skin = Some(skin);
    seq
}

/// (length, CRC-32) of each case's file.
fn files() -> Vec<(&'static str, usize, u32)> {
    let cases: Vec<(&str, Sequence, EncodeOptions)> = vec![
        // A glTF-like exact skin: skinning predicts every band, coarse nodes sit at their
        // skinned positions, Joints chunks in their three codings.
        ("bending tube, skinned", bending_tube(16, 40, 24), options(4)),
        // A fitted skin, where the two predictions compete band by band.
        ("twisting tube, fitted", fitted(samples::twisting_tube(12, 24, 20), 8), options(8)),
        // No skin: coarse nodes on their surfaces' grid points.
        ("waving cloth", samples::waving_cloth(20, 14, 20), options(8)),
        ("waving cloth, default options", samples::waving_cloth(16, 12, 12), EncodeOptions::default()),
    ];
    cases
        .into_iter()
        .map(|(name, seq, opts)| {
            let bytes = encode(&seq, &opts, |_| {}).expect(name);
            (name, bytes.len(), crc32fast::hash(&bytes))
        })
        .collect()
}

#[test]
fn generated_files_keep_their_bytes() {
    let pinned: [(&str, usize, u32); 4] = [
        ("bending tube, skinned", 15502, 3084163941),
        ("twisting tube, fitted", 26861, 2643312668),
        ("waving cloth", 18881, 416585368),
        ("waving cloth, default options", 10255, 2844589417),
    ];
    let got = files();
    assert_eq!(got, pinned, "the encoder's bytes changed: {got:?}");
}

/// `encode` stops the default prediction's coding of a band once skinning's costs less;
/// `encode_with_report` codes it whole for its report: the same bytes, and the same choices.
#[test]
fn the_report_s_exact_coding_writes_the_same_bytes() {
    for (name, seq, opts) in [
        ("bending tube", bending_tube(12, 24, 12), options(4)),
        ("rigid parts, fitted", fitted(samples::rigid_parts(5, 12), 5), options(8)),
    ] {
        let fast = encode(&seq, &opts, |_| {}).expect(name);
        let (exact, report) = encode_with_report(&seq, &opts, |_| std::ops::ControlFlow::Continue(())).expect(name);
        assert_eq!(fast, exact, "{name}");
        assert!(report.skinned_bands > 0 && report.stored_bits < report.plain_bits, "{name}: {report:?}");
    }
}
