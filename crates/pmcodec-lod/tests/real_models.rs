//! LOD chains of the real models in ../shared/data/gltf (required; a missing model fails):
//! every level valid at 50%, 25%, 10% and 5% of the triangles, every level of the GLB read
//! back with the `gltf` crate and compared with the chain, the GLB posed through our reader,
//! and the error against meshoptimizer on the Fox. (The Parrot is Draco-compressed, which the
//! reader decodes.)
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use common::{check_chain, check_glb_levels, max_pose_gap, shared_model};
use pmcodec_eval::SampleOptions;
use pmcodec_lod::measure::{MeasureOptions, animation_error, meshopt_baseline};
use pmcodec_lod::{LodOptions, build_chain, gltf_out};
use pmcodec_mesh::gltf_input::RiggedMesh;

/// The budgets: 50%, 25%, 10% and 5% of the input's triangles.
fn shares(rig: &RiggedMesh) -> Vec<usize> {
    [0.5, 0.25, 0.10, 0.05].iter().map(|s| (rig.triangles.len() as f64 * s).round() as usize).collect()
}

fn round_trip(name: &str) {
    let rig = shared_model(name);
    let targets = shares(&rig);
    let chain = build_chain(rig, &targets, &LodOptions::default()).unwrap_or_else(|e| panic!("{name} at {targets:?}: {e}"));
    check_chain(&chain);
    let counts: Vec<usize> = chain.levels.iter().map(|l| l.rig.triangles.len()).collect();
    eprintln!("{name}: targets {targets:?}, triangles per level {counts:?}");
    for (k, (level, &t)) in chain.levels[1..].iter().zip(&targets).enumerate() {
        let n = level.rig.triangles.len();
        assert!(n <= t && n < counts[k], "{name} level {}: {n} triangles for target {t} (previous level {})", k + 1, counts[k]);
    }
    let bytes = gltf_out::chain_glb(&chain, "houle-poulin").expect("glb");
    check_glb_levels(&chain, &bytes);
    check_appearance(name, &chain, &bytes);
    let back = RiggedMesh::from_bytes(&bytes).expect("our reader reads it");
    assert_eq!(back.animations.len(), chain.input.animations.len(), "{name}: animations kept");
    let diag = pmcodec_lod::measure::posed_mesh(&chain.input, None, 0.0).diagonal();
    for anim in 0..back.animations.len() {
        let t = back.animations[anim].duration * 0.37;
        let gap = max_pose_gap(&back, &chain.levels[0].rig, Some(anim), t);
        assert!(gap < 1e-4 * diag, "{name} animation {anim}: {gap} of {diag}");
    }
}

/// Every level keeps the input's attributes and every material it uses; the file holds the
/// input's images once, one skeleton and one set of animations.
fn check_appearance(name: &str, chain: &pmcodec_lod::LodChain, bytes: &[u8]) {
    let input = chain.input.appearance.as_ref().expect("the input's appearance");
    let used = |a: &pmcodec_mesh::Appearance| a.triangle_material.iter().copied().collect::<std::collections::BTreeSet<u32>>();
    for (k, level) in chain.levels.iter().enumerate() {
        let app = level.rig.appearance.as_ref().unwrap_or_else(|| panic!("{name} level {k}: no appearance"));
        app.validate(level.rig.vertex_count(), &level.rig.triangles).expect("valid");
        assert_eq!((app.uv0.is_empty(), app.colors.is_empty()), (input.uv0.is_empty(), input.colors.is_empty()), "{name} level {k}");
        assert_eq!(used(app), used(input), "{name} level {k}: every material kept");
        assert!(app.uv0.iter().flatten().all(|x| x.is_finite()), "{name} level {k}: UVs");
    }
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    let count = |key: &str| doc[key].as_array().map_or(0, Vec::len);
    assert_eq!(count("images"), input.images.len(), "{name}: images once");
    assert_eq!(count("materials"), input.materials.len(), "{name}: materials once");
    assert_eq!(count("animations"), chain.input.animations.len(), "{name}: animations once");
    assert!(count("skins") <= chain.input.skins.len() + chain.input.instances.len(), "{name}: skins once");
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

/// The Parrot is Draco-compressed; the reader decodes it.
#[test]
fn parrot_round_trip() {
    round_trip("Parrot.glb");
}

#[test]
fn fox_beats_meshopt_at_ten_percent() {
    let rig = shared_model("Fox.glb");
    let target = shares(&rig)[2];
    let chain = build_chain(rig.clone(), &[target], &LodOptions::default()).expect("chain");
    let measure = MeasureOptions { frame_rate: 4.0, samples: SampleOptions { samples: 1500, seed: 7 } };
    let ours = animation_error(&chain.input, &chain.levels[1].rig, &measure).expect("ours");
    let base = animation_error(&rig, &meshopt_baseline(&rig, target), &measure).expect("meshopt");
    eprintln!("Fox 10%: ours {ours:?}, meshopt {base:?}");
    assert!(ours.mean < 0.7 * base.mean, "ours {} vs meshopt {}", ours.mean, base.mean);
}
