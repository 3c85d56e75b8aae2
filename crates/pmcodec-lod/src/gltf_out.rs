//! GLB output of an LOD chain: every level skinned, with its morph targets, the input's node
//! hierarchy, skins and animations, one scene per level, and the chain described in the root
//! `extras.pmcodec_lod` (specified in `proto/lod.md`).
//!
//! * Nodes 0..N are the input's nodes (transforms and hierarchy, no meshes). Each level adds
//!   one root node per mesh, named `lod<k>_mesh<i>`, carrying that mesh and a skin.
//! * Rigid parts (meshes placed by a node, not skinned) become skinned by a one-joint skin on
//!   their node, with bind-space positions `W p` and inverse bind matrix `W^-1` (`W` the node's
//!   rest world transform), which poses exactly as before and lets every level live in a scene
//!   of its own without duplicating the skeleton.
//! * Scene k holds the input's root nodes and level k's mesh nodes; scene 0 (the default) is
//!   level 0, the welded input, so any viewer shows the full model and its animations.
//! * Animation channels are copied (times and values as read, quaternions renormalised); a
//!   morph-weight channel on an input mesh node is copied onto every level's node that carries
//!   that mesh's morph targets (sharing the sampler).
//! * Attributes: POSITION (with min/max), NORMAL (rest pose, unit), JOINTS_0 (u16),
//!   WEIGHTS_0 (float, summing to 1; unused slots joint 0), u32 indices, morph target POSITION deltas. The
//!   correspondence tables are u32 SCALAR accessors no mesh uses.

use crate::LodError;
use crate::chain::LodChain;
use crate::poses::pose_at;
use glam::{Mat4, Vec3};
use pmcodec_mesh::TriMesh;
use pmcodec_mesh::glb::{ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, GlbBuilder};
use pmcodec_mesh::gltf_input::{AnimatedProperty, Interpolation};
use serde_json::{Value, json};

fn unit_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mesh = TriMesh { positions: positions.to_vec(), triangles: triangles.to_vec() };
    pmcodec_mesh::write::vertex_normals(&mesh)
        .into_iter()
        .map(|n| {
            let n = n.normalize_or_zero();
            if n.length_squared() > 0.5 { n } else { Vec3::Z }
        })
        .collect()
}

fn node_json(n: &pmcodec_mesh::gltf_input::NodeTransform, animated: bool) -> Value {
    let mut v = json!({});
    match n.matrix {
        Some(m) if !animated => {
            if m != Mat4::IDENTITY {
                v["matrix"] = json!(m.to_cols_array());
            }
        }
        _ => {
            if n.translation != Vec3::ZERO {
                v["translation"] = json!(n.translation.to_array());
            }
            if n.rotation != glam::Quat::IDENTITY {
                v["rotation"] = json!(n.rotation.normalize().to_array());
            }
            if n.scale != Vec3::ONE {
                v["scale"] = json!(n.scale.to_array());
            }
        }
    }
    v
}

/// The matrix with its last row exactly (0, 0, 0, 1), as glTF requires of inverse bind matrices
/// (an inverse computed in f32 gives 0.99999994).
fn affine(mut m: Mat4) -> Mat4 {
    m.x_axis.w = 0.0;
    m.y_axis.w = 0.0;
    m.z_axis.w = 0.0;
    m.w_axis.w = 1.0;
    m
}

