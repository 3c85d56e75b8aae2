//! Small deterministic rigs built in code, and the checks every LOD output must pass.
#![allow(dead_code)]

use pmcodec_lod::LodChain;
#[allow(unused_imports)]
pub use pmcodec_lod::fixture::bending_tube_and_face;
use pmcodec_mesh::gltf_input::RiggedMesh;
use std::path::PathBuf;

pub fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/gltf")
}

/// Loads and welds a model of the shared data, or `None` (with a note) when it is not there.
pub fn shared_model(name: &str) -> Option<RiggedMesh> {
    let path = data_dir().join(name);
    if !path.exists() {
        panic!("{} is absent: these tests read the real models in ../shared/data beside the repository", path.display());
    }
    let mut rig = RiggedMesh::from_path(&path).expect("shared model loads");
    rig.weld();
    Some(rig)
}

/// Skin validity, morph target counts, kept animations and the correspondence tables.
pub fn check_chain(chain: &LodChain) {
    let input = &chain.input;
    for (k, level) in chain.levels.iter().enumerate() {
        let rig = &level.rig;
        assert_eq!(rig.animations.len(), input.animations.len(), "level {k} keeps the animations");
        assert!(!rig.triangles.is_empty(), "level {k} has triangles");
        for inst in &rig.instances {
            let class = chain.attrs.classes.iter().find(|c| c.node == inst.node && c.skin == inst.skin);
            if let Some(c) = class {
                assert_eq!(inst.morph_targets.len(), c.morph_count, "level {k}: morph targets kept");
            }
            for t in &inst.morph_targets {
                assert_eq!(t.len(), inst.vertices.len(), "level {k}: one delta per vertex");
            }
            let Some(s) = inst.skin else { continue };
            let joints = input.skins[s].joints.len();
            for v in inst.vertices.clone() {
                let (j, w) = (rig.joints[v], rig.weights[v]);
                let sum: f32 = w.iter().sum();
                assert!((sum - 1.0).abs() < 1e-4, "level {k} vertex {v}: weights sum to {sum}");
                assert!(w.iter().all(|&x| x >= 0.0), "level {k} vertex {v}: negative weight");
                for (&jj, &ww) in j.iter().zip(&w) {
                    assert!((jj as usize) < joints || ww == 0.0, "level {k} vertex {v}: joint {jj} of {joints}");
                }
            }
        }
        for t in &rig.triangles {
            assert!(t.iter().all(|&i| (i as usize) < rig.positions.len()));
        }
        if k + 1 < chain.levels.len() {
            let coarse = chain.levels[k + 1].rig.positions.len() as u32;
            assert_eq!(level.to_coarser.len(), rig.positions.len(), "level {k}: one entry per vertex");
            assert!(level.to_coarser.iter().all(|&c| c < coarse), "level {k}: table points into level {}", k + 1);
            let used: std::collections::HashSet<u32> = chain.levels[k + 1].rig.triangles.iter().flatten().copied().collect();
            assert!(level.to_coarser.iter().all(|c| used.contains(c)), "level {k}: table targets are used vertices");
        } else {
            assert!(level.to_coarser.is_empty());
        }
    }
}

/// Largest distance between two rigs' vertices posed at `(anim, t)`, vertex by vertex.
pub fn max_pose_gap(a: &RiggedMesh, b: &RiggedMesh, anim: Option<usize>, t: f32) -> f32 {
    let pa = a.pose(anim.and_then(|i| a.animations.get(i)), t);
    let pb = b.pose(anim.and_then(|i| b.animations.get(i)), t);
    assert_eq!(pa.len(), pb.len(), "same vertex count");
    pa.iter().zip(&pb).map(|(x, y)| (*x - *y).length()).fold(0.0, f32::max)
}
