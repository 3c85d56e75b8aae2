//! Sequences without a skeleton, given a skin by the skinning decomposition
//! (`pmcodec_mesh::skin_fit`, Le & Deng's SSDR), round trip through the container within the
//! quantization bound at every frame, and piecewise-rigid motion costs fewer bytes with it.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{Decoder, EncodeOptions, QuantizationChoice, Reader, encode, encode_with_report, summary, verify};
use pmcodec_hierarchy::CutTarget;
use pmcodec_mesh::skin_fit::{FitOptions, fit_skin};
use pmcodec_mesh::{Sequence, samples};

fn options() -> EncodeOptions {
    EncodeOptions {
        build: pmcodec_hierarchy::BuildOptions { min_coarsest: 4, ..EncodeOptions::default().build },
        keyframe_interval: 8,
        quantization: QuantizationChoice::Bits(12),
        ..Default::default()
    }
}

/// Every frame decodes at full resolution within the quantization bound of the input.
fn within_bound(seq: &Sequence, bytes: &[u8]) {
    let r = Reader::open(bytes).expect("open");
    verify(&r).expect("verify");
    let h = r.header().clone();
    let bound = h.quantization.step * 0.5 * 3f32.sqrt() * 1.01;
    let mut d = Decoder::new(r.borrowed(), 0).expect("decoder");
    for f in 0..h.frame_count {
        d.seek(f).expect("frame");
        let mesh = d.mesh(CutTarget::Level(0)).expect("mesh");
        for (v, (a, b)) in mesh.positions.iter().zip(&seq.frames[f as usize]).enumerate() {
            assert!((*a - *b).length() <= bound, "frame {f} vertex {v}: {a} for {b} (bound {bound})");
        }
    }
}

fn fitted(mut seq: Sequence, bones: u32) -> Sequence {
    let (skin, _) = fit_skin(&seq, &FitOptions { bones: Some(bones), ..Default::default() }).expect("fit");
    seq.skin = Some(skin);
    seq
}

#[test]
fn fitted_skins_round_trip_within_the_bound() {
    for (name, seq, bones) in [
        ("rigid parts", samples::rigid_parts(5, 20), 5),
        ("twisting tube", samples::twisting_tube(12, 24, 20), 8),
        ("waving cloth", samples::waving_cloth(20, 14, 20), 6),
    ] {
        let seq = fitted(seq, bones);
        let (bytes, report) = encode_with_report(&seq, &options(), |_| std::ops::ControlFlow::Continue(())).expect(name);
        let r = Reader::open(bytes.as_slice()).expect("open");
        assert!(r.header().skin.is_some(), "{name}");
        assert!(report.stored_bits <= report.plain_bits && report.bands > 0, "{name}: {report:?}");
        within_bound(&seq, &bytes);
    }
}

#[test]
fn rigid_parts_cost_less_with_a_fitted_skin() {
    let plain = samples::rigid_parts(6, 24);
    let seq = fitted(plain.clone(), 6);
    let (skinned, report) = encode_with_report(&seq, &options(), |_| std::ops::ControlFlow::Continue(())).expect("encode");
    let without = encode(&plain, &options(), |_| {}).expect("encode plain");
    // Every band of every frame but the first is predicted by skinning: the parts are rigid.
    assert!(report.skinned_bands * 10 >= report.bands * 9, "{report:?}");
    let (s, p) = (summary(&Reader::open(skinned.as_slice()).unwrap()), summary(&Reader::open(without.as_slice()).unwrap()));
    assert!(
        s.positions_bits_per_vertex_frame * 2.0 < p.positions_bits_per_vertex_frame,
        "positions {} bits/vertex/frame skinned, {} without",
        s.positions_bits_per_vertex_frame,
        p.positions_bits_per_vertex_frame
    );
    assert!(skinned.len() < without.len(), "{} bytes skinned, {} without", skinned.len(), without.len());
}

/// The trial before the encode (`skin_trial`: band 0 coded both ways on a sample of keyframe
/// intervals) keeps a fitted skin exactly where the file with it is smaller than the file
/// without it: on rigid parts (which it must keep) and on a waving cloth and a twisting tube
/// (bent, not rigid: a skin of their few bones predicts them about as well as their neighbours
/// do, for its pose bytes every frame).
#[test]
fn the_trial_keeps_the_skin_where_the_file_with_it_is_smaller() {
    use pmcodec_container::skin_trial;
    for (name, plain, bones) in [
        ("rigid parts", samples::rigid_parts(6, 24), 6),
        ("waving cloth", samples::waving_cloth(24, 16, 24), 12),
        ("twisting tube", samples::twisting_tube(12, 24, 24), 12),
    ] {
        let seq = fitted(plain.clone(), bones);
        let trial = skin_trial(&seq, &options()).expect(name);
        assert_eq!(trial.frames, 24, "{name}");
        // Keyframes every 8 frames: the first and the last interval.
        assert_eq!(trial.frames_coded, 16, "{name}");
        assert!(trial.plain_bytes > 0 && trial.skinned_bytes > 0 && trial.pose_bytes > 0 && trial.bind_bytes > 0, "{name}: {trial:?}");
        let with = encode(&seq, &options(), |_| {}).expect(name).len();
        let without = encode(&plain, &options(), |_| {}).expect(name).len();
        assert_eq!(trial.pays(), with < without, "{name}: {trial:?}, {with} bytes with the skin, {without} without");
        if name == "rigid parts" {
            assert!(trial.pays(), "{trial:?}");
        }
    }
    // A sequence without a skin has nothing to try.
    assert!(skin_trial(&samples::rigid_parts(2, 4), &options()).is_err());
}
