//! glTF 2.0 / GLB input: skinned and morph-target meshes posed by an animation, sampled at a
//! frame rate, as a [`Sequence`].
//!
//! Every mesh node of the default scene is merged into one vertex and face set; each glTF
//! primitive is numbered in visiting order (depth first through the scene's nodes, primitives
//! in mesh order) and [`Sequence::source`] maps every vertex back to `(primitive, index)`.
//! Skinned nodes are posed by linear blend skinning (glTF 2.0 section 3.7.3: the joint matrices
//! are the joints' world transforms times the inverse bind matrices; the mesh node's own
//! transform does not apply); other mesh nodes by their world transform. Morph targets are
//! applied before skinning. Vertices that are the same in every pose (a seam split for normals
//! or UVs, or an unindexed file) are welded, so the surface is connected.

use crate::{MeshError, Sequence, SourceVertex};
use glam::{Mat4, Quat, Vec3};
use gltf::animation::util::ReadOutputs;
use gltf::animation::{Interpolation, Property};
use std::collections::HashMap;
use std::path::Path;

/// Which animation to sample.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AnimationSelector {
    Index(usize),
    Name(String),
}

/// How to read a glTF file.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfOptions {
    /// The animation to sample (default: the first; a file without animations gives one frame).
    pub animation: Option<AnimationSelector>,
    /// Frames per second at which the animation is sampled.
    pub frame_rate: f32,
    /// Merge vertices that coincide in every pose.
    pub weld: bool,
}

impl Default for GltfOptions {
    fn default() -> Self {
        GltfOptions { animation: None, frame_rate: 30.0, weld: true }
    }
}

/// Name (or `#index` when unnamed) and duration in seconds of every animation of a file.
pub fn list_animations(path: &Path) -> Result<Vec<(String, f32)>, MeshError> {
    let (doc, buffers) = open_path(path)?;
    let rig = Rig::new(&doc, &buffers)?;
    Ok(rig.animations.iter().map(|a| (a.name.clone(), a.duration)).collect())
}

/// Reads a .gltf or .glb file (external buffers are resolved next to it).
pub fn load_gltf(path: &Path, opts: &GltfOptions) -> Result<Sequence, MeshError> {
    let (doc, buffers) = open_path(path)?;
    to_sequence(&doc, &buffers, opts)
}

/// Reads a GLB (or a self-contained .gltf with embedded data URIs) from memory.
pub fn load_gltf_bytes(bytes: &[u8], opts: &GltfOptions) -> Result<Sequence, MeshError> {
    let (doc, buffers) = parse(bytes, None).map_err(|e| match e {
        MeshError::Gltf(m) if m.contains("external") || m.contains("uri") => {
            MeshError::Gltf(format!("{m} (a .gltf that references external files can only be read from a path)"))
        }
        e => e,
    })?;
    to_sequence(&doc, &buffers, opts)
}

fn open_path(path: &Path) -> Result<(gltf::Document, Vec<gltf::buffer::Data>), MeshError> {
    let bytes = std::fs::read(path).map_err(|source| MeshError::Io { path: path.to_path_buf(), source })?;
    parse(&bytes, path.parent()).map_err(|e| match e {
        MeshError::Gltf(m) => MeshError::Gltf(format!("{}: {m}", path.display())),
        e => e,
    })
}

/// Parses and validates a document and loads its buffers. Required extensions are checked on
/// the unvalidated document first, so that a Draco- or meshopt-compressed file is reported as
/// an unsupported feature by name rather than as a validation failure.
fn parse(bytes: &[u8], base: Option<&Path>) -> Result<(gltf::Document, Vec<gltf::buffer::Data>), MeshError> {
    let raw = gltf::Gltf::from_slice_without_validation(bytes).map_err(gltf_err)?;
    check_extensions(&raw.document)?;
    let g = gltf::Gltf::from_slice(bytes).map_err(gltf_err)?;
    let buffers = gltf::import_buffers(&g.document, base, g.blob.clone()).map_err(gltf_err)?;
    Ok((g.document, buffers))
}

