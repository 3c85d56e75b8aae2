//! LOD chains of small rigs built in code: skin and morph validity, every placement, the
//! written GLB read back, and clear errors for bad requests.

use crate::common;

use common::{bending_tube_and_face, check_chain, check_glb_levels, max_pose_gap};
use pmcodec_lod::{LodError, LodOptions, Placement, PoseOptions, PoseWeights, build_chain, gltf_out};
use pmcodec_mesh::gltf_input::{GltfOptions, RiggedMesh, load_gltf_bytes};

#[test]
fn every_placement_gives_a_valid_chain() {
    let rig = bending_tube_and_face(16, 12);
    let total = rig.triangles.len();
    for placement in Placement::ALL {
        let chain =
            build_chain(rig.clone(), &[total / 2, total / 4, total / 10], &LodOptions { placement, ..Default::default() }).expect("chain");
        assert_eq!(chain.levels.len(), 4);
        for (level, target) in chain.levels[1..].iter().zip([total / 2, total / 4, total / 10]) {
            assert!(level.rig.triangles.len() <= target, "{placement:?}: reached {target}");
        }
        check_chain(&chain);
    }
}

#[test]
fn endpoint_keeps_authored_influences() {
    let rig = bending_tube_and_face(16, 12);
    let total = rig.triangles.len();
    let chain =
        build_chain(rig.clone(), &[total / 4], &LodOptions { placement: Placement::Endpoint, ..Default::default() }).expect("chain");
    let lod = &chain.levels[1].rig;
    for v in 0..lod.positions.len() {
        let found = (0..rig.positions.len())
            .any(|u| rig.positions[u] == lod.positions[v] && rig.joints[u] == lod.joints[v] && rig.weights[u] == lod.weights[v]);
        assert!(found, "vertex {v} is an input vertex with its influences");
    }
}

#[test]
fn level_zero_poses_like_the_input() {
    let rig = bending_tube_and_face(10, 8);
    let total = rig.triangles.len();
    let chain = build_chain(rig.clone(), &[total / 3], &LodOptions::default()).expect("chain");
    // Level 0 reorders vertices by class; compare posed meshes by surface distance instead.
    for t in [0.0, 0.5, 1.0] {
        let a = pmcodec_lod::measure::posed_mesh(&rig, Some(0), t);
        let b = pmcodec_lod::measure::posed_mesh(&chain.levels[0].rig, Some(0), t);
        let d = pmcodec_eval::symmetric(&a, &b, &Default::default()).expect("distance");
        assert!(d.max < 1e-5, "t = {t}: {d:?}");
    }
}

#[test]
fn written_glb_reads_back() {
    let rig = bending_tube_and_face(12, 10);
    let total = rig.triangles.len();
    let chain = build_chain(rig, &[total / 2, total / 5], &LodOptions::default()).expect("chain");
    let bytes = gltf_out::chain_glb(&chain, "houle-poulin").expect("glb");
    check_glb_levels(&chain, &bytes);
    let back = RiggedMesh::from_bytes(&bytes).expect("our reader reads it");
    assert_eq!(back.animations.len(), 1);
    assert_eq!(back.instances.len(), chain.levels[0].rig.instances.len());
    assert_eq!(back.instances.iter().map(|i| i.morph_targets.len()).sum::<usize>(), 1);
    for t in [0.0, 0.4, 1.0] {
        let gap = max_pose_gap(&back, &chain.levels[0].rig, Some(0), t);
        assert!(gap < 1e-4, "t = {t}: {gap}");
    }
    let seq = load_gltf_bytes(&bytes, &GltfOptions::default()).expect("sequence");
    assert!(seq.frame_count() > 1);
    // The chain description.
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let levels = json["extras"]["pmcodec_lod"]["levels"].as_array().expect("levels");
    assert_eq!(levels.len(), 3);
    assert_eq!(json["scenes"].as_array().map(Vec::len), Some(3));
    for (k, level) in levels.iter().enumerate() {
        assert_eq!(level["scene"], k);
        let table = &level["toCoarser"];
        assert_eq!(table.is_null(), k == 2);
        if let Some(a) = table.as_u64() {
            let acc = &json["accessors"][a as usize];
            assert_eq!(acc["count"], level["vertices"]);
            assert_eq!(acc["componentType"], 5125);
        }
    }
}

