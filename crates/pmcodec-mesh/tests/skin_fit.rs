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

/// Two rigid parts of one surface with known motion, split at a plane: every vertex moves by
/// one of two rigid transforms exactly.
fn two_rigid_halves(frames: u32) -> (Sequence, Vec<bool>) {
    let mut seq = samples::twisting_tube(10, 16, 1);
    let rest = seq.frames[0].clone();
    let upper: Vec<bool> = rest.iter().map(|p| p.y > 2.0).collect();
    seq.frames = (0..frames)
        .map(|f| {
            let s = f as f32 / frames as f32 * std::f32::consts::TAU;
            let a = Mat4::from_translation(Vec3::new(0.2 * s.sin(), 0.1 * s.cos() - 0.1, 0.0));
            let pivot = Vec3::new(0.0, 2.0, 0.0);
            let b = Mat4::from_translation(pivot + Vec3::new(0.0, 0.0, 0.3 * s.sin()))
                * Mat4::from_quat(Quat::from_euler(glam::EulerRot::XYZ, 0.9 * s.sin(), 0.4 * s.sin(), 0.7 * (2.0 * s).sin()))
                * Mat4::from_translation(-pivot);
            rest.iter().zip(&upper).map(|(&p, &u)| if u { b.transform_point3(p) } else { a.transform_point3(p) }).collect()
        })
        .collect();
    seq.frame_names = (0..frames).map(|f| format!("two-halves@{f}")).collect();
    (seq, upper)
}

#[test]
fn recovers_two_rigid_parts_with_the_default_bone_count() {
    let (seq, upper) = two_rigid_halves(20);
    // Not told how many bones: the default has more than the two parts need; the fit must
    // still reproduce every vertex (spare bones are rigid copies or dropped), with one bone
    // per vertex and no vertex of one part on a bone that also carries the other part.
    let (skin, report) = fit_skin(&seq, &FitOptions::default()).unwrap();
    skin.validate(seq.vertex_count(), seq.frame_count()).unwrap();
    assert!(report.max_error < 1e-4, "{report:?}");
    let mut part_of_bone: Vec<Option<bool>> = vec![None; skin.palette_len as usize];
    for (v, &u) in upper.iter().enumerate() {
        for (&j, &w) in skin.joints[v].iter().zip(&skin.weights[v]) {
            if w > 1e-3 {
                let seen = part_of_bone[j as usize].get_or_insert(u);
                assert_eq!(*seen, u, "bone {j} moves vertices of both parts");
            }
        }
    }
}

#[test]
fn a_static_sequence_fits_exactly() {
    // Every vertex still in every frame: the identity reproduces it exactly.
    let mut still = samples::waving_cloth(5, 4, 6);
    let first = still.frames[0].clone();
    for frame in &mut still.frames {
        frame.clone_from(&first);
    }
    let (skin, report) = fit_skin(&still, &FitOptions::default()).unwrap();
    skin.validate(still.vertex_count(), still.frame_count()).unwrap();
    assert!(report.max_error < 1e-9, "{report:?}");
}

#[test]
fn the_bone_count_is_chosen_by_cost() {
    // Two rigid halves: the default count already reproduces every vertex, so doubling it only
    // adds bones to pay for: the choice stays at the default (4 for so few vertices).
    let (seq, _) = two_rigid_halves(12);
    let (skin, report) = fit_skin(&seq, &FitOptions::default()).unwrap();
    assert!(skin.palette_len <= 4, "{report:?}");
    // A tube bending and twisting smoothly: no few rigid bones reproduce it, and more bones pay
    // for themselves in residual bits, so the choice goes past the default (5 bones here).
    let tube = samples::twisting_tube(24, 48, 16);
    let (skin, report) = fit_skin(&tube, &FitOptions::default()).unwrap();
    skin.validate(tube.vertex_count(), tube.frame_count()).unwrap();
    let (_, five) = fit_skin(&tube, &FitOptions { bones: Some(5), ..Default::default() }).unwrap();
    assert!(skin.palette_len > 5 && report.rms_error < five.rms_error, "{report:?} vs 5 bones {five:?}");
    let e = fit_skin(&tube, &FitOptions { quant_bits: 40, ..Default::default() }).unwrap_err();
    assert!(e.to_string().contains("quant_bits"), "{e}");
}

