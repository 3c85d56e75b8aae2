//! GLB output of an LOD chain: every level skinned, with its morph targets and its appearance,
//! on ONE copy of the input's node hierarchy, skins, materials, textures and animations, one
//! scene per level, and the chain described in the root `extras.pmcodec_lod` (specified in
//! `proto/lod.md`).
//!
//! * Nodes 0..N are the input's nodes (transforms and hierarchy, no meshes): the skeleton every
//!   level shares. Each level adds one root node per mesh, named `lod<k>_mesh<i>`, carrying that
//!   mesh and a skin on those joints.
//! * Rigid parts (meshes placed by a node, not skinned) become skinned by a one-joint skin on
//!   their node, with bind-space positions `W p` and inverse bind matrix `W^-1` (`W` the node's
//!   rest world transform), which poses exactly as before; one such skin per node, shared.
//! * Scene k holds the skeleton's roots and level k's mesh nodes; scene 0 (the default) is
//!   level 0, the welded input, so any viewer shows the full model and its animations.
//! * Animation channels are written once (times and values as read, quaternions renormalised);
//!   a morph-weight channel on an input mesh node is copied onto every level's node that carries
//!   that mesh's morph targets (sharing the sampler).
//! * Vertices are the level's wedges (one per vertex and attribute record); one primitive per
//!   material, all primitives of a mesh sharing its vertex accessors. Attributes: POSITION (with
//!   min/max), NORMAL (unit, from the level's rest positions, split where the input's normals
//!   crease; left out for faceted input, which glTF then draws flat), TEXCOORD_0/1 and COLOR_0
//!   as the input has them, JOINTS_0 (u16), WEIGHTS_0 (float, summing to 1; unused slots joint
//!   0), indices (u16 or u32), morph target POSITION deltas. The correspondence tables are u32
//!   SCALAR accessors no mesh uses, over those vertices.

use crate::LodError;
use crate::chain::LodChain;
use crate::poses::pose_at;
use glam::{Mat4, Vec3};
use pmcodec_mesh::Appearance;
use pmcodec_mesh::glb::{ARRAY_BUFFER, GlbBuilder, triangles_by_material, wedge_attributes, wedge_normals, write_looks};
use pmcodec_mesh::gltf_input::{AnimatedProperty, Interpolation, RiggedMesh};
use serde_json::{Value, json};
use std::collections::HashMap;

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

/// A level's appearance, or for a bare surface one wedge per vertex and no attributes.
pub fn level_appearance(rig: &RiggedMesh) -> Appearance {
    match &rig.appearance {
        Some(a) => a.clone(),
        None => Appearance {
            corner_wedges: rig.triangles.clone(),
            wedge_vertex: (0..rig.vertex_count() as u32).collect(),
            ..Default::default()
        },
    }
}

