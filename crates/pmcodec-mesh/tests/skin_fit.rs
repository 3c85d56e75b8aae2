//! The skinning decomposition (SSDR) recovers a known rigid-bone animation, is deterministic,
//! and gives a valid skin or a clear error on degenerate input.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::{Mat4, Quat, Vec3};
use pmcodec_mesh::skin_fit::{FitError, FitOptions, fit_skin};
use pmcodec_mesh::{Sequence, SequenceSkin, samples};

fn rows(m: &Mat4) -> [f32; 12] {
    let r = m.transpose().to_cols_array();
    [r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10], r[11]]
}

/// A tube along +Y skinned by three known bones (lower third, middle, upper third, with
/// blends between), each bone's transform a rotation about a joint plus a small drift.
fn three_bone_tube(frames: u32) -> Sequence {
    let mut seq = samples::twisting_tube(16, 24, 1);
    let rest = seq.frames[0].clone();
    let n = rest.len();
    let mut skin = SequenceSkin {
        palette_len: 3,
        palette_names: vec!["a".into(), "b".into(), "c".into()],
        rest: rest.clone(),
        joints: vec![[0, 1, 2, 0]; n],
        weights: Vec::with_capacity(n),
        ..Default::default()
    };
    for p in &rest {
        // Height 0..4: bone a below 1.2, c above 2.8, b between, with linear blends 0.4 wide.
        let t1 = ((p.y - 1.2) / 0.4).clamp(0.0, 1.0);
        let t2 = ((p.y - 2.6) / 0.4).clamp(0.0, 1.0);
        skin.weights.push([1.0 - t1, t1 - t2, t2, 0.0]);
    }
    let joint = |y: f32| Mat4::from_translation(Vec3::new(0.0, y, 0.0));
    for f in 0..frames {
        let s = f as f32 / frames as f32 * std::f32::consts::TAU;
        let a = Mat4::from_translation(Vec3::new(0.1 * s.sin(), 0.0, 0.0));
        let b = a * joint(1.4) * Mat4::from_quat(Quat::from_rotation_z(0.6 * s.sin())) * joint(1.4).inverse();
        let c = b * joint(2.8) * Mat4::from_quat(Quat::from_rotation_x(0.8 * (2.0 * s).sin())) * joint(2.8).inverse();
        skin.matrices.push(vec![rows(&a), rows(&b), rows(&c)]);
    }
    // Frame 0 is the rest pose in the fit: start the animation there.
    skin.matrices[0] = vec![rows(&Mat4::IDENTITY); 3];
    seq.frames = (0..frames as usize).map(|f| (0..n).map(|v| skin.pose_vertex(f, v)).collect()).collect();
    seq.frame_names = (0..frames).map(|f| format!("three-bones@{f}")).collect();
    seq
}

fn worst_error(seq: &Sequence, skin: &SequenceSkin) -> f32 {
    let mut worst = 0.0f32;
    for f in 0..seq.frame_count() {
        for v in 0..seq.vertex_count() {
            worst = worst.max((skin.pose_vertex(f, v) - seq.frames[f][v]).length());
        }
    }
    worst
}

#[test]
fn recovers_a_three_bone_animation() {
    let seq = three_bone_tube(24);
    let (skin, report) = fit_skin(&seq, &FitOptions { bones: Some(3), ..Default::default() }).unwrap();
    skin.validate(seq.vertex_count(), seq.frame_count()).unwrap();
    assert!(skin.palette_len <= 3);
    let diag = seq.bounds().map(|(lo, hi)| (hi - lo).length()).unwrap();
    let worst = worst_error(&seq, &skin);
    // The blends are exactly linear blend skinning of three rigid bones; a fit that found the
    // bones reproduces every vertex to a small fraction of the size.
    assert!(report.rms_error < 2e-3, "{report:?}");
    assert!(worst < 0.02 * diag, "worst {worst} of diagonal {diag}");
    assert!((report.max_error - (worst / diag) as f64).abs() < 1e-3, "{report:?} vs {worst}");
    // The matrices are rigid: orthonormal linear parts.
    for frame in &skin.matrices {
        for m in frame {
            let l = glam::Mat3::from_cols_array(&[m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]]);
            assert!((l.determinant() - 1.0).abs() < 1e-4);
            assert!((l * l.transpose() - glam::Mat3::IDENTITY).abs().to_cols_array().iter().all(|&x| x < 1e-4));
        }
    }
}