#[test]
fn the_fit_is_deterministic_and_its_work_bounded_when_it_subsamples() {
    // More vertices than the fit's sample (4,096 by default, 16 per bone for up to 256 bones):
    // the bones are fitted to a subsample, the count is chosen on held-out vertices; two runs
    // give the same skin.
    let cloth = samples::waving_cloth(70, 60, 6);
    assert!(cloth.vertex_count() > 4096);
    let opts = FitOptions::default();
    let (a, report) = fit_skin(&cloth, &opts).unwrap();
    let (b, again) = fit_skin(&cloth, &opts).unwrap();
    assert_eq!(report, again);
    assert_eq!(a, b);
    a.validate(cloth.vertex_count(), cloth.frame_count()).unwrap();
    assert_eq!(report.sample_vertices, 4096, "{report:?}");
    // Counts double from the default (one bone per 200 vertices) up to 256.
    assert_eq!(report.counts_tried[0], (cloth.vertex_count() / 200) as u32, "{report:?}");
    for w in report.counts_tried.windows(2) {
        assert_eq!(w[1], (2 * w[0]).min(256), "{report:?}");
    }
    // At most `iterations` alternations at the first count, 3 at each doubling (started from
    // the last fit's split bones), and at least one at each.
    let tried = report.counts_tried.len() as u32;
    assert!(report.alternations >= tried, "{report:?}");
    assert!(report.alternations <= opts.iterations + 3 * (tried - 1), "{report:?}");
}

#[test]
fn the_sample_holds_enough_vertices_per_bone() {
    let opts = FitOptions::default();
    let cloth = samples::waving_cloth(30, 24, 6);
    // A sample asked for: taken, with the count given.
    let (_, small) = fit_skin(&cloth, &FitOptions { sample_vertices: 300, bones: Some(12), ..opts.clone() }).unwrap();
    assert_eq!(small.sample_vertices, 300, "{small:?}");
    assert_eq!(small.counts_tried, vec![12]);
    // Too small for the bones: 16 vertices per bone.
    let (_, few) = fit_skin(&cloth, &FitOptions { sample_vertices: 100, bones: Some(20), ..opts.clone() }).unwrap();
    assert_eq!(few.sample_vertices, 16 * 20, "{few:?}");
    // A mesh smaller than the sample: every vertex.
    let (_, all) = fit_skin(&cloth, &FitOptions { bones: Some(4), ..opts.clone() }).unwrap();
    assert_eq!(all.sample_vertices as usize, cloth.vertex_count());
    // One alternation asked for: one per count tried.
    let (_, one) = fit_skin(&cloth, &FitOptions { iterations: 1, ..opts }).unwrap();
    assert_eq!(one.alternations, one.counts_tried.len() as u32, "{one:?}");
    assert!(one.counts_tried.len() > 1, "{one:?}");
}

#[test]
fn generated_articulated_sequences_fit_under_a_stated_residual() {
    // The fitted skin reproduces a bending, twisting tube and a waving cloth (no rigid parts in
    // either) to a small fraction of the bounding-box diagonal (RMS over every vertex and
    // frame), also with the bones fitted to a quarter of the cloth's vertices.
    let tube = samples::twisting_tube(24, 48, 16);
    let (_, report) = fit_skin(&tube, &FitOptions::default()).unwrap();
    assert!(report.rms_error < TUBE_RMS, "tube {report:?}");
    let cloth = samples::waving_cloth(56, 44, 12);
    let (_, report) = fit_skin(&cloth, &FitOptions { bones: Some(24), sample_vertices: 616, ..Default::default() }).unwrap();
    assert_eq!(report.sample_vertices, 616);
    assert!(report.rms_error < CLOTH_RMS, "cloth {report:?}");
    let (_, full) = fit_skin(&cloth, &FitOptions { bones: Some(24), sample_vertices: 4096, ..Default::default() }).unwrap();
    // The subsample costs little against fitting the bones to every vertex.
    assert!(report.rms_error < 1.5 * full.rms_error, "quarter {report:?} vs all {full:?}");
}

const TUBE_RMS: f64 = 0.002;
const CLOTH_RMS: f64 = 0.005;

#[test]
fn one_and_two_threads_fit_the_same_skin() {
    // Vertices and frames are solved in parallel and collected in order: the thread count
    // must not change a byte. Both with the count chosen and with a subsample.
    let tube = samples::twisting_tube(16, 30, 10);
    for opts in [FitOptions::default(), FitOptions { bones: Some(8), sample_vertices: 200, ..Default::default() }] {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| fit_skin(&tube, &opts).unwrap())
        };
        let (one, r1) = run(1);
        let (two, r2) = run(2);
        assert_eq!(r1, r2);
        assert_eq!(one, two);
    }
}