fn gltf_err(e: gltf::Error) -> MeshError {
    MeshError::Gltf(e.to_string())
}

/// Any required extension changes how data must be read; none is implemented, so say which.
fn check_extensions(doc: &gltf::Document) -> Result<(), MeshError> {
    let required: Vec<&str> = doc.extensions_required().collect();
    if required.is_empty() {
        Ok(())
    } else {
        Err(MeshError::Unsupported(format!("required extension(s) {}", required.join(", "))))
    }
}

fn to_sequence(doc: &gltf::Document, buffers: &[gltf::buffer::Data], opts: &GltfOptions) -> Result<Sequence, MeshError> {
    if !(opts.frame_rate.is_finite() && opts.frame_rate > 0.0 && opts.frame_rate <= 1000.0) {
        return Err(MeshError::Invalid(format!("frame rate {} is not in (0, 1000]", opts.frame_rate)));
    }
    let mut rig = Rig::new(doc, buffers)?;
    if opts.weld {
        rig.weld();
    }
    let anim = match &opts.animation {
        None => (!rig.animations.is_empty()).then_some(0),
        Some(sel) => {
            let found = match sel {
                AnimationSelector::Index(i) => (*i < rig.animations.len()).then_some(*i),
                AnimationSelector::Name(n) => rig.animations.iter().position(|a| &a.name == n),
            };
            if found.is_none() {
                let names: Vec<&str> = rig.animations.iter().map(|a| a.name.as_str()).collect();
                return Err(MeshError::Invalid(format!("no animation {sel:?}; the file has {names:?}")));
            }
            found
        }
    };
    let (duration, label) = match anim {
        Some(a) => (rig.animations[a].duration, rig.animations[a].name.clone()),
        None => (0.0, "rest".to_string()),
    };
    let count = (duration * opts.frame_rate).floor() as usize + 1;
    if count > 100_000 {
        return Err(MeshError::TooLarge { what: format!("{count} frames at {} fps", opts.frame_rate) });
    }
    let mut seq = Sequence {
        triangles: rig.triangles.clone(),
        frame_rate: opts.frame_rate,
        source: rig.source.clone(),
        ..Default::default()
    };
    for i in 0..count {
        let t = i as f32 / opts.frame_rate;
        seq.frames.push(rig.pose(anim, t));
        seq.frame_names.push(format!("{label}@{t:.3}s"));
    }
    if rig.vertices.iter().any(|v| !v.deltas.is_empty()) {
        seq.morph_displacement = rig.vertices.iter().map(|v| v.deltas.iter().map(|d| d.length()).sum()).collect();
    }
    seq.drop_degenerate_faces();
    seq.validate()?;
    Ok(seq)
}

/// One vertex of the merged mesh, as authored.
#[derive(Clone, Debug, PartialEq)]
pub struct RigVertex {
    pub rest: Vec3,
    /// Index into [`Rig::groups`]: which node (and skin) poses this vertex.
    pub group: u32,
    pub joints: [u16; 4],
    pub weights: [f32; 4],
    /// Position delta of each morph target of the vertex's mesh.
    pub deltas: Vec<Vec3>,
}

/// A mesh node: its node index, its skin (if any) and its mesh's default morph weights.
#[derive(Clone, Debug, PartialEq)]
pub struct RigGroup {
    pub node: usize,
    pub skin: Option<usize>,
    pub default_weights: Vec<f32>,
}

/// A skin: joint node indices and inverse bind matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct RigSkin {
    pub joints: Vec<usize>,
    pub inverse_bind: Vec<Mat4>,
}

/// One animation channel's keyframes.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub node: usize,
    pub property: ChannelProperty,
    pub interpolation: Interpolation,
    pub times: Vec<f32>,
    /// `components` floats per key (three per key for cubic splines: in-tangent, value,
    /// out-tangent).
    pub values: Vec<f32>,
    pub components: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelProperty {
    Translation,
    Rotation,
    Scale,
    Weights,
}

#[derive(Clone, Debug, PartialEq)]
pub struct RigAnimation {
    pub name: String,
    pub duration: f32,
    pub channels: Vec<Channel>,
}