#[test]
fn one_bone_per_rigid_part() {
    let seq = samples::rigid_parts(4, 12);
    let (skin, report) = fit_skin(&seq, &FitOptions { bones: Some(4), ..Default::default() }).unwrap();
    assert!(report.max_error < 1e-4, "{report:?}");
    // Every vertex is on one bone only, the same one for all vertices of a part.
    let per_part = seq.vertex_count() / 4;
    for p in 0..4 {
        let b = skin.joints[p * per_part][0];
        for v in p * per_part..(p + 1) * per_part {
            assert_eq!(skin.joints[v][0], b, "part {p} vertex {v}");
            assert!(skin.weights[v][0] > 0.999, "vertex {v}: {:?}", skin.weights[v]);
        }
    }
}

#[test]
fn fits_are_deterministic_and_better_with_more_bones() {
    let seq = samples::twisting_tube(12, 20, 16);
    let opts = FitOptions { bones: Some(6), ..Default::default() };
    let (a, ra) = fit_skin(&seq, &opts).unwrap();
    let (b, rb) = fit_skin(&seq, &opts).unwrap();
    assert_eq!(a, b);
    assert_eq!(ra, rb);
    let (_, one) = fit_skin(&seq, &FitOptions { bones: Some(1), ..Default::default() }).unwrap();
    assert!(ra.rms_error < 0.5 * one.rms_error, "6 bones {ra:?}, 1 bone {one:?}");
}

#[test]
fn one_frame_and_degenerate_geometry() {
    // One frame: the rest pose itself, reproduced exactly.
    let seq = samples::waving_cloth(6, 5, 1);
    let (skin, report) = fit_skin(&seq, &FitOptions::default()).unwrap();
    skin.validate(seq.vertex_count(), 1).unwrap();
    assert!(report.max_error < 1e-9, "{report:?}");
    // Every vertex at one point in every frame: a valid skin, no NaN.
    let mut flat = samples::waving_cloth(4, 4, 5);
    for frame in &mut flat.frames {
        for p in frame.iter_mut() {
            *p = Vec3::new(1.0, 2.0, 3.0);
        }
    }
    let (skin, _) = fit_skin(&flat, &FitOptions { bones: Some(8), ..Default::default() }).unwrap();
    skin.validate(flat.vertex_count(), flat.frame_count()).unwrap();
    // Collinear points moving along their line.
    let mut line = samples::waving_cloth(4, 4, 5);
    for (f, frame) in line.frames.iter_mut().enumerate() {
        for (v, p) in frame.iter_mut().enumerate() {
            *p = Vec3::new(v as f32 + f as f32, 0.0, 0.0);
        }
    }
    let (skin, report) = fit_skin(&line, &FitOptions { bones: Some(3), ..Default::default() }).unwrap();
    skin.validate(line.vertex_count(), line.frame_count()).unwrap();
    assert!(report.max_error < 1e-5, "{report:?}");
}

#[test]
fn bad_input_and_options_are_refused() {
    let seq = samples::twisting_tube(6, 4, 3);
    assert!(matches!(fit_skin(&seq, &FitOptions { bones: Some(0), ..Default::default() }), Err(FitError::Bones(0))));
    let e = fit_skin(&seq, &FitOptions { bones: Some(100_000), ..Default::default() }).unwrap_err();
    assert!(e.to_string().contains("100000 bones"), "{e}");
    let mut bad = seq.clone();
    bad.frames[2][5].x = f32::NAN;
    let e = fit_skin(&bad, &FitOptions::default()).unwrap_err();
    assert!(matches!(e, FitError::Invalid(_)) && e.to_string().contains("vertex 5"), "{e}");
    let e = fit_skin(&Sequence::default(), &FitOptions::default()).unwrap_err();
    assert!(matches!(e, FitError::Invalid(_)), "{e}");
}
