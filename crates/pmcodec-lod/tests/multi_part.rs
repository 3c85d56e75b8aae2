//! LOD chains of generated multi-part characters (issue 13): many disconnected parts of a few
//! dozen triangles, several meshes on one 18-joint skeleton, welded and unwelded, touching
//! parts, at many budgets and with every placement. Before the fix every such character with
//! open parts failed with "level k vertex N merged into N, which level k+1 does not use".

use crate::common;

use common::{check_chain, check_glb_levels};
use pmcodec_lod::fixture::{CharacterSpec, multi_part_character};
use pmcodec_lod::{LodChain, LodOptions, Placement, RefitOptions, build_chain, build_chain_with, gltf_out};
use pmcodec_mesh::gltf_input::RiggedMesh;
use proptest::prelude::*;

fn character(spec: &CharacterSpec) -> RiggedMesh {
    let mut rig = multi_part_character(spec);
    rig.weld();
    rig
}

/// Triangle counts for shares of `total`, made strictly decreasing (duplicates dropped).
fn targets(total: usize, shares: &[f64]) -> Vec<usize> {
    let mut out: Vec<usize> = Vec::new();
    for s in shares {
        let t = ((total as f64) * s).round().max(1.0) as usize;
        if t < out.last().copied().unwrap_or(total) {
            out.push(t);
        }
    }
    out
}

/// What every chain of a multi-part character must satisfy beyond [`check_chain`]: triangle
/// counts never grow; a level above its target means no collapse was left, so every later level
/// is the same.
fn check_multi_part(chain: &LodChain, targets: &[usize], what: &str) {
    check_chain(chain);
    let counts: Vec<usize> = chain.levels.iter().map(|l| l.rig.triangles.len()).collect();
    for k in 1..counts.len() {
        assert!(counts[k] <= counts[k - 1], "{what}: level {k} has more triangles than level {}: {counts:?}", k - 1);
        if counts[k] > targets[k - 1] {
            assert!(
                counts[k..].iter().all(|&c| c == counts[k]),
                "{what}: level {k} stopped above its target {targets:?} but later levels went on: {counts:?}"
            );
        }
    }
}

/// The issue's budgets on the default character (60 parts, six meshes, unwelded and touching
/// parts) with every placement, the refit on for the two that use it.
#[test]
fn issue_budgets_with_every_placement() {
    let rig = character(&CharacterSpec { parts: 24, ..Default::default() });
    let targets = targets(rig.triangles.len(), &[0.5, 0.25, 0.1, 0.05]);
    for placement in Placement::ALL {
        let chain = build_chain(rig.clone(), &targets, &LodOptions { placement, ..Default::default() })
            .unwrap_or_else(|e| panic!("{placement:?} at {targets:?}: {e}"));
        check_multi_part(&chain, &targets, placement.name());
        check_glb_levels(&chain, &gltf_out::chain_glb(&chain, placement.name()).expect("glb"));
    }
}

/// Welded closed parts only: nothing blocks the collapses, so every budget down to a few
/// triangles per part is reached exactly.
#[test]
fn welded_characters_reach_their_budgets() {
    let rig = character(&CharacterSpec { seed: 7, parts: 50, unwelded: false, touching: false, ..Default::default() });
    let targets = targets(rig.triangles.len(), &[0.5, 0.25]);
    let chain =
        build_chain_with(rig, &targets, &LodOptions::default(), &RefitOptions { iterations: 0, ..Default::default() }).expect("chain");
    check_multi_part(&chain, &targets, "welded");
    for (level, &t) in chain.levels[1..].iter().zip(&targets) {
        assert!(level.rig.triangles.len() <= t, "target {t}: {} triangles", level.rig.triangles.len());
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]

    /// Any character of that kind at any decreasing budgets, with any placement (the refit is
    /// off here: it moves vertices, never changes which exist, and has its own tests).
    #[test]
    fn any_multi_part_character_at_any_budgets(
        seed in any::<u64>(),
        parts in 1usize..70,
        meshes in 1usize..7,
        unwelded in any::<bool>(),
        touching in any::<bool>(),
        morph in any::<bool>(),
        mut shares in proptest::collection::vec(0.01f64..0.95, 1..7),
        placement in 0usize..3,
    ) {
        let spec = CharacterSpec { seed, parts, meshes, unwelded, touching, morph };
        let rig = character(&spec);
        shares.sort_by(|a, b| b.total_cmp(a));
        let targets = targets(rig.triangles.len(), &shares);
        prop_assume!(!targets.is_empty());
        let placement = Placement::ALL[placement];
        let opts = LodOptions { placement, ..Default::default() };
        let chain = build_chain_with(rig, &targets, &opts, &RefitOptions { iterations: 0, ..Default::default() });
        let chain = chain.map_err(|e| TestCaseError::fail(format!("{spec:?} {placement:?} at {targets:?}: {e}")))?;
        check_multi_part(&chain, &targets, &format!("{spec:?} {placement:?} at {targets:?}"));
    }
}