/// The GLB bytes of a chain (see the module documentation).
pub fn chain_glb(chain: &LodChain, placement: &str) -> Result<Vec<u8>, LodError> {
    let input = &chain.input;
    let mut b = GlbBuilder::default();
    let node_count = input.nodes.len();
    let mut animated = vec![false; node_count];
    for a in &input.animations {
        for ch in &a.channels {
            if ch.property != AnimatedProperty::MorphWeights
                && let Some(f) = animated.get_mut(ch.node)
            {
                *f = true;
            }
        }
    }
    let mut nodes: Vec<Value> = input.nodes.iter().zip(&animated).map(|(n, &a)| node_json(n, a)).collect();
    for (c, p) in input.parents.iter().enumerate() {
        if let Some(p) = *p
            && p < node_count
        {
            let list = nodes[p].as_object_mut().map(|o| o.entry("children").or_insert_with(|| json!([])));
            if let Some(Value::Array(list)) = list {
                list.push(json!(c));
            }
        }
    }
    let roots: Vec<usize> = (0..node_count).filter(|&n| input.parents.get(n).is_none_or(|p| p.is_none())).collect();

    // The input's skins' inverse bind matrices, written once and shared by every level's copy.
    let ibm_accessors: Vec<usize> = input
        .skins
        .iter()
        .map(|s| {
            let ibm: Vec<f32> = s.inverse_bind_matrices.iter().flat_map(|m| affine(*m).to_cols_array()).collect();
            b.floats(&ibm, None, "MAT4", 16, false)
        })
        .collect();
    let mut skins: Vec<Value> = Vec::new();
    let rest_world = pose_at(input, None, 0.0).world;
    // One-joint skins for rigid parts, one per (level, node), created on demand.
    let mut rigid_skin: std::collections::HashMap<(usize, usize), (usize, Mat4)> = std::collections::HashMap::new();
    // Per level: the first node of its copy of the input's nodes (0 for level 0, which uses the
    // input's own), and its skins for the input's skins.
    let mut skeletons: Vec<usize> = Vec::new();
    let input_nodes = nodes.clone();

    let mut meshes: Vec<Value> = Vec::new();
    let mut levels_json: Vec<Value> = Vec::new();
    let mut scenes: Vec<Value> = Vec::new();
    // For every input node with a morph-weight channel: the level nodes that must get a copy.
    let mut morph_nodes: Vec<(usize, usize)> = Vec::new();
    for (k, level) in chain.levels.iter().enumerate() {
        let rig = &level.rig;
        // Level k's skeleton: the input's nodes for level 0, a copy of them (same names,
        // transforms and hierarchy, children renumbered) for the others. glTF lets scenes share
        // nodes, but loaders that instance each scene separately (three.js clones shared
        // roots) would then animate a copy the skins do not follow.
        let off = if k == 0 { 0 } else { nodes.len() };
        if k > 0 {
            for n in &input_nodes {
                let mut n = n.clone();
                if let Some(Value::Array(children)) = n.get_mut("children") {
                    for c in children.iter_mut() {
                        *c = json!(c.as_u64().unwrap_or(0) as usize + off);
                    }
                }
                nodes.push(n);
            }
        }
        skeletons.push(off);
        let level_skins: Vec<usize> = input
            .skins
            .iter()
            .zip(&ibm_accessors)
            .map(|(s, &acc)| {
                let joints: Vec<usize> = s.joints.iter().map(|&j| j + off).collect();
                skins.push(json!({"joints": joints, "inverseBindMatrices": acc}));
                skins.len() - 1
            })
            .collect();
        let mut level_nodes = Vec::new();
        let mut level_meshes = Vec::new();
        for (i, inst) in rig.instances.iter().enumerate() {
            let range = inst.vertices.clone();
            let tris: Vec<[u32; 3]> =
                rig.triangles.iter().filter(|t| range.contains(&(t[0] as usize))).map(|t| t.map(|x| x - range.start as u32)).collect();
            let (skin, bind) = match inst.skin {
                Some(s) => {
                    (level_skins.get(s).copied().ok_or_else(|| LodError::Write(format!("skin {s} is not in the input")))?, Mat4::IDENTITY)
                }
                None => match rigid_skin.get(&(k, inst.node)) {
                    Some(e) => *e,
                    None => {
                        let w = rest_world.get(inst.node).copied().unwrap_or(Mat4::IDENTITY);
                        if !(w.determinant().abs() > 1e-30) || !w.is_finite() {
                            return Err(LodError::Write(format!("node {} has a singular rest transform", inst.node)));
                        }
                        let acc = b.floats(&affine(w.inverse()).to_cols_array(), None, "MAT4", 16, false);
                        skins.push(json!({"joints": [inst.node + off], "inverseBindMatrices": acc}));
                        let e = (skins.len() - 1, w);
                        rigid_skin.insert((k, inst.node), e);
                        e
                    }
                },
            };
            let rigid = inst.skin.is_none();
            let positions: Vec<Vec3> =
                rig.positions[range.clone()].iter().map(|&p| if rigid { bind.transform_point3(p) } else { p }).collect();
            let normals = unit_normals(&positions, &tris);
            let mut joints: Vec<[u16; 4]> = Vec::with_capacity(positions.len());
            let mut weights: Vec<f32> = Vec::with_capacity(positions.len() * 4);
            for v in range.clone() {
                if rigid {
                    joints.push([0; 4]);
                    weights.extend([1.0, 0.0, 0.0, 0.0]);
                } else {
                    let w = rig.weights.get(v).copied().unwrap_or_default();
                    let sum: f32 = w.iter().sum();
                    let w = if sum > 0.0 { w.map(|x| x / sum) } else { [1.0, 0.0, 0.0, 0.0] };
                    // Unused slots point at joint 0 (the validator warns about others).
                    let j = rig.joints.get(v).copied().unwrap_or_default();
                    joints.push(std::array::from_fn(|k| if w[k] > 0.0 { j[k] } else { 0 }));
                    weights.extend(w);
                }
            }
            let pos_acc = b.vec3s(&positions, Some(ARRAY_BUFFER), true);
            let nrm_acc = b.vec3s(&normals, Some(ARRAY_BUFFER), false);
            let jnt_acc = b.joints(&joints);
            let wgt_acc = b.floats(&weights, Some(ARRAY_BUFFER), "VEC4", 4, false);
            let flat: Vec<u32> = tris.iter().flatten().copied().collect();
            let idx_acc = b.u32s(&flat, Some(ELEMENT_ARRAY_BUFFER));
            let mut targets = Vec::new();
            for t in &inst.morph_targets {
                let deltas: Vec<Vec3> = t.iter().map(|&d| if rigid { bind.transform_vector3(d) } else { d }).collect();
                targets.push(json!({"POSITION": b.vec3s(&deltas, Some(ARRAY_BUFFER), true)}));
            }
            let mut prim = json!({
                "attributes": {"POSITION": pos_acc, "NORMAL": nrm_acc, "JOINTS_0": jnt_acc, "WEIGHTS_0": wgt_acc},
                "indices": idx_acc,
                "material": 0,
                "mode": 4,
            });
            let mut mesh = json!({"name": format!("lod{k}_mesh{i}")});
            if !targets.is_empty() {
                prim["targets"] = json!(targets);
                let mut w = inst.default_weights.clone();
                w.resize(inst.morph_targets.len(), 0.0);
                mesh["weights"] = json!(w);
            }
            mesh["primitives"] = json!([prim]);
            meshes.push(mesh);
            nodes.push(json!({"name": format!("lod{k}_mesh{i}"), "mesh": meshes.len() - 1, "skin": skin}));
            if !inst.morph_targets.is_empty() {
                morph_nodes.push((inst.node, nodes.len() - 1));
            }
            level_nodes.push(nodes.len() - 1);
            level_meshes.push(meshes.len() - 1);
        }
        let table = if level.to_coarser.is_empty() { Value::Null } else { json!(b.u32s(&level.to_coarser, None)) };
        let mut scene_nodes: Vec<usize> = roots.iter().map(|&r| r + off).collect();
        scene_nodes.extend(&level_nodes);
        scenes.push(json!({"name": format!("lod{k}"), "nodes": scene_nodes}));
        levels_json.push(json!({
            "scene": k,
            "skeleton": off,
            "nodes": level_nodes,
            "meshes": level_meshes,
            "triangles": rig.triangles.len(),
            "vertices": rig.positions.len(),
            "target": level.target,
            "toCoarser": table,
        }));
    }

    let mut animations = Vec::new();
    for a in &input.animations {
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        for ch in &a.channels {
            if ch.times.is_empty() || ch.width == 0 {
                continue;
            }
            let mut values = ch.values.clone();
            if ch.property == AnimatedProperty::Rotation && ch.interpolation != Interpolation::CubicSpline {
                for q in values.chunks_exact_mut(4) {
                    let n = glam::Vec4::from_slice(q).normalize_or_zero();
                    q.copy_from_slice(&n.to_array());
                }
            }
            let (ty, width) = match ch.property {
                AnimatedProperty::Rotation => ("VEC4", 4),
                AnimatedProperty::MorphWeights => ("SCALAR", 1),
                _ => ("VEC3", 3),
            };
            let targets: Vec<(usize, &str)> = match ch.property {
                AnimatedProperty::MorphWeights => {
                    morph_nodes.iter().filter(|(n, _)| *n == ch.node).map(|&(_, out)| (out, "weights")).collect()
                }
                // Every level's copy of the node moves alike (one sampler, a channel each).
                AnimatedProperty::Translation => skeletons.iter().map(|&o| (ch.node + o, "translation")).collect(),
                AnimatedProperty::Rotation => skeletons.iter().map(|&o| (ch.node + o, "rotation")).collect(),
                AnimatedProperty::Scale => skeletons.iter().map(|&o| (ch.node + o, "scale")).collect(),
            };
            if targets.is_empty() || ch.node >= node_count {
                continue;
            }
            let input_acc = b.floats(&ch.times, None, "SCALAR", 1, true);
            let output_acc = b.floats(&values, None, ty, width, false);
            let interpolation = match ch.interpolation {
                Interpolation::Step => "STEP",
                Interpolation::Linear => "LINEAR",
                Interpolation::CubicSpline => "CUBICSPLINE",
            };
            samplers.push(json!({"input": input_acc, "output": output_acc, "interpolation": interpolation}));
            for (node, path) in targets {
                channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": node, "path": path}}));
            }
        }
        if channels.is_empty() {
            continue;
        }
        let mut anim = json!({"samplers": samplers, "channels": channels});
        if let Some(name) = &a.name {
            anim["name"] = json!(name);
        }
        animations.push(anim);
    }

    let mut root = json!({
        "asset": {"version": "2.0", "generator": "pmcodec lod"},
        "scene": 0,
        "scenes": scenes,
        "nodes": nodes,
        "meshes": meshes,
        // The input's materials are not carried; one plain, non-metallic material keeps viewers
        // from drawing glTF's default (fully metallic: black without an environment map).
        "materials": [{"name": "pmcodec plain", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}}],
        "skins": skins,
        "extras": {"pmcodec_lod": {
            "version": 2,
            "placement": placement,
            "poses": chain.pose_count,
            "levels": levels_json,
        }},
    });
    if !animations.is_empty() {
        root["animations"] = json!(animations);
    }
    if skins.is_empty()
        && let Some(o) = root.as_object_mut()
    {
        o.remove("skins");
    }
    b.finish(root).map_err(|e| LodError::Write(e.to_string()))
}
