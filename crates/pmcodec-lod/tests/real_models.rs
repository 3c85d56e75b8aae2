//! LOD chains of the real models in ../shared/data/gltf (required): validity, the
//! GLB read back through our reader, and the error against meshoptimizer on the Fox.

mod common;

use common::{check_chain, max_pose_gap, shared_model};
use pmcodec_eval::SampleOptions;
use pmcodec_lod::measure::{MeasureOptions, animation_error, meshopt_baseline};
use pmcodec_lod::{LodOptions, build_chain, gltf_out};
use pmcodec_mesh::gltf_input::RiggedMesh;

fn shares(rig: &RiggedMesh) -> Vec<usize> {
    [0.25, 0.10].iter().map(|s| (rig.triangles.len() as f64 * s).round() as usize).collect()
}

fn round_trip(name: &str) {
    let Some(rig) = shared_model(name) else { return };
    let targets = shares(&rig);
    let chain = build_chain(rig, &targets, &LodOptions::default()).expect("chain");
    check_chain(&chain);
    let bytes = gltf_out::chain_glb(&chain, "houle-poulin").expect("glb");
    let back = RiggedMesh::from_bytes(&bytes).expect("our reader reads it");
    assert_eq!(back.animations.len(), chain.input.animations.len(), "{name}: animations kept");
    let diag = pmcodec_lod::measure::posed_mesh(&chain.input, None, 0.0).diagonal();
    for anim in 0..back.animations.len() {
        let t = back.animations[anim].duration * 0.37;
        let gap = max_pose_gap(&back, &chain.levels[0].rig, Some(anim), t);
        assert!(gap < 1e-4 * diag, "{name} animation {anim}: {gap} of {diag}");
    }
}

#[test]
fn fox_round_trip() {
    round_trip("Fox.glb");
}

#[test]
fn robot_round_trip() {
    round_trip("RobotExpressive.glb");
}

#[test]
fn horse_round_trip() {
    round_trip("Horse.glb");
}

#[test]
fn parrot_needs_draco_and_says_so() {
    let path = common::data_dir().join("Parrot.glb");
    assert!(path.exists(), "{} is absent: these tests read ../shared/data beside the repository", path.display());
    let err = RiggedMesh::from_path(&path).expect_err("Draco is not read");
    assert!(err.to_string().contains("KHR_draco_mesh_compression"), "{err}");
}

#[test]
fn fox_beats_meshopt_at_ten_percent() {
    let Some(rig) = shared_model("Fox.glb") else { return };
    let target = shares(&rig)[1];
    let chain = build_chain(rig.clone(), &[target], &LodOptions::default()).expect("chain");
    let measure = MeasureOptions { frame_rate: 4.0, samples: SampleOptions { samples: 1500, seed: 7 } };
    let ours = animation_error(&chain.input, &chain.levels[1].rig, &measure).expect("ours");
    let base = animation_error(&rig, &meshopt_baseline(&rig, target), &measure).expect("meshopt");
    eprintln!("Fox 10%: ours {ours:?}, meshopt {base:?}");
    assert!(ours.mean < 0.7 * base.mean, "ours {} vs meshopt {}", ours.mean, base.mean);
}
