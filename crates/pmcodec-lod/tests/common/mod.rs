//! Small deterministic rigs built in code, and the checks every LOD output must pass.
#![allow(clippy::unwrap_used, clippy::expect_used)]
#![allow(dead_code)]

use pmcodec_lod::LodChain;
#[allow(unused_imports)]
pub use pmcodec_lod::fixture::bending_tube_and_face;
use pmcodec_mesh::gltf_input::RiggedMesh;
use std::path::PathBuf;

pub fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/gltf")
}

/// Loads and welds a model of the shared data; a missing model fails the test, saying where it
/// was looked for.
pub fn shared_model(name: &str) -> RiggedMesh {
    let path = data_dir().join(name);
    assert!(path.exists(), "{} is absent: these tests read the real models in ../shared/data beside the repository", path.display());
    let mut rig = RiggedMesh::from_path(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    rig.weld();
    rig
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
            let mut hit = vec![false; coarse as usize];
            for &c in &level.to_coarser {
                hit[c as usize] = true;
            }
            assert!(hit.iter().all(|&h| h), "level {k}: every vertex of level {} is the geomorph target of one of its vertices", k + 1);
        } else {
            assert!(level.to_coarser.is_empty());
        }
    }
}

/// Largest distance between a level read back from its GLB (`a`: one vertex per written
/// wedge, primitive by primitive) and the level's rig (`b`) posed at `(anim, t)`, each wedge
/// against its vertex. A read-back vertex is wedge `start + index` of its mesh, `index` being
/// its place in the mesh's shared vertex accessors.
pub fn max_pose_gap(a: &RiggedMesh, b: &RiggedMesh, anim: Option<usize>, t: f32) -> f32 {
    let pa = a.pose(anim.and_then(|i| a.animations.get(i)), t);
    let pb = b.pose(anim.and_then(|i| b.animations.get(i)), t);
    let wedges = pmcodec_lod::gltf_out::level_appearance(b).wedge_vertex;
    assert_eq!(pa.len(), wedges.len(), "one vertex per wedge");
    assert_eq!(a.instances.len(), b.instances.len(), "one mesh per instance");
    let mut gap = 0.0f32;
    let mut start = 0usize;
    for (ia, ib) in a.instances.iter().zip(&b.instances) {
        for v in ia.vertices.clone() {
            let w = start + a.source[v].index as usize;
            gap = gap.max((pa[v] - pb[wedges[w] as usize]).length());
        }
        start += wedges[start..].iter().take_while(|&&v| ib.vertices.contains(&(v as usize))).count();
    }
    gap
}