/// Everything needed to pose the merged mesh at any time of any animation: the authored
/// vertices with their skin and morph data, the node hierarchy and the animations. Later
/// stages (LOD output that keeps skins and morphs) read it directly.
#[derive(Clone, Debug, Default)]
pub struct Rig {
    pub vertices: Vec<RigVertex>,
    pub triangles: Vec<[u32; 3]>,
    pub source: Vec<SourceVertex>,
    pub groups: Vec<RigGroup>,
    pub skins: Vec<RigSkin>,
    /// Rest TRS of every node and its children.
    pub rest: Vec<(Vec3, Quat, Vec3)>,
    pub node_children: Vec<Vec<usize>>,
    pub roots: Vec<usize>,
    pub animations: Vec<RigAnimation>,
}

impl Rig {
    /// Reads the default scene's mesh nodes, skins and animations.
    pub fn new(doc: &gltf::Document, buffers: &[gltf::buffer::Data]) -> Result<Self, MeshError> {
        let get = |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d.0[..]);
        let mut rig = Rig::default();
        for node in doc.nodes() {
            let (t, r, s) = node.transform().decomposed();
            rig.rest.push((Vec3::from_array(t), Quat::from_array(r).normalize(), Vec3::from_array(s)));
            rig.node_children.push(node.children().map(|c| c.index()).collect());
        }
        for skin in doc.skins() {
            let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
            let inverse_bind: Vec<Mat4> = match skin.reader(get).read_inverse_bind_matrices() {
                Some(m) => m.map(|c| Mat4::from_cols_array_2d(&c)).collect(),
                None => vec![Mat4::IDENTITY; joints.len()],
            };
            if inverse_bind.len() < joints.len() {
                return Err(MeshError::Gltf(format!("skin {} has {} inverse bind matrices for {} joints", skin.index(), inverse_bind.len(), joints.len())));
            }
            rig.skins.push(RigSkin { joints, inverse_bind });
        }
        let scene = doc.default_scene().or_else(|| doc.scenes().next());
        rig.roots = match &scene {
            Some(s) => s.nodes().map(|n| n.index()).collect(),
            None => doc.nodes().map(|n| n.index()).collect(),
        };
        // Depth-first over the scene, guarding against cycles in a hostile file.
        let mut visited = vec![false; rig.rest.len()];
        let mut stack: Vec<usize> = rig.roots.iter().rev().copied().collect();
        let mut primitive_index = 0u32;
        while let Some(n) = stack.pop() {
            if n >= visited.len() || visited[n] {
                continue;
            }
            visited[n] = true;
            stack.extend(rig.node_children[n].iter().rev().copied());
            let Some(node) = doc.nodes().nth(n) else { continue };
            let Some(mesh) = node.mesh() else { continue };
            let group = rig.groups.len() as u32;
            rig.groups.push(RigGroup {
                node: n,
                skin: node.skin().map(|s| s.index()),
                default_weights: node.weights().or(mesh.weights()).map(|w| w.to_vec()).unwrap_or_default(),
            });
            for prim in mesh.primitives() {
                rig.add_primitive(&prim, group, primitive_index, &get)?;
                primitive_index += 1;
            }
        }
        if rig.vertices.is_empty() {
            return Err(MeshError::Empty { what: "the glTF scene has no mesh with triangles".into() });
        }
        for anim in doc.animations() {
            rig.animations.push(read_animation(&anim, &get, rig.rest.len())?);
        }
        Ok(rig)
    }

    fn add_primitive<'a, 's, F>(&mut self, prim: &'a gltf::Primitive<'a>, group: u32, index: u32, get: &F) -> Result<(), MeshError>
    where
        F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
    {
        use gltf::mesh::Mode;
        let reader = prim.reader(get.clone());
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| MeshError::Gltf(format!("primitive {index} has no POSITION")))?
            .map(Vec3::from_array)
            .collect();
        let n = positions.len();
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..n as u32).collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(MeshError::Gltf(format!("primitive {index}: index {bad} is beyond its {n} vertices")));
        }
        let tris: Vec<[u32; 3]> = match prim.mode() {
            Mode::Triangles => indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            Mode::TriangleStrip => (2..indices.len())
                .map(|i| if i % 2 == 0 { [indices[i - 2], indices[i - 1], indices[i]] } else { [indices[i - 1], indices[i - 2], indices[i]] })
                .collect(),
            Mode::TriangleFan => (2..indices.len()).map(|i| [indices[0], indices[i - 1], indices[i]]).collect(),
            other => return Err(MeshError::Unsupported(format!("primitive {index} has mode {other:?}; only triangles are meshes"))),
        };
        let joints: Vec<[u16; 4]> = match reader.read_joints(0) {
            Some(j) => j.into_u16().collect(),
            None => vec![[0; 4]; n],
        };
        let weights: Vec<[f32; 4]> = match reader.read_weights(0) {
            Some(w) => w.into_f32().collect(),
            None => vec![[1.0, 0.0, 0.0, 0.0]; n],
        };
        if joints.len() != n || weights.len() != n {
            return Err(MeshError::Gltf(format!("primitive {index}: JOINTS_0/WEIGHTS_0 counts differ from POSITION")));
        }
        let mut targets: Vec<Vec<Vec3>> = Vec::new();
        for (t, (pos, _, _)) in reader.read_morph_targets().enumerate() {
            let d: Vec<Vec3> = match pos {
                Some(p) => p.map(Vec3::from_array).collect(),
                None => vec![Vec3::ZERO; n],
            };
            if d.len() != n {
                return Err(MeshError::Gltf(format!("primitive {index}: morph target {t} has {} positions for {n}", d.len())));
            }
            targets.push(d);
        }
        let skin = self.groups[group as usize].skin;
        let joint_count = skin.and_then(|s| self.skins.get(s)).map_or(0, |s| s.joints.len());
        let base = self.vertices.len() as u32;
        for v in 0..n {
            let mut w = weights[v];
            let sum: f32 = w.iter().sum();
            // Weights should sum to 1 (glTF 3.7.3.3); normalise rather than reject small drift.
            if sum > 0.0 && sum.is_finite() {
                w.iter_mut().for_each(|x| *x /= sum);
            } else {
                w = [1.0, 0.0, 0.0, 0.0];
            }
            if skin.is_some() && joints[v].iter().zip(&w).any(|(&j, &wt)| wt > 0.0 && j as usize >= joint_count) {
                return Err(MeshError::Gltf(format!("primitive {index}: vertex {v} uses a joint beyond the skin's {joint_count}")));
            }
            self.vertices.push(RigVertex {
                rest: positions[v],
                group,
                joints: joints[v],
                weights: w,
                deltas: targets.iter().map(|t| t[v]).collect(),
            });
            self.source.push(SourceVertex { primitive: index, index: v as u32 });
        }
        self.triangles.extend(tris.into_iter().map(|t| t.map(|i| i + base)));
        Ok(())
    }

    /// Merges vertices that are identical in every pose: same node, same rest position, same
    /// skin influences and same morph deltas (compared bit for bit).
    pub fn weld(&mut self) {
        let mut key_to_new: HashMap<Vec<u32>, u32> = HashMap::new();
        let mut remap = Vec::with_capacity(self.vertices.len());
        let mut vertices = Vec::new();
        let mut source = Vec::new();
        for (v, vert) in self.vertices.iter().enumerate() {
            let mut key = vec![vert.group];
            key.extend(vert.rest.to_array().map(f32::to_bits));
            key.extend(vert.joints.iter().zip(&vert.weights).flat_map(|(&j, &w)| [if w > 0.0 { j as u32 } else { 0 }, w.to_bits()]));
            key.extend(vert.deltas.iter().flat_map(|d| d.to_array().map(f32::to_bits)));
            let next = vertices.len() as u32;
            let id = *key_to_new.entry(key).or_insert_with(|| {
                vertices.push(vert.clone());
                source.push(self.source[v]);
                next
            });
            remap.push(id);
        }
        self.vertices = vertices;
        self.source = source;
        for t in &mut self.triangles {
            *t = t.map(|i| remap[i as usize]);
        }
        self.triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    }

    /// Local TRS and morph weights of every node at time `t` of animation `anim`.
    fn sample(&self, anim: Option<usize>, t: f32) -> (Vec<Mat4>, HashMap<usize, Vec<f32>>) {
        let mut trs = self.rest.clone();
        let mut weights: HashMap<usize, Vec<f32>> = HashMap::new();
        if let Some(a) = anim.and_then(|a| self.animations.get(a)) {
            for ch in &a.channels {
                let v = ch.sample(t);
                let Some(slot) = trs.get_mut(ch.node) else { continue };
                match ch.property {
                    ChannelProperty::Translation if v.len() == 3 => slot.0 = Vec3::new(v[0], v[1], v[2]),
                    ChannelProperty::Rotation if v.len() == 4 => slot.1 = Quat::from_xyzw(v[0], v[1], v[2], v[3]).normalize(),
                    ChannelProperty::Scale if v.len() == 3 => slot.2 = Vec3::new(v[0], v[1], v[2]),
                    ChannelProperty::Weights => {
                        weights.insert(ch.node, v);
                    }
                    _ => {}
                }
            }
        }
        // World transforms, parents before children.
        let mut world = vec![Mat4::IDENTITY; trs.len()];
        let mut done = vec![false; trs.len()];
        let mut stack: Vec<(usize, Mat4)> = self.roots.iter().map(|&r| (r, Mat4::IDENTITY)).collect();
        while let Some((n, parent)) = stack.pop() {
            if n >= trs.len() || done[n] {
                continue;
            }
            done[n] = true;
            let (tr, rot, sc) = trs[n];
            world[n] = parent * Mat4::from_scale_rotation_translation(sc, rot, tr);
            for &c in &self.node_children[n] {
                stack.push((c, world[n]));
            }
        }
        (world, weights)
    }

    /// Positions of every vertex at time `t` of animation `anim` (None: the rest pose).
    pub fn pose(&self, anim: Option<usize>, t: f32) -> Vec<Vec3> {
        let (world, weights) = self.sample(anim, t);
        // Joint matrices per skin: world(joint) * inverse bind.
        let joint_mats: Vec<Vec<Mat4>> = self
            .skins
            .iter()
            .map(|s| s.joints.iter().zip(&s.inverse_bind).map(|(&j, ib)| world.get(j).copied().unwrap_or(Mat4::IDENTITY) * *ib).collect())
            .collect();
        self.vertices
            .iter()
            .map(|v| {
                let g = &self.groups[v.group as usize];
                let w = weights.get(&g.node).unwrap_or(&g.default_weights);
                let mut p = v.rest;
                for (d, &wt) in v.deltas.iter().zip(w) {
                    p += *d * wt;
                }
                match g.skin.and_then(|s| joint_mats.get(s)) {
                    Some(mats) => {
                        let mut out = Vec3::ZERO;
                        for (&j, &wt) in v.joints.iter().zip(&v.weights) {
                            if wt > 0.0 {
                                out += mats.get(j as usize).copied().unwrap_or(Mat4::IDENTITY).transform_point3(p) * wt;
                            }
                        }
                        out
                    }
                    None => world.get(g.node).copied().unwrap_or(Mat4::IDENTITY).transform_point3(p),
                }
            })
            .collect()
    }
}