/// Whether the input is faceted: most corners carry their face's own normal (the Fox, the
/// robot). Such levels are written without normals, which glTF draws flat (§3.7.2.1).
fn faceted(rig: &RiggedMesh) -> bool {
    let Some(app) = rig.appearance.as_ref().filter(|a| !a.normals.is_empty()) else { return false };
    let mut flat = 0usize;
    for (tri, cw) in rig.triangles.iter().zip(&app.corner_wedges) {
        let [a, b, c] = tri.map(|i| rig.positions[i as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        flat += cw.iter().filter(|&&w| Vec3::from_array(app.normals[w as usize]).dot(n) > 0.999).count();
    }
    flat * 10 > rig.triangles.len() * 3 * 9
}

/// Per level: for each written vertex (wedge), its level vertex; wedges are numbered over the
/// level's meshes in order.
pub fn wedge_tables(chain: &LodChain) -> Vec<Vec<u32>> {
    let levels: Vec<Appearance> = chain.levels.iter().map(|l| level_appearance(&l.rig)).collect();
    let mut out = Vec::with_capacity(levels.len());
    for (k, app) in levels.iter().enumerate() {
        let Some(next) = levels.get(k + 1) else {
            out.push(Vec::new());
            break;
        };
        // Wedges of the next level by vertex.
        let mut by_vertex: HashMap<u32, Vec<u32>> = HashMap::new();
        for (w, &v) in next.wedge_vertex.iter().enumerate() {
            by_vertex.entry(v).or_default().push(w as u32);
        }
        let level = &chain.levels[k];
        let (mine, theirs) = (wedge_materials(app), wedge_materials(next));
        let table = app
            .wedge_vertex
            .iter()
            .enumerate()
            .map(|(w, &v)| {
                let to = level.to_coarser.get(v as usize).copied().unwrap_or(0);
                let choices = by_vertex.get(&to).map(Vec::as_slice).unwrap_or_default();
                // The wedge of the same attributes, or the nearest.
                let dist = |c: u32| -> f32 {
                    let col = app
                        .colors
                        .get(w)
                        .zip(next.colors.get(c as usize))
                        .map_or(0.0, |(x, y)| x.iter().zip(y).map(|(a, b)| (a - b).powi(2)).sum());
                    let other = if mine.get(w) == theirs.get(c as usize) { 0.0 } else { 1e9 };
                    uv_d2(&app.uv0, &next.uv0, w, c) + uv_d2(&app.uv1, &next.uv1, w, c) + col + other
                };
                choices.iter().copied().min_by(|a, b| dist(*a).total_cmp(&dist(*b))).unwrap_or(0)
            })
            .collect();
        out.push(table);
    }
    out
}

/// The material of each wedge (of a triangle using it).
fn wedge_materials(app: &Appearance) -> Vec<u32> {
    let mut out = vec![0; app.wedge_count()];
    for (t, cw) in app.corner_wedges.iter().enumerate() {
        for &w in cw {
            if let Some(m) = out.get_mut(w as usize) {
                *m = app.material_of(t);
            }
        }
    }
    out
}

fn uv_d2(a: &[[f32; 2]], b: &[[f32; 2]], w: usize, c: u32) -> f32 {
    a.get(w).zip(b.get(c as usize)).map_or(0.0, |(x, y)| (x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2))
}

/// The skeleton (the input's nodes), its roots, and which nodes animations move.
fn skeleton(input: &RiggedMesh) -> (Vec<Value>, Vec<usize>) {
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
    let roots = (0..node_count).filter(|&n| input.parents.get(n).is_none_or(|p| p.is_none())).collect();
    (nodes, roots)
}

/// What the levels share while they are written.
struct Shared {
    b: GlbBuilder,
    nodes: Vec<Value>,
    meshes: Vec<Value>,
    skins: Vec<Value>,
    /// Skin index of every input skin.
    input_skins: Vec<usize>,
    /// One-joint skins of rigid parts by node, with the node's rest world transform.
    rigid_skins: HashMap<usize, (usize, Mat4)>,
    rest_world: Vec<Mat4>,
    /// Input mesh node and level node of every mesh with morph targets.
    morph_nodes: Vec<(usize, usize)>,
    faceted: bool,
    /// Material of a primitive when the input has none of its own.
    plain: Option<u32>,
}

impl Shared {
    fn skin_for(&mut self, inst: &pmcodec_mesh::gltf_input::MeshInstance) -> Result<(usize, Mat4), LodError> {
        if let Some(s) = inst.skin {
            let skin = self.input_skins.get(s).copied().ok_or_else(|| LodError::Write(format!("skin {s} is not in the input")))?;
            return Ok((skin, Mat4::IDENTITY));
        }
        if let Some(e) = self.rigid_skins.get(&inst.node) {
            return Ok(*e);
        }
        let w = self.rest_world.get(inst.node).copied().unwrap_or(Mat4::IDENTITY);
        if !(w.determinant().abs() > 1e-30) || !w.is_finite() {
            return Err(LodError::Write(format!("node {} has a singular rest transform", inst.node)));
        }
        let acc = self.b.floats(&affine(w.inverse()).to_cols_array(), None, "MAT4", 16, false);
        self.skins.push(json!({"joints": [inst.node], "inverseBindMatrices": acc}));
        let e = (self.skins.len() - 1, w);
        self.rigid_skins.insert(inst.node, e);
        Ok(e)
    }

    /// Writes level `k`'s meshes and their nodes; returns the nodes, the meshes and the number
    /// of vertices written.
    fn write_level(&mut self, k: usize, rig: &RiggedMesh) -> Result<(Vec<usize>, Vec<usize>, usize), LodError> {
        let app = level_appearance(rig);
        // Bind-space positions of every level vertex (rigid parts in their node's world space).
        let mut bind_of = vec![Mat4::IDENTITY; rig.vertex_count()];
        let mut skin_of = Vec::with_capacity(rig.instances.len());
        for inst in &rig.instances {
            let (skin, bind) = self.skin_for(inst)?;
            skin_of.push((skin, bind));
            for v in inst.vertices.clone() {
                bind_of[v] = bind;
            }
        }
        let positions: Vec<Vec3> = rig.positions.iter().zip(&bind_of).map(|(p, m)| m.transform_point3(*p)).collect();
        let normals = wedge_normals(&positions, &rig.triangles, &app);
        let (mut level_nodes, mut level_meshes, mut written) = (Vec::new(), Vec::new(), 0);
        let mut wedge_start = 0usize;
        for (i, inst) in rig.instances.iter().enumerate() {
            let range = inst.vertices.clone();
            // This mesh's wedges: a contiguous run (level_rig creates them instance by instance).
            let end = wedge_start + app.wedge_vertex[wedge_start..].iter().take_while(|&&v| range.contains(&(v as usize))).count();
            let wedges = wedge_start..end;
            wedge_start = end;
            let local = |w: u32| w - wedges.start as u32;
            let sub = Appearance {
                corner_wedges: Vec::new(),
                wedge_vertex: app.wedge_vertex[wedges.clone()].to_vec(),
                uv0: app.uv0.get(wedges.clone()).map(<[_]>::to_vec).unwrap_or_default(),
                uv1: app.uv1.get(wedges.clone()).map(<[_]>::to_vec).unwrap_or_default(),
                colors: app.colors.get(wedges.clone()).map(<[_]>::to_vec).unwrap_or_default(),
                ..Default::default()
            };
            let (skin, bind) = skin_of[i];
            let rigid = inst.skin.is_none();
            let wpos: Vec<Vec3> = sub.wedge_vertex.iter().map(|&v| positions[v as usize]).collect();
            let mut attributes = wedge_attributes(&mut self.b, &sub);
            attributes.insert("POSITION".into(), json!(self.b.vec3s(&wpos, Some(ARRAY_BUFFER), true)));
            if !self.faceted {
                let n: Vec<Vec3> = normals[wedges.clone()].to_vec();
                attributes.insert("NORMAL".into(), json!(self.b.vec3s(&n, Some(ARRAY_BUFFER), false)));
            }
            let mut joints: Vec<[u16; 4]> = Vec::with_capacity(wpos.len());
            let mut weights: Vec<f32> = Vec::with_capacity(wpos.len() * 4);
            for &v in &sub.wedge_vertex {
                let v = v as usize;
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
            attributes.insert("JOINTS_0".into(), json!(self.b.joints(&joints)));
            attributes.insert("WEIGHTS_0".into(), json!(self.b.floats(&weights, Some(ARRAY_BUFFER), "VEC4", 4, false)));
            let mut targets = Vec::new();
            for t in &inst.morph_targets {
                let deltas: Vec<Vec3> = sub
                    .wedge_vertex
                    .iter()
                    .map(|&v| {
                        let d = t.get(v as usize - range.start).copied().unwrap_or(Vec3::ZERO);
                        if rigid { bind.transform_vector3(d) } else { d }
                    })
                    .collect();
                targets.push(json!({"POSITION": self.b.vec3s(&deltas, Some(ARRAY_BUFFER), true)}));
            }
            // This mesh's triangles by material.
            let mine = Appearance {
                corner_wedges: rig
                    .triangles
                    .iter()
                    .zip(&app.corner_wedges)
                    .filter(|(t, _)| range.contains(&(t[0] as usize)))
                    .map(|(_, cw)| cw.map(local))
                    .collect(),
                triangle_material: rig
                    .triangles
                    .iter()
                    .enumerate()
                    .filter(|(_, t)| range.contains(&(t[0] as usize)))
                    .map(|(t, _)| app.material_of(t))
                    .collect(),
                ..Default::default()
            };
            let mut prims = Vec::new();
            for (material, indices) in triangles_by_material(&mine) {
                let idx = self.b.indices(&indices, wpos.len());
                let mut prim = json!({"attributes": attributes, "indices": idx, "mode": 4});
                prim["material"] = json!(self.plain.unwrap_or(material));
                if !targets.is_empty() {
                    prim["targets"] = json!(targets);
                }
                prims.push(prim);
            }
            let mut mesh = json!({"name": format!("lod{k}_mesh{i}"), "primitives": prims});
            if !targets.is_empty() {
                let mut w = inst.default_weights.clone();
                w.resize(inst.morph_targets.len(), 0.0);
                mesh["weights"] = json!(w);
            }
            self.meshes.push(mesh);
            self.nodes.push(json!({"name": format!("lod{k}_mesh{i}"), "mesh": self.meshes.len() - 1, "skin": skin}));
            if !inst.morph_targets.is_empty() {
                self.morph_nodes.push((inst.node, self.nodes.len() - 1));
            }
            level_nodes.push(self.nodes.len() - 1);
            level_meshes.push(self.meshes.len() - 1);
            written += wpos.len();
        }
        Ok((level_nodes, level_meshes, written))
    }
}

/// The GLB bytes of a chain (see the module documentation).
pub fn chain_glb(chain: &LodChain, placement: &str) -> Result<Vec<u8>, LodError> {
    let input = &chain.input;
    let (nodes, roots) = skeleton(input);
    let mut root = json!({"asset": {"version": "2.0", "generator": "pmcodec lod"}, "scene": 0});
    let mut sh = Shared {
        b: GlbBuilder::default(),
        nodes,
        meshes: Vec::new(),
        skins: Vec::new(),
        input_skins: Vec::new(),
        rigid_skins: HashMap::new(),
        rest_world: pose_at(input, None, 0.0).world,
        morph_nodes: Vec::new(),
        faceted: faceted(input),
        plain: None,
    };
    // The materials, textures and images once; without them one plain, non-metallic material
    // keeps viewers from drawing glTF's default (fully metallic: black without an environment).
    match input.appearance.as_ref().filter(|a| !a.materials.is_empty()) {
        Some(app) => write_looks(&mut sh.b, app, &mut root),
        None => {
            root["materials"] = json!([{"name": "pmcodec plain", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}}]);
            sh.plain = Some(0);
        }
    }
    // The input's skins' inverse bind matrices and joints, written once and shared.
    for s in &input.skins {
        let ibm: Vec<f32> = s.inverse_bind_matrices.iter().flat_map(|m| affine(*m).to_cols_array()).collect();
        let acc = sh.b.floats(&ibm, None, "MAT4", 16, false);
        sh.skins.push(json!({"joints": s.joints, "inverseBindMatrices": acc}));
        sh.input_skins.push(sh.skins.len() - 1);
    }
    let tables = wedge_tables(chain);
    let mut levels_json = Vec::new();
    let mut scenes = Vec::new();
    for (k, level) in chain.levels.iter().enumerate() {
        let (level_nodes, level_meshes, vertices) = sh.write_level(k, &level.rig)?;
        let table = match tables.get(k) {
            Some(t) if !t.is_empty() => json!(sh.b.u32s(t, None)),
            _ => Value::Null,
        };
        let mut scene_nodes = roots.clone();
        scene_nodes.extend(&level_nodes);
        scenes.push(json!({"name": format!("lod{k}"), "nodes": scene_nodes}));
        levels_json.push(json!({
            "scene": k,
            "nodes": level_nodes,
            "meshes": level_meshes,
            "triangles": level.rig.triangles.len(),
            "vertices": vertices,
            "target": level.target,
            "toCoarser": table,
        }));
    }
    let animations = write_animations(&mut sh, input);
    root["scenes"] = json!(scenes);
    root["nodes"] = json!(sh.nodes);
    root["meshes"] = json!(sh.meshes);
    if !sh.skins.is_empty() {
        root["skins"] = json!(sh.skins);
    }
    if !animations.is_empty() {
        root["animations"] = json!(animations);
    }
    root["extras"] = json!({"pmcodec_lod": {"version": 3, "placement": placement, "poses": chain.pose_count, "levels": levels_json}});
    sh.b.finish(root).map_err(|e| LodError::Write(e.to_string()))
}

/// The input's animations, once: node channels as read, morph-weight channels onto every
/// level's node carrying that mesh's targets (one sampler, a channel each).
fn write_animations(sh: &mut Shared, input: &RiggedMesh) -> Vec<Value> {
    let node_count = input.nodes.len();
    let mut animations = Vec::new();
    for a in &input.animations {
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        for ch in &a.channels {
            if ch.times.is_empty() || ch.width == 0 || ch.node >= node_count {
                continue;
            }
            let mut values = ch.values.clone();
            if ch.property == AnimatedProperty::Rotation && ch.interpolation != Interpolation::CubicSpline {
                for q in values.chunks_exact_mut(4) {
                    let n = glam::Vec4::from_slice(q).normalize_or_zero();
                    q.copy_from_slice(&n.to_array());
                }
            }
            let (ty, width, path) = match ch.property {
                AnimatedProperty::Rotation => ("VEC4", 4, "rotation"),
                AnimatedProperty::MorphWeights => ("SCALAR", 1, "weights"),
                AnimatedProperty::Translation => ("VEC3", 3, "translation"),
                AnimatedProperty::Scale => ("VEC3", 3, "scale"),
            };
            let targets: Vec<usize> = match ch.property {
                AnimatedProperty::MorphWeights => sh.morph_nodes.iter().filter(|(n, _)| *n == ch.node).map(|&(_, out)| out).collect(),
                _ => vec![ch.node],
            };
            if targets.is_empty() {
                continue;
            }
            let input_acc = sh.b.floats(&ch.times, None, "SCALAR", 1, true);
            let output_acc = sh.b.floats(&values, None, ty, width, false);
            let interpolation = match ch.interpolation {
                Interpolation::Step => "STEP",
                Interpolation::Linear => "LINEAR",
                Interpolation::CubicSpline => "CUBICSPLINE",
            };
            samplers.push(json!({"input": input_acc, "output": output_acc, "interpolation": interpolation}));
            for node in targets {
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
    animations
}