/// Reads every level (scene k = level k) of a written chain back with the `gltf` crate and
/// compares it with the chain that wrote it: the level description, scene, the one shared
/// skeleton, vertex (wedge) and triangle counts, triangles per material, positions, skin joints
/// and weights, morph deltas, texture coordinates, and the geomorph table. Rigid parts are
/// written skinned to one joint in that node's rest world space, so their positions and deltas
/// are compared through the inverse bind matrix.
pub fn check_glb_levels(chain: &LodChain, bytes: &[u8]) {
    use glam::{Mat4, Vec3};
    use pmcodec_lod::gltf_out::{level_appearance, wedge_tables};
    let g = gltf::Gltf::from_slice(bytes).expect("the gltf crate reads the GLB");
    let blob: &[u8] = g.blob.as_deref().expect("a GLB binary chunk");
    let data = |_: gltf::Buffer| Some(blob);
    let root: serde_json::Value =
        serde_json::from_slice(&bytes[20..20 + u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize]).unwrap();
    let levels = root["extras"]["pmcodec_lod"]["levels"].as_array().expect("extras.pmcodec_lod.levels");
    assert_eq!(levels.len(), chain.levels.len(), "one level description per level");
    let scenes: Vec<gltf::Scene> = g.scenes().collect();
    assert_eq!(scenes.len(), chain.levels.len(), "one scene per level");
    assert_eq!(g.default_scene().map(|s| s.index()), Some(0), "scene 0 is the default");
    let input_nodes = chain.input.nodes.len();
    // One skeleton: the input's nodes, and one mesh node per instance and level besides.
    let instances: usize = chain.levels.iter().map(|l| l.rig.instances.len()).sum();
    assert_eq!(g.nodes().count(), input_nodes + instances, "one skeleton for all levels");
    // One set of animations, as many as the input has (with channels).
    assert!(g.animations().count() <= chain.input.animations.len());
    let tables = wedge_tables(chain);
    let close = |a: Vec3, b: Vec3, what: &str| {
        let tol = 1e-4 * (1.0 + a.abs().max_element().max(b.abs().max_element()));
        assert!((a - b).abs().max_element() <= tol, "{what}: {a} read back, {b} written");
    };
    for (k, (level, desc)) in chain.levels.iter().zip(levels).enumerate() {
        let rig = &level.rig;
        let app = level_appearance(rig);
        app.validate(rig.vertex_count(), &rig.triangles).expect("the level's appearance is consistent");
        assert_eq!(desc["scene"], k);
        assert_eq!(desc["vertices"], app.wedge_count(), "level {k}: vertices");
        assert_eq!(desc["triangles"], rig.triangles.len(), "level {k}: triangles");
        assert_eq!(desc["target"].as_u64().map(|t| t as usize), level.target, "level {k}: target");
        let mesh_nodes: Vec<usize> = desc["nodes"].as_array().expect("nodes").iter().map(|n| n.as_u64().unwrap() as usize).collect();
        assert_eq!(mesh_nodes.len(), rig.instances.len(), "level {k}: one mesh node per instance");
        let in_scene: Vec<usize> = scenes[k].nodes().map(|n| n.index()).collect();
        let (mut vertices, mut triangles) = (0usize, 0);
        for (i, (inst, &node_index)) in rig.instances.iter().zip(&mesh_nodes).enumerate() {
            let what = format!("level {k} mesh {i}");
            assert!(in_scene.contains(&node_index), "{what}: its node is in scene {k}");
            let node = g.nodes().nth(node_index).expect("mesh node");
            let skin = node.skin().expect("every level mesh is skinned");
            for j in skin.joints() {
                assert!(j.index() < input_nodes, "{what}: joint {} outside the shared skeleton", j.index());
            }
            let ibm: Vec<Mat4> = skin
                .reader(data)
                .read_inverse_bind_matrices()
                .expect("inverse bind matrices")
                .map(|m| Mat4::from_cols_array_2d(&m))
                .collect();
            let to_rest = if inst.skin.is_none() { ibm[0] } else { Mat4::IDENTITY };
            let range = inst.vertices.clone();
            // This mesh's wedges: the next run of wedges on its vertices.
            let count = app.wedge_vertex[vertices..].iter().take_while(|&&v| range.contains(&(v as usize))).count();
            let wedges = vertices..vertices + count;
            let mesh = node.mesh().expect("mesh");
            let prims: Vec<gltf::Primitive> = mesh.primitives().collect();
            let r = prims[0].reader(data);
            let positions: Vec<Vec3> = r.read_positions().expect("positions").map(Vec3::from_array).collect();
            assert_eq!(positions.len(), count, "{what}: vertex count");
            for (p, w) in positions.iter().zip(wedges.clone()) {
                let v = app.wedge_vertex[w] as usize;
                close(to_rest.transform_point3(*p), rig.positions[v], &format!("{what} wedge {w} position"));
            }
            if !app.uv0.is_empty() {
                let uv: Vec<[f32; 2]> = r.read_tex_coords(0).expect("TEXCOORD_0").into_f32().collect();
                assert_eq!(uv, app.uv0[wedges.clone()], "{what}: texture coordinates");
            }
            let joints: Vec<[u16; 4]> = r.read_joints(0).expect("joints").into_u16().collect();
            let weights: Vec<[f32; 4]> = r.read_weights(0).expect("weights").into_f32().collect();
            assert_eq!((joints.len(), weights.len()), (count, count), "{what}: one influence set per vertex");
            for ((j, w), wi) in joints.iter().zip(&weights).zip(wedges.clone()) {
                let v = app.wedge_vertex[wi] as usize;
                let sum: f32 = w.iter().sum();
                assert!((sum - 1.0).abs() < 1e-5, "{what} vertex {v}: weights {w:?}");
                if inst.skin.is_none() {
                    assert_eq!((*j, *w), ([0; 4], [1.0, 0.0, 0.0, 0.0]), "{what} vertex {v}: rigid part");
                    continue;
                }
                let cw = rig.weights[v];
                let csum: f32 = cw.iter().sum();
                for s in 0..4 {
                    assert!((w[s] - cw[s] / csum).abs() < 1e-6, "{what} vertex {v}: weights {w:?} read back, {cw:?} written");
                    if cw[s] > 0.0 {
                        assert_eq!(j[s], rig.joints[v][s], "{what} vertex {v}: joints {j:?} read back, {:?} written", rig.joints[v]);
                    }
                }
            }
            // Triangles: every primitive one material, together exactly this mesh's triangles.
            let mut read: Vec<(u32, [u32; 3])> = Vec::new();
            for p in &prims {
                let m = p.material().index().expect("a material") as u32;
                let idx: Vec<u32> = p.reader(data).read_indices().expect("indices").into_u32().collect();
                read.extend(idx.chunks_exact(3).map(|c| (m, [c[0], c[1], c[2]])));
            }
            let plain = chain.input.appearance.as_ref().is_none_or(|a| a.materials.is_empty());
            let mut written: Vec<(u32, [u32; 3])> = rig
                .triangles
                .iter()
                .zip(&app.corner_wedges)
                .enumerate()
                .filter(|(_, (t, _))| range.contains(&(t[0] as usize)))
                .map(|(t, (_, cw))| (if plain { 0 } else { app.material_of(t) }, cw.map(|w| w - wedges.start as u32)))
                .collect();
            read.sort_unstable();
            written.sort_unstable();
            assert_eq!(read, written, "{what}: triangles and their materials");
            let targets: Vec<Vec<Vec3>> =
                r.read_morph_targets().map(|(p, _, _)| p.expect("morph positions").map(Vec3::from_array).collect()).collect();
            assert_eq!(targets.len(), inst.morph_targets.len(), "{what}: morph targets");
            for (t, (read, wrote)) in targets.iter().zip(&inst.morph_targets).enumerate() {
                assert_eq!(read.len(), count, "{what} target {t}: one delta per vertex");
                for (a, w) in read.iter().zip(wedges.clone()) {
                    let v = app.wedge_vertex[w] as usize - range.start;
                    close(to_rest.transform_vector3(*a), wrote[v], &format!("{what} target {t} vertex {v}"));
                }
            }
            vertices += count;
            triangles += written.len();
        }
        assert_eq!((vertices, triangles), (app.wedge_count(), rig.triangles.len()), "level {k}: the meshes hold the level");
        match desc["toCoarser"].as_u64() {
            None => assert!(level.to_coarser.is_empty() && k + 1 == chain.levels.len(), "level {k}: only the last has no table"),
            Some(a) => {
                let acc = g.accessors().nth(a as usize).expect("table accessor");
                let table: Vec<u32> = gltf::accessor::Iter::<u32>::new(acc, data).expect("table").collect();
                assert_eq!(table, tables[k], "level {k}: geomorph table");
                // Each written vertex goes to a written vertex of the vertex it collapses into.
                let next = level_appearance(&chain.levels[k + 1].rig);
                for (w, &to) in table.iter().enumerate() {
                    let v = app.wedge_vertex[w] as usize;
                    assert_eq!(next.wedge_vertex[to as usize], level.to_coarser[v], "level {k} wedge {w}: table");
                }
            }
        }
    }
}