fn read_animation<'a, 's, F>(anim: &'a gltf::Animation<'a>, get: &F, nodes: usize) -> Result<RigAnimation, MeshError>
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    let name = anim.name().map(str::to_string).unwrap_or_else(|| format!("#{}", anim.index()));
    let mut channels = Vec::new();
    let mut duration = 0f32;
    for ch in anim.channels() {
        let node = ch.target().node().index();
        if node >= nodes {
            continue;
        }
        let reader = ch.reader(get.clone());
        let times: Vec<f32> = match reader.read_inputs() {
            Some(t) => t.collect(),
            None => continue,
        };
        if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
            return Err(MeshError::Gltf(format!("animation {name:?}: keyframe times are not increasing numbers")));
        }
        let (property, values, components) = match reader.read_outputs() {
            Some(ReadOutputs::Translations(v)) => (ChannelProperty::Translation, v.flatten().collect::<Vec<f32>>(), 3),
            Some(ReadOutputs::Rotations(v)) => (ChannelProperty::Rotation, v.into_f32().flatten().collect(), 4),
            Some(ReadOutputs::Scales(v)) => (ChannelProperty::Scale, v.flatten().collect(), 3),
            Some(ReadOutputs::MorphTargetWeights(v)) => {
                let all: Vec<f32> = v.into_f32().collect();
                let per_key = if times.is_empty() { 0 } else { all.len() / times.len() };
                let per_key = if ch.sampler().interpolation() == Interpolation::CubicSpline { per_key / 3 } else { per_key };
                (ChannelProperty::Weights, all, per_key.max(1))
            }
            None => continue,
        };
        debug_assert!(matches!(ch.target().property(), Property::Translation | Property::Rotation | Property::Scale | Property::MorphTargetWeights));
        let interpolation = ch.sampler().interpolation();
        let per_key = components * if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        if times.is_empty() || values.len() < times.len() * per_key {
            return Err(MeshError::Gltf(format!("animation {name:?}: a channel has {} values for {} keys", values.len(), times.len())));
        }
        duration = duration.max(*times.last().unwrap_or(&0.0));
        channels.push(Channel { node, property, interpolation, times, values, components });
    }
    Ok(RigAnimation { name, duration, channels })
}

