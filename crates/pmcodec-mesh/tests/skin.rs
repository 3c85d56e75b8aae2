//! The skin `to_sequence` keeps beside the frames poses every vertex as the frames say, and bad
//! skins are refused by name.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::gltf_input::{GltfOptions, load_gltf};
use pmcodec_mesh::{SequenceSkin, samples};
use std::path::PathBuf;

/// A real file from ../shared/data/gltf; the test fails with a message when it is absent.
fn model(name: &str) -> PathBuf {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf")).join(name);
    assert!(path.is_file(), "{} is absent; these tests read the real models in ../shared/data beside the repository", path.display());
    path
}

#[test]
fn skinned_models_carry_a_skin_that_poses_every_frame() {
    for name in ["Fox.glb", "RobotExpressive.glb"] {
        let opts = GltfOptions { frame_rate: 5.0, ..Default::default() };
        let seq = load_gltf(&model(name), &opts).expect("load");
        let skin = seq.skin.as_ref().unwrap_or_else(|| panic!("{name}: no skin"));
        assert_eq!(skin.matrices.len(), seq.frame_count(), "{name}");
        let diag = seq.frame_mesh(0).expect("frame").diagonal();
        let mut worst = 0.0f32;
        for f in 0..seq.frame_count() {
            for v in 0..seq.vertex_count() {
                worst = worst.max((skin.pose_vertex(f, v) - seq.frames[f][v]).length());
            }
        }
        // RobotExpressive has morph targets on its face, which the skin does not carry: allow
        // their size, but the skeleton must pose everything else.
        let bound = if name == "Fox.glb" { 1e-5 } else { 0.05 };
        assert!(worst <= bound * diag, "{name}: skin poses {worst} away from the frames (diagonal {diag})");
    }
}

#[test]
fn unskinned_input_has_no_skin_and_bad_skins_are_refused_by_name() {
    let mut seq = samples::waving_cloth(4, 3, 2);
    assert!(seq.skin.is_none());
    let n = seq.vertex_count();
    let good = SequenceSkin {
        palette_len: 1,
        palette_names: vec!["node 0".into()],
        rest: seq.frames[0].clone(),
        joints: vec![[0; 4]; n],
        weights: vec![[1.0, 0.0, 0.0, 0.0]; n],
        matrices: vec![vec![[1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0.]]; 2],
        warnings: Vec::new(),
    };
    seq.skin = Some(good.clone());
    seq.validate().expect("a good skin");
    type Damage = fn(&mut SequenceSkin);
    let cases: [(&str, Damage); 4] = [
        ("joint 3 beyond the palette of 1", |s| s.joints[2] = [3, 0, 0, 0]),
        ("vertex 1: weights sum to 0.5", |s| s.weights[1] = [0.5, 0.0, 0.0, 0.0]),
        ("vertex 0 influence 1: weight -1", |s| s.weights[0] = [2.0, -1.0, 0.0, 0.0]),
        ("frame 1: the matrix of node 0 is not finite", |s| s.matrices[1][0][3] = f32::NAN),
    ];
    for (expected, damage) in cases {
        let mut bad = good.clone();
        damage(&mut bad);
        seq.skin = Some(bad);
        let e = seq.validate().expect_err(expected).to_string();
        assert!(e.contains(expected), "{e}");
    }
}

/// A skinned mesh beside a rigid one: one palette entry per skin joint, then one per rigid
/// node; a joint whose inverse bind matrix cannot be inverted is named in a warning.
#[test]
fn the_palette_holds_skin_joints_then_rigid_nodes_and_a_singular_bind_is_named() {
    use glam::{Mat4, Vec3};
    use pmcodec_mesh::gltf_input::{MeshInstance, NodeTransform, RiggedMesh, Skin};
    let instance = |node: usize, skin: Option<usize>, vertices: std::ops::Range<usize>| MeshInstance {
        node,
        mesh: 0,
        skin,
        vertices,
        morph_targets: Vec::new(),
        default_weights: Vec::new(),
    };
    let rig = RiggedMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE, Vec3::NEG_X],
        triangles: vec![[0, 1, 2], [3, 4, 5]],
        joints: vec![[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 0], [0; 4], [0; 4], [0; 4]],
        weights: vec![[0.5, 0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0; 4], [0.0; 4], [0.0; 4]],
        instances: vec![instance(0, Some(0), 0..3), instance(1, None, 3..6)],
        nodes: vec![NodeTransform { translation: Vec3::Y, ..Default::default() }; 3],
        parents: vec![None; 3],
        skins: vec![Skin { joints: vec![2, 1], inverse_bind_matrices: vec![Mat4::IDENTITY, Mat4::ZERO] }],
        ..Default::default()
    };
    let skin = pmcodec_mesh::skin::sequence_skin(&rig, None, &[0.0]).expect("a skinned scene has a skin");
    assert_eq!(skin.palette_len, 3);
    assert_eq!(skin.joints[0], [0, 1, 0, 0]);
    assert_eq!((skin.joints[4], skin.weights[4]), ([2, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]), "rigid vertices on their node's entry");
    assert!(skin.palette_names[2].contains("node 1"), "{:?}", skin.palette_names);
    assert_eq!(skin.warnings.len(), 1, "{:?}", skin.warnings);
    assert!(skin.warnings[0].contains("skin 0 joint 1 (node 1)") && skin.warnings[0].contains("not invertible"), "{}", skin.warnings[0]);
    // Everything the skin poses is what the rig poses.
    let posed = rig.pose(None, 0.0);
    for (v, p) in posed.iter().enumerate().take(6) {
        assert!((skin.pose_vertex(0, v) - *p).length() < 1e-6, "vertex {v}");
    }
}