#[test]
fn bad_requests_are_errors() {
    let rig = bending_tube_and_face(8, 8);
    let total = rig.triangles.len();
    assert!(matches!(build_chain(rig.clone(), &[], &LodOptions::default()), Err(LodError::NoTargets)));
    assert!(matches!(build_chain(rig.clone(), &[total], &LodOptions::default()), Err(LodError::BadTarget { .. })));
    assert!(matches!(build_chain(rig.clone(), &[10, 20], &LodOptions::default()), Err(LodError::BadTarget { .. })));
    let weights = PoseWeights::parse(&["nope=1".into()]).unwrap();
    let opts = LodOptions { poses: PoseOptions { weights, ..Default::default() }, ..Default::default() };
    assert!(matches!(build_chain(rig.clone(), &[10], &opts), Err(LodError::UnknownPose { .. })));
    let weights = PoseWeights::parse(&["rest=0".into(), "morph=0".into(), "*=0".into()]).unwrap();
    let opts = LodOptions { poses: PoseOptions { weights, ..Default::default() }, ..Default::default() };
    assert!(matches!(build_chain(rig, &[10], &opts), Err(LodError::NoPoses)));
    assert!(PoseWeights::parse(&["rest=-1".into()]).is_ok_and(|w| w.rest == -1.0));
    let weights = PoseWeights::parse(&["rest=-1".into()]).unwrap();
    let opts = LodOptions { poses: PoseOptions { weights, ..Default::default() }, ..Default::default() };
    let rig = bending_tube_and_face(8, 8);
    assert!(matches!(build_chain(rig.clone(), &[10], &opts), Err(LodError::BadPoseWeight { .. })));
    let mut broken = rig.clone();
    broken.triangles.push([0, 0, 1]);
    assert!(matches!(build_chain(broken, &[10], &LodOptions::default()), Err(LodError::BadRig(_))));
    let mut broken = rig.clone();
    broken.joints[0] = [9, 0, 0, 0];
    assert!(matches!(build_chain(broken, &[10], &LodOptions::default()), Err(LodError::BadRig(_))));
    let mut broken = rig;
    broken.triangles[0][1] = 1_000_000;
    assert!(matches!(build_chain(broken, &[10], &LodOptions::default()), Err(LodError::BadRig(_))));
}

#[test]
fn geomorph_targets_are_nearby_in_every_pose() {
    let rig = bending_tube_and_face(16, 12);
    let total = rig.triangles.len();
    let chain = build_chain(rig, &[total / 3, total / 8], &LodOptions::default()).expect("chain");
    let diag = pmcodec_lod::measure::posed_mesh(&chain.input, None, 0.0).diagonal();
    for t in [0.0, 0.5, 1.0] {
        for k in 0..chain.levels.len() - 1 {
            let (fine, coarse) = (&chain.levels[k], &chain.levels[k + 1]);
            let pf = fine.rig.pose(Some(&fine.rig.animations[0]), t);
            let pc = coarse.rig.pose(Some(&coarse.rig.animations[0]), t);
            for (i, &c) in fine.to_coarser.iter().enumerate() {
                let d = (pf[i] - pc[c as usize]).length();
                assert!(d < 0.25 * diag, "t {t} level {k} vertex {i} -> {c}: {d} of {diag}");
            }
        }
    }
}

#[test]
fn the_refit_does_not_depend_on_the_thread_count() {
    // Its closest-point walks run in parallel; their answers are accumulated in sample order.
    use pmcodec_lod::{RefitOptions, build_chain_with};
    let rig = bending_tube_and_face(12, 10);
    let target = rig.triangles.len() / 6;
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        pool.install(|| build_chain_with(rig.clone(), &[target], &LodOptions::default(), &RefitOptions::default())).expect("chain")
    };
    let (one, three) = (run(1), run(3));
    assert_eq!(one.levels[1].rig.positions, three.levels[1].rig.positions);
    assert_eq!(one.levels[1].rig.weights, three.levels[1].rig.weights);
    assert_eq!(one.levels[1].rig.triangles, three.levels[1].rig.triangles);
}

#[test]
fn refit_does_not_increase_the_error() {
    use pmcodec_eval::SampleOptions;
    use pmcodec_lod::measure::{MeasureOptions, animation_error};
    use pmcodec_lod::{RefitOptions, build_chain_with};
    let rig = bending_tube_and_face(16, 12);
    let target = rig.triangles.len() / 8;
    let opts = LodOptions::default();
    let off = build_chain_with(rig.clone(), &[target], &opts, &RefitOptions { iterations: 0, ..Default::default() }).expect("chain");
    let on = build_chain_with(rig, &[target], &opts, &RefitOptions::default()).expect("chain");
    check_chain(&on);
    assert_eq!(off.levels[1].rig.triangles, on.levels[1].rig.triangles, "the refit keeps the connectivity");
    let measure = MeasureOptions { frame_rate: 4.0, samples: SampleOptions { samples: 1500, seed: 7 } };
    let e_off = animation_error(&off.input, &off.levels[1].rig, &measure).expect("error");
    let e_on = animation_error(&on.input, &on.levels[1].rig, &measure).expect("error");
    assert!(e_on.mean <= 1.02 * e_off.mean, "refit {} vs collapse positions {}", e_on.mean, e_off.mean);
    // No triangle turns over in an example pose (the animation's first and last frames are).
    let (a, b) = (&off.levels[1].rig, &on.levels[1].rig);
    let duration = a.animations[0].duration;
    for t in [0.0, duration] {
        let (pa, pb) = (a.pose(Some(&a.animations[0]), t), b.pose(Some(&b.animations[0]), t));
        for tri in &a.triangles {
            let normal = |p: &[glam::Vec3]| {
                let [x, y, z] = tri.map(|i| p[i as usize]);
                (y - x).cross(z - x)
            };
            let (n0, n1) = (normal(&pa), normal(&pb));
            assert!(n0.length_squared() == 0.0 || n0.dot(n1) > 0.0, "t = {t}: triangle {tri:?} flipped by the refit");
        }
    }
}