impl Channel {
    /// The channel's value at time t (clamped to its first and last keys), per glTF 2.0
    /// appendix C: step, linear (rotations by spherical interpolation on the shorter arc) and
    /// cubic Hermite splines with tangents scaled by the key interval.
    pub fn sample(&self, t: f32) -> Vec<f32> {
        let n = self.times.len();
        let c = self.components;
        let cubic = self.interpolation == Interpolation::CubicSpline;
        let value = |k: usize| -> &[f32] {
            let start = if cubic { (3 * k + 1) * c } else { k * c };
            &self.values[start..start + c]
        };
        if n == 1 || t <= self.times[0] {
            return value(0).to_vec();
        }
        if t >= self.times[n - 1] {
            return value(n - 1).to_vec();
        }
        let k = self.times.partition_point(|&x| x <= t).saturating_sub(1).min(n - 2);
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let dt = t1 - t0;
        let u = if dt > 0.0 { (t - t0) / dt } else { 0.0 };
        let (a, b) = (value(k), value(k + 1));
        let mut out: Vec<f32> = match self.interpolation {
            Interpolation::Step => a.to_vec(),
            Interpolation::Linear if self.property == ChannelProperty::Rotation => {
                let qa = Quat::from_xyzw(a[0], a[1], a[2], a[3]).normalize();
                let qb = Quat::from_xyzw(b[0], b[1], b[2], b[3]).normalize();
                // glam's slerp takes the shorter arc.
                qa.slerp(qb, u).to_array().to_vec()
            }
            Interpolation::Linear => a.iter().zip(b).map(|(x, y)| x + (y - x) * u).collect(),
            Interpolation::CubicSpline => {
                let out_tangent = &self.values[(3 * k + 2) * c..(3 * k + 3) * c];
                let in_tangent = &self.values[(3 * (k + 1)) * c..(3 * (k + 1) + 1) * c];
                let (u2, u3) = (u * u, u * u * u);
                let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
                let h10 = u3 - 2.0 * u2 + u;
                let h01 = -2.0 * u3 + 3.0 * u2;
                let h11 = u3 - u2;
                (0..c).map(|i| h00 * a[i] + h10 * dt * out_tangent[i] + h01 * b[i] + h11 * dt * in_tangent[i]).collect()
            }
        };
        if self.property == ChannelProperty::Rotation && out.len() == 4 {
            let q = Quat::from_xyzw(out[0], out[1], out[2], out[3]).normalize();
            out = q.to_array().to_vec();
        }
        out
    }
}
