//! glTF 2.0 / GLB input: skinned and morph-target meshes posed by an animation and sampled at a
//! frame rate into a [`Sequence`].
//!
//! # What is read
//!
//! * **Scene.** Every mesh node of the default scene (`scene`, else the first scene, else every
//!   root node) is merged into one vertex and face set. Nodes are visited depth first in
//!   pre-order (the scene's `nodes` in order, then each node's `children` in order) and, within a
//!   node, its mesh's primitives in order. [`SourceVertex::primitive`] numbers primitives in that
//!   visiting order, so a mesh instanced by two nodes contributes its primitives twice, under two
//!   numbers; [`RiggedMesh::primitives`] says which node, mesh and primitive each number is.
//! * **Posing.** A mesh node with a skin is posed by linear blend skinning (glTF 2.0 §3.7.3): each
//!   joint matrix is the joint's world transform times its inverse bind matrix, and the skinned
//!   node's own transform is ignored, as the specification requires. Other mesh nodes get their
//!   world transform. Morph targets (§3.7.2.2) are applied first, in the mesh's space, and then
//!   the skin. Only `POSITION` is read; normals, UVs and materials are not.
//! * **Animation.** Frames are taken at `t = i / frame_rate` for `i` in `0..=floor(duration *
//!   frame_rate)` (computed in `f32`), where the duration is the largest keyframe time of the
//!   animation's channels; a file without animations gives one frame, the rest pose. Sampling
//!   follows §3.11 and Appendix C: STEP, LINEAR (rotations by spherical interpolation on the
//!   shorter arc) and CUBICSPLINE (Hermite, tangents scaled by the key interval), clamped to the
//!   first and last key outside the keyed range.
//! * **Welding.** Exporters split vertices at UV and normal seams, and some write every triangle
//!   with its own three vertices, which leaves a surface in pieces. [`RiggedMesh::weld`] merges
//!   vertices that land on the same bits in every pose: same rest position, same skin influences,
//!   same morph deltas and the same transform (the same mesh node, or the same skin for
//!   skinned vertices without morph deltas). Triangles that then repeat a corner are dropped.
//!   Vertices no triangle uses are always dropped: several primitives often index different
//!   parts of one shared vertex buffer.
//!
//! # Hostile input
//!
//! Uploads reach this code, so nothing here trusts the file. The document is deserialised with
//! `gltf`'s JSON types but not walked with `gltf`'s convenience wrappers: those unwrap indices
//! the validator never checks (animation channel targets), underflow on accessors with
//! `count: 0`, and hit `unreachable!()` on unexpected component types. Every index, length,
//! stride and component type is checked here instead, and buffers (including GLB chunks and
//! `data:` URIs) are decoded here. A file path may only reference buffers inside its own folder.

use crate::{InputLimits, MeshError, Sequence, SourceVertex};
use glam::{Mat4, Quat, Vec3, Vec4};
use gltf::json;
use json::accessor::{ComponentType, GenericComponentType, IndexComponentType, Type};
use json::validation::Checked;
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Component, Path, PathBuf};

// ------------------------------------------------------------------------------------------------
// Public options and entry points
// ------------------------------------------------------------------------------------------------

/// Which animation of a file to sample.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AnimationSelector {
    /// The animation at this position in the file's `animations` array.
    Index(usize),
    /// The first animation with exactly this name.
    Name(String),
}

/// How to read a glTF file into a [`Sequence`].
#[derive(Clone, Debug, PartialEq)]
pub struct GltfOptions {
    /// The animation to sample; `None` takes the first. A file without animations gives one
    /// frame, the rest pose, unless an animation is asked for, which is then an error.
    pub animation: Option<AnimationSelector>,
    /// Frames per second at which the animation is sampled (default 30).
    pub frame_rate: f32,
    /// Merge vertices that coincide in every pose so that the surface is connected (default on;
    /// see [`RiggedMesh::weld`]).
    pub weld: bool,
    /// What the file may expand to: vertices and triangles are checked as each primitive is
    /// read, frames and frames times vertices before the animation is sampled.
    pub limits: InputLimits,
}

impl Default for GltfOptions {
    fn default() -> Self {
        GltfOptions { animation: None, frame_rate: 30.0, weld: true, limits: InputLimits::default() }
    }
}

/// An animation as listed by [`list_animations`].
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationInfo {
    /// Position in the file's `animations` array.
    pub index: usize,
    /// The animation's name, if it has one.
    pub name: Option<String>,
    /// Largest keyframe time over its channels, in seconds.
    pub duration: f32,
}

/// Reads a `.glb` or `.gltf` file and samples the chosen animation.
///
/// External buffers of a `.gltf` are read from the file's folder (never from outside it).
pub fn load_gltf(path: &Path, opts: &GltfOptions) -> Result<Sequence, MeshError> {
    let file = GltfFile::open(path)?;
    file_to_sequence(&file, opts).map_err(|e| at_path(path, e))
}

/// Reads a GLB, or a `.gltf` whose buffers are embedded as `data:` URIs, from memory (uploads).
/// A `.gltf` that references external files can only be read from a path.
pub fn load_gltf_bytes(bytes: &[u8], opts: &GltfOptions) -> Result<Sequence, MeshError> {
    file_to_sequence(&GltfFile::parse(bytes, None)?, opts)
}

/// Every animation of a file, in file order, with its duration.
pub fn list_animations(path: &Path) -> Result<Vec<AnimationInfo>, MeshError> {
    let file = GltfFile::open(path)?;
    animation_infos(&file).map_err(|e| at_path(path, e))
}

/// [`list_animations`] for a file in memory.
pub fn list_animations_bytes(bytes: &[u8]) -> Result<Vec<AnimationInfo>, MeshError> {
    animation_infos(&GltfFile::parse(bytes, None)?)
}

fn animation_infos(file: &GltfFile) -> Result<Vec<AnimationInfo>, MeshError> {
    let targets = morph_target_counts(&file.root);
    Ok(read_animations(file, &targets)?.into_iter().map(|a| AnimationInfo { index: a.index, name: a.name, duration: a.duration }).collect())
}

fn file_to_sequence(file: &GltfFile, opts: &GltfOptions) -> Result<Sequence, MeshError> {
    let mut rig = RiggedMesh::from_file(file, &opts.limits)?;
    if opts.weld {
        rig.weld();
    }
    let animation = match &opts.animation {
        Some(selector) => Some(rig.find_animation(selector)?),
        None => (!rig.animations.is_empty()).then_some(0),
    };
    rig.to_sequence_with(animation, opts.frame_rate, &opts.limits)
}

/// Names the file in messages about its content (I/O errors name it already).
fn at_path(path: &Path, e: MeshError) -> MeshError {
    match e {
        MeshError::Gltf(m) => MeshError::Gltf(format!("{}: {m}", path.display())),
        e => e,
    }
}

fn gltf_error(message: impl Into<String>) -> MeshError {
    MeshError::Gltf(message.into())
}

// ------------------------------------------------------------------------------------------------
// The rigged mesh
// ------------------------------------------------------------------------------------------------

/// The transforms of one pose of a [`RiggedMesh`].
#[derive(Clone, Debug, PartialEq)]
pub struct PoseTransforms {
    /// World transform of every node.
    pub world: Vec<Mat4>,
    /// Per skin, its joint matrices (joint world transform times inverse bind matrix).
    pub joints: Vec<Vec<Mat4>>,
    /// Morph weights of every instance.
    pub morph: Vec<Vec<f32>>,
}

/// Everything needed to pose the merged mesh at any time of any of the file's animations: the
/// authored vertices with their skin and morph data, the node hierarchy, the skins and the
/// animations. [`RiggedMesh::to_sequence`] samples it; a writer that keeps skins and morphs can
/// read it directly.
///
/// Vertex arrays (`positions`, `joints`, `weights`, `source`) are parallel. The vertices of each
/// [`MeshInstance`] are the contiguous range [`MeshInstance::vertices`].
#[derive(Clone, Debug, Default)]
pub struct RiggedMesh {
    /// Rest positions before morphing: in the mesh's own space, which for a skinned mesh is the
    /// bind space its inverse bind matrices expect.
    pub positions: Vec<Vec3>,
    /// Counter-clockwise triangles over all instances.
    pub triangles: Vec<[u32; 3]>,
    /// Where each vertex came from: primitive number (see [`RiggedMesh::primitives`]) and
    /// vertex index inside that primitive.
    pub source: Vec<SourceVertex>,
    /// Up to four joints per vertex, as indices into its skin's [`Skin::joints`]. Zero for
    /// vertices of unskinned instances and for unused slots (whose weight is zero).
    pub joints: Vec<[u16; 4]>,
    /// Skin weights matching `joints`, normalised to sum to 1; all zero when unskinned.
    pub weights: Vec<[f32; 4]>,
    /// One entry per mesh node of the scene, in visiting order.
    pub instances: Vec<MeshInstance>,
    /// What each primitive number of [`SourceVertex::primitive`] refers to.
    pub primitives: Vec<PrimitiveRef>,
    /// Rest transform of every node of the file (indexed like the file's `nodes`).
    pub nodes: Vec<NodeTransform>,
    /// Parent of every node, `None` for roots.
    pub parents: Vec<Option<usize>>,
    /// Every skin of the file (indexed like the file's `skins`).
    pub skins: Vec<Skin>,
    /// Every animation of the file, in file order.
    pub animations: Vec<Animation>,
}

/// A mesh placed in the scene by one node.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshInstance {
    /// The node that places the mesh (its weights are the morph weights; its world transform
    /// poses the mesh when there is no skin).
    pub node: usize,
    /// The file's mesh index.
    pub mesh: usize,
    /// The skin that poses the mesh, as an index into [`RiggedMesh::skins`].
    pub skin: Option<usize>,
    /// This instance's vertices in the merged arrays.
    pub vertices: Range<usize>,
    /// `morph_targets[k][i]` is the `POSITION` delta of target `k` for vertex
    /// `vertices.start + i`.
    pub morph_targets: Vec<Vec<Vec3>>,
    /// Morph weights when no animation drives them: the node's `weights`, else the mesh's,
    /// else zeros (one per target).
    pub default_weights: Vec<f32>,
}

/// Which node, mesh and primitive of the file a primitive number stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrimitiveRef {
    pub node: usize,
    pub mesh: usize,
    /// Index into the mesh's `primitives`.
    pub primitive: usize,
}

/// A node's rest transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeTransform {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
    /// Set when the node was given as a matrix. It is used as is unless an animation targets
    /// the node (which glTF forbids, §5.25), in which case its decomposition above is animated.
    pub matrix: Option<Mat4>,
}

impl Default for NodeTransform {
    fn default() -> Self {
        NodeTransform { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: Vec3::ONE, matrix: None }
    }
}

/// A skin: joint nodes and their inverse bind matrices (identity when the file has none).
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    pub joints: Vec<usize>,
    pub inverse_bind_matrices: Vec<Mat4>,
}

/// One animation of the file.
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    /// Position in the file's `animations` array.
    pub index: usize,
    pub name: Option<String>,
    /// Largest keyframe time over the channels, in seconds (0 without keys).
    pub duration: f32,
    pub channels: Vec<Channel>,
}

impl Animation {
    /// The name, or the index for an unnamed animation: what frame names start with.
    pub fn label(&self) -> String {
        self.name.clone().unwrap_or_else(|| self.index.to_string())
    }
}

/// What an animation channel drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnimatedProperty {
    Translation,
    Rotation,
    Scale,
    /// The morph weights of the mesh the node instantiates.
    MorphWeights,
}

/// Keyframe interpolation (glTF 2.0 §3.11, Appendix C).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// One animation channel: keyframes of one property of one node.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub node: usize,
    pub property: AnimatedProperty,
    pub interpolation: Interpolation,
    /// Keyframe times in seconds, non-decreasing.
    pub times: Vec<f32>,
    /// `width` floats per keyframe, or for cubic splines three groups of `width` per keyframe:
    /// in-tangent, value, out-tangent.
    pub values: Vec<f32>,
    /// Floats per value: 3 for translation and scale, 4 for rotation (x, y, z, w), the number of
    /// morph targets for weights.
    pub width: usize,
}

/// What the rest of a file may still add while it is read: vertex records (a vertex plus one per
/// morph target) up to [`MAX_ELEMENTS`], and vertices and triangles up to the input limits.
struct Budget<'a> {
    records: usize,
    limits: &'a InputLimits,
}

/// Most positions a sequence may hold (frames times vertices), and most frames: a hostile
/// duration or frame rate must not exhaust memory.
const MAX_POSITIONS: usize = 1 << 28;
const MAX_FRAMES: usize = 1 << 20;
/// Most components one accessor may decode to, and most vertex records (a vertex plus one per
/// morph target) a file may expand to: a few kilobytes of JSON can otherwise ask for terabytes
/// (a huge `count` without a bufferView, a million empty morph targets, a mesh instanced by a
/// million nodes).
const MAX_ELEMENTS: usize = 1 << 27;

impl RiggedMesh {
    /// Reads a `.glb` or `.gltf` file (external buffers from its folder).
    pub fn from_path(path: &Path) -> Result<Self, MeshError> {
        Self::from_path_with(path, &InputLimits::default())
    }

    /// [`RiggedMesh::from_path`] under the given limits on vertices and triangles.
    pub fn from_path_with(path: &Path, limits: &InputLimits) -> Result<Self, MeshError> {
        let file = GltfFile::open(path)?;
        Self::from_file(&file, limits).map_err(|e| at_path(path, e))
    }

    /// Reads a GLB or a self-contained `.gltf` from memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, MeshError> {
        Self::from_bytes_with(bytes, &InputLimits::default())
    }

    /// [`RiggedMesh::from_bytes`] under the given limits on vertices and triangles.
    pub fn from_bytes_with(bytes: &[u8], limits: &InputLimits) -> Result<Self, MeshError> {
        Self::from_file(&GltfFile::parse(bytes, None)?, limits)
    }

    fn from_file(file: &GltfFile, limits: &InputLimits) -> Result<Self, MeshError> {
        let root = &file.root;
        let mut rig = RiggedMesh { nodes: read_nodes(root)?, parents: node_parents(root)?, ..Default::default() };
        for (s, skin) in root.skins.iter().enumerate() {
            rig.skins.push(read_skin(file, s, skin)?);
        }
        let mut budget = Budget { records: MAX_ELEMENTS, limits };
        for node in scene_mesh_nodes(root, &rig.parents) {
            rig.add_instance(file, node, &mut budget)?;
        }
        let targets = morph_target_counts(root);
        rig.animations = read_animations(file, &targets)?;
        rig.drop_unused_vertices();
        rig.check_vertices()?;
        if rig.triangles.is_empty() {
            return Err(MeshError::Empty { what: "the glTF scene has no triangles".into() });
        }
        Ok(rig)
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Index of the animation a selector names; the error lists the file's animations.
    pub fn find_animation(&self, selector: &AnimationSelector) -> Result<usize, MeshError> {
        let found = match selector {
            AnimationSelector::Index(i) => (*i < self.animations.len()).then_some(*i),
            AnimationSelector::Name(name) => self.animations.iter().position(|a| a.name.as_deref() == Some(name.as_str())),
        };
        found.ok_or_else(|| MeshError::NoSuchAnimation {
            wanted: match selector {
                AnimationSelector::Index(i) => format!("#{i}"),
                AnimationSelector::Name(n) => format!("{n:?}"),
            },
            available: self.animations.iter().map(Animation::label).collect(),
        })
    }

    /// Samples `animation` (an index into [`RiggedMesh::animations`]; `None` for the rest pose)
    /// at `frame_rate` into a validated sequence. See the module documentation for the times.
    pub fn to_sequence(&self, animation: Option<usize>, frame_rate: f32) -> Result<Sequence, MeshError> {
        self.to_sequence_with(animation, frame_rate, &InputLimits::default())
    }

    /// [`RiggedMesh::to_sequence`] under the given limits on frames and frames times vertices,
    /// checked before any frame is sampled.
    pub fn to_sequence_with(&self, animation: Option<usize>, frame_rate: f32, limits: &InputLimits) -> Result<Sequence, MeshError> {
        if !(frame_rate.is_finite() && frame_rate > 0.0) {
            return Err(MeshError::Invalid(format!("frame rate {frame_rate} is not a positive number")));
        }
        let anim = match animation {
            Some(i) => Some(self.find_animation(&AnimationSelector::Index(i)).map(|i| &self.animations[i])?),
            None => None,
        };
        let duration = anim.map_or(0.0, |a| a.duration.max(0.0));
        // f32 on purpose: a clip of exactly N frames whose duration was rounded to f32 still
        // gets its last frame, and callers computing `floor(duration * rate) + 1` in f32 agree.
        let last = (duration * frame_rate).floor();
        // Each frame costs the vertices, the channels and the node hierarchy.
        let channels = anim.map_or(0, |a| a.channels.len()) + self.nodes.len();
        let n = self.vertex_count();
        let count = if last.is_finite() && last < MAX_FRAMES as f32 { last as usize + 1 } else { usize::MAX };
        if count > MAX_FRAMES || count.saturating_mul(n + channels) > MAX_POSITIONS {
            return Err(MeshError::TooLarge { what: format!("{duration} s at {frame_rate} frames per second for {n} vertices") });
        }
        let label = anim.map_or_else(|| "rest".to_string(), Animation::label);
        limits.check_positions(count, n, &format!("animation {label}, {duration} s at {frame_rate} frames per second"))?;
        let mut seq = Sequence { triangles: self.triangles.clone(), frame_rate, source: self.source.clone(), ..Default::default() };
        for i in 0..count {
            let t = i as f32 / frame_rate;
            seq.frames.push(self.pose(anim, t));
            seq.frame_names.push(format!("{label}@{t:.3}s"));
        }
        seq.morph_displacement = self.morph_displacement();
        seq.validate()?;
        Ok(seq)
    }

    /// Per vertex, the summed length of its morph deltas over all targets (the distance to the
    /// neutral shape, as Berner and Rieger weigh vertices); empty when no instance has targets.
    pub fn morph_displacement(&self) -> Vec<f32> {
        if self.instances.iter().all(|i| i.morph_targets.is_empty()) {
            return Vec::new();
        }
        let mut out = vec![0.0f32; self.vertex_count()];
        for inst in &self.instances {
            for target in &inst.morph_targets {
                for (slot, d) in out.get_mut(inst.vertices.clone()).unwrap_or_default().iter_mut().zip(target) {
                    *slot += d.length();
                }
            }
        }
        out
    }

    /// The transforms of `animation` at time `t` (seconds), or of the rest pose for `None`:
    /// channels naming nodes this mesh does not have are ignored, and a node given as a matrix
    /// keeps it unless a channel animates it.
    pub fn pose_transforms(&self, animation: Option<&Animation>, t: f32) -> PoseTransforms {
        let mut local: Vec<NodeTransform> = self.nodes.clone();
        let mut animated = vec![false; local.len()];
        let mut morph: Vec<Vec<f32>> = self.instances.iter().map(|i| i.default_weights.clone()).collect();
        for ch in animation.map_or(&[][..], |a| a.channels.as_slice()) {
            let v = ch.sample(t);
            if ch.property == AnimatedProperty::MorphWeights {
                for (inst, w) in self.instances.iter().zip(morph.iter_mut()) {
                    if inst.node == ch.node {
                        w.clone_from(&v);
                    }
                }
                continue;
            }
            let Some(node) = local.get_mut(ch.node) else { continue };
            match (ch.property, v.as_slice()) {
                (AnimatedProperty::Translation, &[x, y, z]) => node.translation = Vec3::new(x, y, z),
                (AnimatedProperty::Scale, &[x, y, z]) => node.scale = Vec3::new(x, y, z),
                (AnimatedProperty::Rotation, &[x, y, z, w]) => node.rotation = unit_quat(Quat::from_xyzw(x, y, z, w)),
                _ => continue,
            }
            if let Some(flag) = animated.get_mut(ch.node) {
                *flag = true;
            }
        }
        let local_matrices: Vec<Mat4> = local
            .iter()
            .zip(&animated)
            .map(|(n, &moved)| match n.matrix {
                Some(m) if !moved => m,
                _ => Mat4::from_scale_rotation_translation(n.scale, n.rotation, n.translation),
            })
            .collect();
        let world = world_transforms(&self.parents, &local_matrices);
        let joints = self
            .skins
            .iter()
            .map(|s| {
                s.joints
                    .iter()
                    .zip(&s.inverse_bind_matrices)
                    .map(|(&j, ibm)| world.get(j).copied().unwrap_or(Mat4::IDENTITY) * *ibm)
                    .collect()
            })
            .collect();
        PoseTransforms { world, joints, morph }
    }

    /// Positions of every vertex at time `t` (seconds) of `animation`, or in the rest pose for
    /// `None`. Channels naming nodes this mesh does not have are ignored.
    pub fn pose(&self, animation: Option<&Animation>, t: f32) -> Vec<Vec3> {
        let PoseTransforms { world, joints: joint_matrices, morph: weights } = self.pose_transforms(animation, t);
        let world_of = |n: usize| world.get(n).copied().unwrap_or(Mat4::IDENTITY);
        let mut out = vec![Vec3::ZERO; self.vertex_count()];
        for (inst, morph) in self.instances.iter().zip(&weights) {
            let rigid = world_of(inst.node);
            let skin = inst.skin.and_then(|s| joint_matrices.get(s));
            for (i, v) in inst.vertices.clone().enumerate() {
                let (Some(rest), Some(slot)) = (self.positions.get(v), out.get_mut(v)) else { break };
                let mut p = *rest;
                for (target, &w) in inst.morph_targets.iter().zip(morph) {
                    if w != 0.0 {
                        p += target.get(i).copied().unwrap_or(Vec3::ZERO) * w;
                    }
                }
                *slot = match skin {
                    Some(mats) => {
                        let joints = self.joints.get(v).copied().unwrap_or_default();
                        let weights = self.weights.get(v).copied().unwrap_or_default();
                        let mut blended = Mat4::ZERO;
                        for (&j, &w) in joints.iter().zip(&weights) {
                            if w != 0.0 {
                                blended += mats.get(j as usize).copied().unwrap_or(Mat4::IDENTITY) * w;
                            }
                        }
                        blended.transform_point3(p)
                    }
                    None => rigid.transform_point3(p),
                };
            }
        }
        out
    }

    /// Merges vertices that are equal in every pose and drops the triangles that then repeat a
    /// corner (and vertices nothing uses any more). Two vertices are merged when their rest
    /// positions, skin influences and morph deltas are bitwise equal and they are posed by the
    /// same transform: the same mesh node, or, for skinned vertices without morph deltas, the
    /// same skin (so meshes sharing an armature join at their seams). The first occurrence is
    /// kept and vertices keep their order.
    pub fn weld(&mut self) {
        let mut first_of: HashMap<Vec<u32>, u32> = HashMap::new();
        let mut keep: Vec<usize> = Vec::new();
        let mut remap = vec![u32::MAX; self.vertex_count()];
        let mut key = Vec::new();
        for (inst_index, inst) in self.instances.iter().enumerate() {
            for (i, v) in inst.vertices.clone().enumerate() {
                let (Some(p), Some(slot)) = (self.positions.get(v), remap.get_mut(v)) else { break };
                let deltas = inst.morph_targets.iter().map(|t| t.get(i).copied().unwrap_or(Vec3::ZERO));
                let rigid_by_skin = inst.skin.is_some() && deltas.clone().all(|d| d == Vec3::ZERO);
                key.clear();
                match (rigid_by_skin, inst.skin) {
                    (true, Some(s)) => key.extend([0, s as u32]),
                    _ => key.extend([1, inst_index as u32]),
                }
                key.extend(p.to_array().map(f32::to_bits));
                let joints = self.joints.get(v).copied().unwrap_or_default();
                let weights = self.weights.get(v).copied().unwrap_or_default();
                for (j, w) in joints.iter().zip(weights) {
                    key.extend([u32::from(*j), w.to_bits()]);
                }
                if !rigid_by_skin {
                    key.extend(deltas.flat_map(|d| d.to_array().map(f32::to_bits)));
                }
                let next = keep.len() as u32;
                *slot = *first_of.entry(key.clone()).or_insert_with(|| {
                    keep.push(v);
                    next
                });
            }
        }
        self.reindex(&keep, &remap);
        self.drop_unused_vertices();
    }

    /// Drops vertices no triangle uses.
    fn drop_unused_vertices(&mut self) {
        let mut used = vec![false; self.vertex_count()];
        for &i in self.triangles.iter().flatten() {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
        let keep: Vec<usize> = (0..used.len()).filter(|&v| used[v]).collect();
        if keep.len() == used.len() {
            return;
        }
        let mut remap = vec![u32::MAX; used.len()];
        for (new, &old) in keep.iter().enumerate() {
            remap[old] = new as u32;
        }
        self.reindex(&keep, &remap);
    }

    /// Rebuilds the vertex arrays from `keep` (old index of each new vertex, increasing) and
    /// `remap` (new index of each old vertex), and drops triangles that lose or repeat a corner.
    fn reindex(&mut self, keep: &[usize], remap: &[u32]) {
        fn gather<T: Copy + Default>(old: &[T], keep: &[usize]) -> Vec<T> {
            keep.iter().map(|&o| old.get(o).copied().unwrap_or_default()).collect()
        }
        self.positions = gather(&self.positions, keep);
        self.joints = gather(&self.joints, keep);
        self.weights = gather(&self.weights, keep);
        self.source = keep.iter().map(|&o| self.source.get(o).copied().unwrap_or(SourceVertex { primitive: 0, index: 0 })).collect();
        for inst in &mut self.instances {
            // `keep` is increasing and instances occupy increasing ranges, so each instance's
            // surviving vertices are again one contiguous range.
            let old = inst.vertices.clone();
            let start = keep.partition_point(|&o| o < old.start);
            let end = keep.partition_point(|&o| o < old.end);
            let kept = keep.get(start..end).unwrap_or_default();
            for target in &mut inst.morph_targets {
                *target = kept.iter().map(|&o| target.get(o - old.start).copied().unwrap_or(Vec3::ZERO)).collect();
            }
            inst.vertices = start..end;
        }
        let map = |i: u32| remap.get(i as usize).copied().filter(|&n| n != u32::MAX);
        self.triangles = self
            .triangles
            .iter()
            .filter_map(|t| Some([map(t[0])?, map(t[1])?, map(t[2])?]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
    }

    /// Rejects what would poison every frame, naming the source vertex: non-finite rest
    /// positions or morph deltas, and skinned vertices without any weight.
    fn check_vertices(&self) -> Result<(), MeshError> {
        let name = |v: usize| match self.source.get(v) {
            Some(s) => format!("primitive {} vertex {}", s.primitive, s.index),
            None => format!("vertex {v}"),
        };
        for inst in &self.instances {
            for (i, v) in inst.vertices.clone().enumerate() {
                if !self.positions.get(v).is_some_and(|p| p.is_finite()) {
                    return Err(gltf_error(format!("{}: POSITION is not a finite number", name(v))));
                }
                if inst.morph_targets.iter().any(|t| !t.get(i).is_some_and(|d| d.is_finite())) {
                    return Err(gltf_error(format!("{}: a morph target delta is not a finite number", name(v))));
                }
                if inst.skin.is_some() && self.weights.get(v).is_none_or(|w| w.iter().all(|&x| x == 0.0)) {
                    return Err(gltf_error(format!("{}: skinned, but all its WEIGHTS are zero", name(v))));
                }
            }
        }
        Ok(())
    }

    /// Appends the primitives of the mesh on `node_index` as a new instance.
    fn add_instance(&mut self, file: &GltfFile, node_index: usize, budget: &mut Budget) -> Result<(), MeshError> {
        let root = &file.root;
        let Some(node) = root.nodes.get(node_index) else { return Ok(()) };
        let Some(mesh_index) = node.mesh.map(|m| m.value()) else { return Ok(()) };
        let mesh = root
            .meshes
            .get(mesh_index)
            .ok_or_else(|| gltf_error(format!("node {node_index} uses mesh {mesh_index}, which does not exist")))?;
        let skin = match node.skin.map(|s| s.value()) {
            Some(s) if s >= self.skins.len() => {
                return Err(gltf_error(format!("node {node_index} uses skin {s}, which does not exist")));
            }
            s => s,
        };
        let target_count = mesh.primitives.iter().map(|p| p.targets.as_ref().map_or(0, Vec::len)).max().unwrap_or(0);
        let mut default_weights: Vec<f32> = node.weights.clone().or_else(|| mesh.weights.clone()).unwrap_or_default();
        default_weights.resize(target_count, 0.0);
        if default_weights.iter().any(|w| !w.is_finite()) {
            return Err(gltf_error(format!("node {node_index}: morph weights are not finite numbers")));
        }
        let start = self.positions.len();
        let mut inst = MeshInstance {
            node: node_index,
            mesh: mesh_index,
            skin,
            vertices: start..start,
            morph_targets: vec![Vec::new(); target_count],
            default_weights,
        };
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let number = self.primitives.len();
            let what = format!("mesh {mesh_index} primitive {p}");
            self.add_primitive(file, prim, &mut inst, number as u32, &what, budget)?;
            self.primitives.push(PrimitiveRef { node: node_index, mesh: mesh_index, primitive: p });
        }
        inst.vertices = start..self.positions.len();
        self.instances.push(inst);
        Ok(())
    }

    fn add_primitive(
        &mut self,
        file: &GltfFile,
        prim: &json::mesh::Primitive,
        inst: &mut MeshInstance,
        number: u32,
        what: &str,
        budget: &mut Budget,
    ) -> Result<(), MeshError> {
        let limits = budget.limits;
        use json::mesh::{Mode, Semantic};
        let attribute = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|a| a.value());
        let mode = match prim.mode {
            Checked::Valid(m) => m,
            Checked::Invalid => return Err(gltf_error(format!("{what}: invalid primitive mode"))),
        };
        // Only triangles make a surface (§3.7.2.1); say which mode it was.
        let mode_name = match mode {
            Mode::Points => Some("POINTS"),
            Mode::Lines => Some("LINES"),
            Mode::LineLoop => Some("LINE_LOOP"),
            Mode::LineStrip => Some("LINE_STRIP"),
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => None,
        };
        if let Some(name) = mode_name {
            return Err(MeshError::Unsupported(format!("{what} has mode {name}; only triangle modes make a mesh")));
        }
        let positions_at = attribute(Semantic::Positions).ok_or_else(|| gltf_error(format!("{what} has no POSITION")))?;
        // Checked on the accessor's declared count, before its elements are read.
        if self.positions.len().saturating_add(file.accessor_count(positions_at)) > limits.max_vertices {
            return Err(limits.too_many_vertices(1, limits.max_vertices, &format!("{what} POSITION")));
        }
        let positions = to_vec3(&file.read_floats(positions_at, 3, ANY_NUMBER, &format!("{what} POSITION"))?);
        let n = positions.len();
        let records = n.saturating_mul(1 + inst.morph_targets.len());
        budget.records = budget.records.checked_sub(records).ok_or_else(|| MeshError::TooLarge {
            what: format!("{what} brings the scene past {MAX_ELEMENTS} vertex records (vertices times morph targets)"),
        })?;
        let indices: Vec<u32> = match prim.indices.map(|i| i.value()) {
            Some(at) => file.read_uints(at, 1, &[ComponentType::U8, ComponentType::U16, ComponentType::U32], &format!("{what} indices"))?,
            None => (0..n as u32).collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(gltf_error(format!("{what}: index {bad} is out of range for its {n} vertices")));
        }
        let new_triangles = match mode {
            Mode::TriangleStrip | Mode::TriangleFan => indices.len().saturating_sub(2),
            _ => indices.len() / 3,
        };
        if self.triangles.len().saturating_add(new_triangles) > limits.max_triangles {
            return Err(limits.too_many_triangles(&format!("{what} indices")));
        }
        // Topology per §3.7.2.1: strips alternate winding, fans pivot on the first vertex.
        let triangles: Vec<[u32; 3]> = match mode {
            Mode::TriangleStrip => {
                indices.windows(3).enumerate().map(|(i, w)| if i % 2 == 0 { [w[0], w[1], w[2]] } else { [w[0], w[2], w[1]] }).collect()
            }
            Mode::TriangleFan => match indices.split_first() {
                Some((&first, rest)) => rest.windows(2).map(|w| [w[0], w[1], first]).collect(),
                None => Vec::new(),
            },
            _ => {
                if !indices.len().is_multiple_of(3) {
                    return Err(gltf_error(format!("{what}: {} indices is not a whole number of triangles", indices.len())));
                }
                indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            }
        };

        let (joints, weights) = match inst.skin.and_then(|s| self.skins.get(s)) {
            Some(skin) => read_influences(file, &attribute, n, skin.joints.len(), what)?,
            None => (vec![[0; 4]; n], vec![[0.0; 4]; n]),
        };

        let targets = prim.targets.as_deref().unwrap_or_default();
        for (k, slot) in inst.morph_targets.iter_mut().enumerate() {
            let deltas = match targets.get(k).and_then(|t| t.positions).map(|a| a.value()) {
                Some(at) => to_vec3(&file.read_floats(at, 3, ANY_NUMBER, &format!("{what} morph target {k} POSITION"))?),
                // A primitive without this target (or without its POSITION) does not move.
                None => vec![Vec3::ZERO; n],
            };
            if deltas.len() != n {
                return Err(gltf_error(format!("{what}: morph target {k} has {} positions for {n} vertices", deltas.len())));
            }
            slot.extend(deltas);
        }

        let base = self.positions.len() as u32;
        self.positions.extend(positions);
        self.joints.extend(joints);
        self.weights.extend(weights);
        self.source.extend((0..n as u32).map(|index| SourceVertex { primitive: number, index }));
        self.triangles.extend(triangles.into_iter().filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]).map(|t| t.map(|i| i + base)));
        Ok(())
    }
}

/// Per-vertex joints and weights, as stored in [`RiggedMesh::joints`] and [`RiggedMesh::weights`].
type Influences = (Vec<[u16; 4]>, Vec<[f32; 4]>);

/// Reads every `JOINTS_n`/`WEIGHTS_n` pair of a skinned primitive and reduces each vertex to its
/// four strongest influences, normalised to sum to 1 (§3.7.3.3 asks for normalised weights;
/// exporters drift, so they are normalised rather than rejected).
fn read_influences(
    file: &GltfFile,
    attribute: &dyn Fn(json::mesh::Semantic) -> Option<usize>,
    n: usize,
    joint_count: usize,
    what: &str,
) -> Result<Influences, MeshError> {
    use json::mesh::Semantic;
    let mut sets: Vec<(Vec<u32>, Vec<f32>)> = Vec::new();
    for set in 0u32.. {
        let (Some(j), Some(w)) = (attribute(Semantic::Joints(set)), attribute(Semantic::Weights(set))) else { break };
        let joints = file.read_uints(j, 4, &[ComponentType::U8, ComponentType::U16], &format!("{what} JOINTS_{set}"))?;
        let weights =
            file.read_floats(w, 4, &[ComponentType::F32, ComponentType::U8, ComponentType::U16], &format!("{what} WEIGHTS_{set}"))?;
        if joints.len() != 4 * n || weights.len() != 4 * n {
            return Err(gltf_error(format!("{what}: JOINTS_{set}/WEIGHTS_{set} do not have one entry per vertex")));
        }
        sets.push((joints, weights));
    }
    if sets.is_empty() {
        return Err(gltf_error(format!("{what} is on a skinned node but has no JOINTS_0/WEIGHTS_0")));
    }
    let mut joints_out = Vec::with_capacity(n);
    let mut weights_out = Vec::with_capacity(n);
    let mut influences: Vec<(u32, f32)> = Vec::new();
    for v in 0..n {
        influences.clear();
        for (joints, weights) in &sets {
            let range = 4 * v..4 * v + 4;
            let (Some(js), Some(ws)) = (joints.get(range.clone()), weights.get(range)) else { continue };
            for (&j, &w) in js.iter().zip(ws) {
                if !(w.is_finite() && w >= 0.0) {
                    return Err(gltf_error(format!("{what}: vertex {v} has skin weight {w}")));
                }
                if w == 0.0 {
                    continue;
                }
                if j as usize >= joint_count {
                    return Err(gltf_error(format!("{what}: vertex {v} uses joint {j}, but the skin has {joint_count}")));
                }
                match influences.iter_mut().find(|(k, _)| *k == j) {
                    Some(existing) => existing.1 += w,
                    None => influences.push((j, w)),
                }
            }
        }
        if influences.len() > 4 {
            // Stable sort: equal weights keep their file order.
            influences.sort_by(|a, b| b.1.total_cmp(&a.1));
            influences.truncate(4);
        }
        let sum: f32 = influences.iter().map(|i| i.1).sum();
        let mut joints = [0u16; 4];
        let mut weights = [0f32; 4];
        for (slot, &(j, w)) in influences.iter().enumerate().take(4) {
            joints[slot] = j as u16;
            weights[slot] = if sum > 0.0 { w / sum } else { 0.0 };
        }
        joints_out.push(joints);
        weights_out.push(weights);
    }
    Ok((joints_out, weights_out))
}

fn to_vec3(flat: &[f32]) -> Vec<Vec3> {
    flat.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
}

/// A rotation as a unit quaternion; the identity when it has no direction (a zero or non-finite
/// quaternion cannot be normalised and would turn every vertex it touches into NaN).
fn unit_quat(q: Quat) -> Quat {
    let len = q.length();
    if len.is_finite() && len > 1e-12 { q / len } else { Quat::IDENTITY }
}

/// World transform of every node: parents before children, from the roots down.
pub fn world_transforms(parents: &[Option<usize>], local: &[Mat4]) -> Vec<Mat4> {
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); parents.len()];
    let mut stack: Vec<usize> = Vec::new();
    for (c, p) in parents.iter().enumerate() {
        match p.and_then(|p| children.get_mut(p)) {
            Some(list) => list.push(c),
            None => stack.push(c),
        }
    }
    let mut world = vec![Mat4::IDENTITY; parents.len()];
    while let Some(n) = stack.pop() {
        let parent = parents.get(n).copied().flatten().and_then(|p| world.get(p)).copied().unwrap_or(Mat4::IDENTITY);
        let own = local.get(n).copied().unwrap_or(Mat4::IDENTITY);
        if let Some(w) = world.get_mut(n) {
            *w = parent * own;
        }
        if let Some(list) = children.get(n) {
            stack.extend(list.iter().copied());
        }
    }
    world
}

// ------------------------------------------------------------------------------------------------
// Scene structure
// ------------------------------------------------------------------------------------------------

fn read_nodes(root: &json::Root) -> Result<Vec<NodeTransform>, MeshError> {
    let mut out = Vec::with_capacity(root.nodes.len());
    for (i, node) in root.nodes.iter().enumerate() {
        let transform = match node.matrix {
            // Column-major, as glTF stores it (§5.25).
            Some(m) => {
                let matrix = Mat4::from_cols_array(&m);
                let (scale, rotation, translation) = matrix.to_scale_rotation_translation();
                NodeTransform { translation, rotation: unit_quat(rotation), scale, matrix: Some(matrix) }
            }
            None => NodeTransform {
                translation: node.translation.map_or(Vec3::ZERO, Vec3::from_array),
                rotation: node.rotation.map_or(Quat::IDENTITY, |q| unit_quat(Quat::from_array(q.0))),
                scale: node.scale.map_or(Vec3::ONE, Vec3::from_array),
                matrix: None,
            },
        };
        let finite = transform.translation.is_finite()
            && transform.scale.is_finite()
            && node.rotation.is_none_or(|q| q.0.iter().all(|c| c.is_finite()))
            && transform.matrix.is_none_or(|m| m.is_finite());
        if !finite {
            return Err(gltf_error(format!("node {i}: its transform is not made of finite numbers")));
        }
        out.push(transform);
    }
    Ok(out)
}

/// Parents from the `children` lists. glTF requires the nodes to form disjoint strict trees
/// (§3.5.3); a node with two parents or a cycle is rejected rather than guessed at.
fn node_parents(root: &json::Root) -> Result<Vec<Option<usize>>, MeshError> {
    let n = root.nodes.len();
    let mut parents: Vec<Option<usize>> = vec![None; n];
    for (p, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten().map(|c| c.value()) {
            let slot = parents.get_mut(c).ok_or_else(|| gltf_error(format!("node {p} has child {c}, which does not exist")))?;
            if let Some(other) = *slot {
                return Err(gltf_error(format!("node {c} is a child of both node {other} and node {p}")));
            }
            if c == p {
                return Err(gltf_error(format!("node {p} is its own child")));
            }
            *slot = Some(p);
        }
    }
    // Every node must reach a root; one that meets its own path again sits on a cycle. Each
    // node is walked once (a deep chain must not cost n squared).
    const UNKNOWN: u8 = 0;
    const ON_PATH: u8 = 1;
    const REACHES_ROOT: u8 = 2;
    let mut state = vec![UNKNOWN; n];
    let mut path = Vec::new();
    for start in 0..n {
        let mut at = start;
        loop {
            match state.get(at).copied() {
                Some(UNKNOWN) => {
                    state[at] = ON_PATH;
                    path.push(at);
                    match parents.get(at).copied().flatten() {
                        Some(p) => at = p,
                        None => break,
                    }
                }
                Some(ON_PATH) => return Err(gltf_error(format!("node {at} is on a cycle of children"))),
                _ => break,
            }
        }
        for v in path.drain(..) {
            state[v] = REACHES_ROOT;
        }
    }
    Ok(parents)
}

/// Mesh nodes of the default scene (else the first scene, else all root nodes), depth first in
/// pre-order: the order in which primitives are numbered.
fn scene_mesh_nodes(root: &json::Root, parents: &[Option<usize>]) -> Vec<usize> {
    let scene = root.scene.map(|s| s.value()).and_then(|s| root.scenes.get(s)).or_else(|| root.scenes.first());
    let roots: Vec<usize> = match scene {
        Some(s) => s.nodes.iter().map(|n| n.value()).collect(),
        None => (0..parents.len()).filter(|&n| parents.get(n).copied().flatten().is_none()).collect(),
    };
    let mut visited = vec![false; root.nodes.len()];
    let mut out = Vec::new();
    let mut stack: Vec<usize> = roots.into_iter().rev().collect();
    while let Some(n) = stack.pop() {
        let Some(node) = root.nodes.get(n) else { continue };
        if std::mem::replace(&mut visited[n], true) {
            continue;
        }
        if node.mesh.is_some() {
            out.push(n);
        }
        stack.extend(node.children.iter().flatten().rev().map(|c| c.value()));
    }
    out
}

fn read_skin(file: &GltfFile, index: usize, skin: &json::Skin) -> Result<Skin, MeshError> {
    let joints: Vec<usize> = skin.joints.iter().map(|j| j.value()).collect();
    if let Some(&bad) = joints.iter().find(|&&j| j >= file.root.nodes.len()) {
        return Err(gltf_error(format!("skin {index} has joint node {bad}, which does not exist")));
    }
    if joints.len() > usize::from(u16::MAX) + 1 {
        return Err(MeshError::TooLarge { what: format!("skin {index} has {} joints", joints.len()) });
    }
    let inverse_bind_matrices = match skin.inverse_bind_matrices.map(|a| a.value()) {
        // Absent inverse bind matrices are identities (§5.28).
        None => vec![Mat4::IDENTITY; joints.len()],
        Some(at) => {
            let flat = file.read_floats(at, 16, &[ComponentType::F32], &format!("skin {index} inverseBindMatrices"))?;
            let matrices: Vec<Mat4> =
                flat.chunks_exact(16).filter_map(|c| c.try_into().ok()).map(|a: [f32; 16]| Mat4::from_cols_array(&a)).collect();
            if matrices.len() < joints.len() {
                return Err(gltf_error(format!("skin {index} has {} inverse bind matrices for {} joints", matrices.len(), joints.len())));
            }
            if matrices.iter().any(|m| !m.is_finite()) {
                return Err(gltf_error(format!("skin {index}: an inverse bind matrix is not finite")));
            }
            matrices
        }
    };
    Ok(Skin { joints, inverse_bind_matrices })
}

/// Number of morph targets of the mesh on each node (0 without a mesh): the width of a weights
/// channel that targets the node.
fn morph_target_counts(root: &json::Root) -> Vec<usize> {
    root.nodes
        .iter()
        .map(|n| {
            n.mesh
                .and_then(|m| root.meshes.get(m.value()))
                .map_or(0, |m| m.primitives.iter().map(|p| p.targets.as_ref().map_or(0, Vec::len)).max().unwrap_or(0))
        })
        .collect()
}

// ------------------------------------------------------------------------------------------------
// Animations
// ------------------------------------------------------------------------------------------------

fn read_animations(file: &GltfFile, morph_targets: &[usize]) -> Result<Vec<Animation>, MeshError> {
    use json::animation::{Interpolation as JsonInterpolation, Property};
    let mut out = Vec::new();
    for (index, anim) in file.root.animations.iter().enumerate() {
        let name = anim.name.clone();
        let what = match &name {
            Some(n) => format!("animation {index} ({n:?})"),
            None => format!("animation {index}"),
        };
        let mut channels = Vec::new();
        let mut duration = 0f32;
        for (c, ch) in anim.channels.iter().enumerate() {
            let what = format!("{what} channel {c}");
            let node = ch.target.node.value();
            if node >= morph_targets.len() {
                return Err(gltf_error(format!("{what} targets node {node}, which does not exist")));
            }
            let sampler = anim
                .samplers
                .get(ch.sampler.value())
                .ok_or_else(|| gltf_error(format!("{what} uses sampler {}, which does not exist", ch.sampler.value())))?;
            let (property, width, dims) = match ch.target.path {
                Checked::Valid(Property::Translation) => (AnimatedProperty::Translation, 3, 3),
                Checked::Valid(Property::Rotation) => (AnimatedProperty::Rotation, 4, 4),
                Checked::Valid(Property::Scale) => (AnimatedProperty::Scale, 3, 3),
                Checked::Valid(Property::MorphTargetWeights) => {
                    (AnimatedProperty::MorphWeights, morph_targets.get(node).copied().unwrap_or(0), 1)
                }
                // A path this reader does not know cannot move the mesh as far as it can tell.
                Checked::Invalid => continue,
            };
            if width == 0 {
                // Weights for a node without morph targets drive nothing.
                continue;
            }
            let interpolation = match sampler.interpolation {
                Checked::Valid(JsonInterpolation::Step) => Interpolation::Step,
                Checked::Valid(JsonInterpolation::Linear) => Interpolation::Linear,
                Checked::Valid(JsonInterpolation::CubicSpline) => Interpolation::CubicSpline,
                Checked::Invalid => return Err(gltf_error(format!("{what}: unknown interpolation"))),
            };
            let times = file.read_floats(sampler.input.value(), 1, &[ComponentType::F32], &format!("{what} input"))?;
            if times.is_empty() {
                continue;
            }
            if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
                return Err(gltf_error(format!("{what}: keyframe times are not increasing finite numbers")));
            }
            // Outputs may be normalised integers (§3.11, and KHR_mesh_quantization).
            let values = file.read_floats(sampler.output.value(), dims, ANY_NUMBER, &format!("{what} output"))?;
            let per_key = if interpolation == Interpolation::CubicSpline { 3 * width } else { width };
            if values.len() < times.len() * per_key {
                return Err(gltf_error(format!("{what}: {} output values for {} keyframes of {per_key}", values.len(), times.len())));
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(gltf_error(format!("{what}: an output value is not finite")));
            }
            duration = duration.max(times.last().copied().unwrap_or(0.0));
            channels.push(Channel { node, property, interpolation, times, values, width });
        }
        out.push(Animation { index, name, duration, channels });
    }
    Ok(out)
}

impl Channel {
    /// The channel's value at time `t` (`width` floats), per glTF 2.0 Appendix C: clamped to
    /// the first and last keys, STEP holds the earlier key, LINEAR interpolates (rotations by
    /// slerp on the shorter arc), CUBICSPLINE evaluates the Hermite curve with tangents scaled
    /// by the key interval. Rotations come out normalised.
    pub fn sample(&self, t: f32) -> Vec<f32> {
        let w = self.width;
        let cubic = self.interpolation == Interpolation::CubicSpline;
        // part: 0 in-tangent, 1 value, 2 out-tangent (cubic); only the value otherwise.
        let part = |k: usize, part: usize| -> &[f32] {
            let start = if cubic { (3 * k + part) * w } else { k * w };
            self.values.get(start..start + w).unwrap_or_default()
        };
        let value = |k: usize| part(k, 1);
        let mut out = vec![0.0f32; w];
        let (Some(&first), Some(&last)) = (self.times.first(), self.times.last()) else { return out };
        let n = self.times.len();
        if t <= first || n == 1 {
            fill(&mut out, value(0));
        } else if t >= last {
            fill(&mut out, value(n - 1));
        } else {
            // first < t < last, so 1 <= partition point <= n - 1 (saturating only for NaN).
            let k = self.times.partition_point(|&x| x <= t).saturating_sub(1);
            let (t0, t1) = (self.times.get(k).copied().unwrap_or(first), self.times.get(k + 1).copied().unwrap_or(last));
            let dt = t1 - t0;
            let u = if dt > 0.0 { (t - t0) / dt } else { 1.0 };
            match self.interpolation {
                Interpolation::Step => fill(&mut out, value(k)),
                Interpolation::Linear if self.property == AnimatedProperty::Rotation => {
                    if let (&[ax, ay, az, aw], &[bx, by, bz, bw]) = (value(k), value(k + 1)) {
                        let q = slerp(Quat::from_xyzw(ax, ay, az, aw), Quat::from_xyzw(bx, by, bz, bw), u);
                        fill(&mut out, &q.to_array());
                    }
                }
                Interpolation::Linear => {
                    for ((o, a), b) in out.iter_mut().zip(value(k)).zip(value(k + 1)) {
                        *o = a + (b - a) * u;
                    }
                }
                Interpolation::CubicSpline => {
                    let (u2, u3) = (u * u, u * u * u);
                    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
                    let h10 = u3 - 2.0 * u2 + u;
                    let h01 = -2.0 * u3 + 3.0 * u2;
                    let h11 = u3 - u2;
                    let (p0, m0, p1, m1) = (value(k), part(k, 2), value(k + 1), part(k + 1, 0));
                    for (i, o) in out.iter_mut().enumerate() {
                        let at = |s: &[f32]| s.get(i).copied().unwrap_or(0.0);
                        *o = h00 * at(p0) + h10 * dt * at(m0) + h01 * at(p1) + h11 * dt * at(m1);
                    }
                }
            }
        }
        if let (AnimatedProperty::Rotation, &[x, y, z, w]) = (self.property, out.as_slice()) {
            fill(&mut out, &unit_quat(Quat::from_xyzw(x, y, z, w)).to_array());
        }
        out
    }
}

fn fill(out: &mut [f32], from: &[f32]) {
    out.iter_mut().zip(from).for_each(|(o, v)| *o = *v);
}

/// Spherical interpolation on the shorter arc; nearly equal rotations fall back to normalised
/// linear interpolation, where slerp's division by sin(angle) loses precision.
fn slerp(a: Quat, b: Quat, u: f32) -> Quat {
    let a = Vec4::from(unit_quat(a));
    let mut b = Vec4::from(unit_quat(b));
    let mut d = a.dot(b);
    if d < 0.0 {
        b = -b;
        d = -d;
    }
    let mixed = if d > 0.9995 {
        a + (b - a) * u
    } else {
        let angle = d.min(1.0).acos();
        let s = angle.sin();
        a * (((1.0 - u) * angle).sin() / s) + b * ((u * angle).sin() / s)
    };
    unit_quat(Quat::from_vec4(mixed))
}

// ------------------------------------------------------------------------------------------------
// Files, buffers and accessors
// ------------------------------------------------------------------------------------------------

/// A parsed document and the bytes of every buffer an accessor uses (others stay `None`: a
/// buffer that only holds images is never loaded).
struct GltfFile {
    root: json::Root,
    buffers: Vec<Option<Vec<u8>>>,
}

const ANY_NUMBER: &[ComponentType] =
    &[ComponentType::F32, ComponentType::I8, ComponentType::U8, ComponentType::I16, ComponentType::U16, ComponentType::U32];

/// Extensions that do not change how positions, skins, morphs or animations are stored, and
/// KHR_mesh_quantization, whose integer attributes the accessor reader decodes. Any other
/// required extension (Draco, meshopt, ...) changes the data and is refused by name.
fn extension_is_supported(name: &str) -> bool {
    const SUPPORTED: &[&str] = &[
        "KHR_mesh_quantization",
        "KHR_texture_transform",
        "KHR_texture_basisu",
        "EXT_texture_webp",
        "EXT_texture_avif",
        "KHR_lights_punctual",
    ];
    SUPPORTED.contains(&name) || name.starts_with("KHR_materials_")
}

impl GltfFile {
    /// The element count an accessor declares (0 for an accessor that does not exist: reading
    /// it says so).
    fn accessor_count(&self, index: usize) -> usize {
        self.root.accessors.get(index).map_or(0, |a| usize::try_from(a.count.0).unwrap_or(usize::MAX))
    }

    fn open(path: &Path) -> Result<Self, MeshError> {
        let bytes = std::fs::read(path).map_err(|error| MeshError::Io { path: path.to_path_buf(), error })?;
        let base = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
        Self::parse(&bytes, base).map_err(|e| at_path(path, e))
    }

    /// Parses a GLB or a JSON document; `base` is the folder external buffers are read from
    /// (`None` for bytes in memory, where they cannot be).
    fn parse(bytes: &[u8], base: Option<&Path>) -> Result<Self, MeshError> {
        let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
            split_glb(bytes)?
        } else {
            // A UTF-8 byte order mark is not allowed (§3.2) but harmless; skip it.
            (bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes), None)
        };
        let root: json::Root = serde_json::from_slice(json_bytes).map_err(|e| gltf_error(format!("not a glTF 2.0 document: {e}")))?;
        let major = root.asset.version.split('.').next().unwrap_or_default();
        if major != "2" {
            return Err(MeshError::Unsupported(format!("glTF version {} (only 2.x is read)", root.asset.version)));
        }
        let unsupported: Vec<&str> = root.extensions_required.iter().map(String::as_str).filter(|e| !extension_is_supported(e)).collect();
        if !unsupported.is_empty() {
            return Err(MeshError::Unsupported(format!("required extension {}", unsupported.join(", "))));
        }
        let mut needed = vec![false; root.buffers.len()];
        let mut need_view = |view: usize| {
            if let Some(b) = root.buffer_views.get(view).and_then(|v| needed.get_mut(v.buffer.value())) {
                *b = true;
            }
        };
        for acc in &root.accessors {
            if let Some(v) = acc.buffer_view {
                need_view(v.value());
            }
            if let Some(sparse) = &acc.sparse {
                need_view(sparse.indices.buffer_view.value());
                need_view(sparse.values.buffer_view.value());
            }
        }
        let mut buffers = Vec::with_capacity(root.buffers.len());
        for (i, buffer) in root.buffers.iter().enumerate() {
            if !needed.get(i).copied().unwrap_or(false) {
                buffers.push(None);
                continue;
            }
            let mut data = match buffer.uri.as_deref() {
                // The GLB BIN chunk is the first buffer, the one without a URI (§4.4.3.3).
                None if i == 0 => bin.ok_or_else(|| gltf_error("buffer 0 has no URI and there is no GLB BIN chunk"))?.to_vec(),
                None => return Err(gltf_error(format!("buffer {i} has no URI"))),
                Some(uri) => read_uri(uri, base, i)?,
            };
            let declared = usize::try_from(buffer.byte_length.0).unwrap_or(usize::MAX);
            if data.len() < declared {
                return Err(gltf_error(format!("buffer {i} declares {declared} bytes but has {}", data.len())));
            }
            // Views may only reach the declared bytes, not the GLB padding.
            data.truncate(declared);
            buffers.push(Some(data));
        }
        Ok(GltfFile { root, buffers })
    }

    /// The bytes of a buffer view and its stride (if it declares one).
    fn view(&self, index: usize, what: &str) -> Result<(&[u8], Option<usize>), MeshError> {
        let view = self.root.buffer_views.get(index).ok_or_else(|| gltf_error(format!("{what}: bufferView {index} does not exist")))?;
        let buffer = view.buffer.value();
        let data = self
            .buffers
            .get(buffer)
            .and_then(Option::as_deref)
            .ok_or_else(|| gltf_error(format!("{what}: bufferView {index} uses buffer {buffer}, which does not exist")))?;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(view.byte_length.0);
        let slice = end.and_then(|end| data.get(usize::try_from(start).ok()?..usize::try_from(end).ok()?)).ok_or_else(|| {
            gltf_error(format!(
                "{what}: bufferView {index} (bytes {start}..{}) lies outside buffer {buffer} ({} bytes)",
                start.saturating_add(view.byte_length.0),
                data.len()
            ))
        })?;
        Ok((slice, view.byte_stride.map(|s| s.0)))
    }

    /// Decodes accessor `index` with `dims` components per element (§3.6.2), base view and
    /// sparse substitution (§3.6.2.3) included, calling `convert` on each component's bytes.
    fn decode<T: Copy + Default>(
        &self,
        index: usize,
        dims: usize,
        allowed: &[ComponentType],
        what: &str,
        convert: impl Fn(ComponentType, bool, &[u8]) -> T,
    ) -> Result<Vec<T>, MeshError> {
        let what = format!("{what} (accessor {index})");
        let acc = self.root.accessors.get(index).ok_or_else(|| gltf_error(format!("{what} does not exist")))?;
        let ty = match acc.type_ {
            Checked::Valid(t) => t,
            Checked::Invalid => return Err(gltf_error(format!("{what}: unknown type"))),
        };
        let actual_dims = match ty {
            Type::Scalar => 1,
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            Type::Vec4 | Type::Mat2 => 4,
            Type::Mat3 => 9,
            Type::Mat4 => 16,
        };
        let ct = match acc.component_type {
            Checked::Valid(GenericComponentType(c)) => c,
            Checked::Invalid => return Err(gltf_error(format!("{what}: unknown component type"))),
        };
        if actual_dims != dims || !allowed.contains(&ct) {
            return Err(gltf_error(format!("{what} is {ty:?} of {ct:?}; expected {dims} components of one of {allowed:?}")));
        }
        let size = component_size(ct);
        let element = size * dims;
        let count = usize::try_from(acc.count.0).unwrap_or(usize::MAX);
        let total = count.checked_mul(dims).filter(|&t| t <= MAX_ELEMENTS);
        let Some(total) = total else {
            return Err(MeshError::TooLarge { what: format!("{what}: {count} elements") });
        };
        let mut out = vec![T::default(); total];
        let read_element = |slot: &mut [T], bytes: &[u8], at: usize| -> Option<()> {
            for (c, s) in slot.iter_mut().enumerate() {
                let from = at.checked_add(c * size)?;
                *s = convert(ct, acc.normalized, bytes.get(from..from.checked_add(size)?)?);
            }
            Some(())
        };
        let outside = || gltf_error(format!("{what}: {count} elements run past the end of their bufferView"));
        // Without a bufferView the elements are zeros (before sparse substitution).
        if let Some(view) = acc.buffer_view {
            let (bytes, stride) = self.view(view.value(), &what)?;
            let stride = stride.unwrap_or(element);
            if stride < element {
                return Err(gltf_error(format!("{what}: byteStride {stride} is less than its {element}-byte elements")));
            }
            let offset = usize::try_from(acc.byte_offset.map_or(0, |o| o.0)).map_err(|_| outside())?;
            if count > 0 {
                let end = (count - 1).checked_mul(stride).and_then(|x| x.checked_add(offset)).and_then(|x| x.checked_add(element));
                if end.is_none_or(|end| end > bytes.len()) {
                    return Err(outside());
                }
            }
            for (e, slot) in out.chunks_exact_mut(dims).enumerate() {
                read_element(slot, bytes, offset + e * stride).ok_or_else(outside)?;
            }
        }
        if let Some(sparse) = &acc.sparse {
            let n = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
            if n > count {
                return Err(gltf_error(format!("{what}: {n} sparse values for {count} elements")));
            }
            let index_type = match sparse.indices.component_type {
                Checked::Valid(IndexComponentType(c @ (ComponentType::U8 | ComponentType::U16 | ComponentType::U32))) => c,
                _ => return Err(gltf_error(format!("{what}: sparse indices are not unsigned integers"))),
            };
            let (index_bytes, _) = self.view(sparse.indices.buffer_view.value(), &what)?;
            let (value_bytes, _) = self.view(sparse.values.buffer_view.value(), &what)?;
            let index_offset = usize::try_from(sparse.indices.byte_offset.0).unwrap_or(usize::MAX);
            let value_offset = usize::try_from(sparse.values.byte_offset.0).unwrap_or(usize::MAX);
            let sparse_outside = || gltf_error(format!("{what}: sparse data runs past the end of its bufferView"));
            let index_size = component_size(index_type);
            for s in 0..n {
                let at = s.checked_mul(index_size).and_then(|x| x.checked_add(index_offset)).ok_or_else(sparse_outside)?;
                let target =
                    index_bytes.get(at..at.saturating_add(index_size)).map(|b| component_u32(index_type, b)).ok_or_else(sparse_outside)?
                        as usize;
                let slot = out
                    .get_mut(target.saturating_mul(dims)..target.saturating_mul(dims).saturating_add(dims))
                    .ok_or_else(|| gltf_error(format!("{what}: sparse index {target} is beyond its {count} elements")))?;
                // Sparse values are tightly packed (§3.6.2.3).
                let at = s.checked_mul(element).and_then(|x| x.checked_add(value_offset)).ok_or_else(sparse_outside)?;
                read_element(slot, value_bytes, at).ok_or_else(sparse_outside)?;
            }
        }
        Ok(out)
    }

    /// Components as floats; normalised integers map to [0, 1] or [-1, 1] (§3.11).
    fn read_floats(&self, index: usize, dims: usize, allowed: &[ComponentType], what: &str) -> Result<Vec<f32>, MeshError> {
        self.decode(index, dims, allowed, what, component_f32)
    }

    /// Components as unsigned integers (indices, joints).
    fn read_uints(&self, index: usize, dims: usize, allowed: &[ComponentType], what: &str) -> Result<Vec<u32>, MeshError> {
        self.decode(index, dims, allowed, what, |ct, _, b| component_u32(ct, b))
    }
}

fn component_size(ct: ComponentType) -> usize {
    match ct {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn component_f32(ct: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    match (ct, b) {
        (ComponentType::F32, &[a, b, c, d]) => f32::from_le_bytes([a, b, c, d]),
        (ComponentType::I8, &[a]) => {
            let v = f32::from(a as i8);
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        (ComponentType::U8, &[a]) => {
            let v = f32::from(a);
            if normalized { v / 255.0 } else { v }
        }
        (ComponentType::I16, &[a, b]) => {
            let v = f32::from(i16::from_le_bytes([a, b]));
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
        (ComponentType::U16, &[a, b]) => {
            let v = f32::from(u16::from_le_bytes([a, b]));
            if normalized { v / 65535.0 } else { v }
        }
        (ComponentType::U32, &[a, b, c, d]) => {
            let v = u32::from_le_bytes([a, b, c, d]) as f32;
            if normalized { v / u32::MAX as f32 } else { v }
        }
        _ => 0.0,
    }
}

fn component_u32(ct: ComponentType, b: &[u8]) -> u32 {
    match (ct, b) {
        (ComponentType::U8, &[a]) => u32::from(a),
        (ComponentType::U16, &[a, b]) => u32::from(u16::from_le_bytes([a, b])),
        (ComponentType::U32, &[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

/// Splits a GLB (§4.4) into its JSON chunk and optional BIN chunk. Unknown chunk types are
/// skipped, as the specification asks.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), MeshError> {
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    let word = |at: usize| bytes.get(at..at + 4).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes);
    let version = word(4).ok_or_else(|| gltf_error("GLB header is truncated"))?;
    if version != 2 {
        return Err(MeshError::Unsupported(format!("GLB container version {version}")));
    }
    let length = word(8).ok_or_else(|| gltf_error("GLB header is truncated"))? as usize;
    if length < 12 || length > bytes.len() {
        return Err(gltf_error(format!("GLB header says {length} bytes but there are {}: truncated or corrupt", bytes.len())));
    }
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    while at < length {
        let (Some(chunk_length), Some(kind)) = (word(at), word(at + 4)) else {
            return Err(gltf_error(format!("GLB chunk header at byte {at} is truncated")));
        };
        let start = at + 8;
        let end = start.checked_add(chunk_length as usize).filter(|&e| e <= length);
        let data = end
            .and_then(|end| bytes.get(start..end))
            .ok_or_else(|| gltf_error(format!("GLB chunk at byte {at} runs past the end of the file")))?;
        match kind {
            JSON if json.is_none() && at == 12 => json = Some(data),
            BIN if bin.is_none() && json.is_some() => bin = Some(data),
            _ if at == 12 => return Err(gltf_error("the first GLB chunk is not JSON")),
            _ => {}
        }
        at = start + data.len();
    }
    Ok((json.ok_or_else(|| gltf_error("GLB has no JSON chunk"))?, bin))
}

/// Bytes of a buffer URI: a base64 `data:` URI, or with a base folder a relative path inside it.
fn read_uri(uri: &str, base: Option<&Path>, index: usize) -> Result<Vec<u8>, MeshError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) =
            rest.split_once(";base64,").ok_or_else(|| MeshError::Unsupported(format!("buffer {index}: a data URI that is not base64")))?;
        return decode_base64(payload).ok_or_else(|| gltf_error(format!("buffer {index}: invalid base64 in its data URI")));
    }
    let Some(base) = base else {
        return Err(gltf_error(format!(
            "buffer {index} refers to the external file {uri:?}; a .gltf that references external files can only \
             be read from a path (or convert it to GLB)"
        )));
    };
    // Relative references only (§3.3.1 resolves URIs against the file), and never outside its
    // folder: a file from elsewhere must not make us read arbitrary local files.
    let decoded = percent_decode(uri).ok_or_else(|| gltf_error(format!("buffer {index}: URI {uri:?} is not valid")))?;
    let relative = PathBuf::from(&decoded);
    let inside = !uri.contains(':') && relative.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
    if !inside {
        return Err(MeshError::Unsupported(format!("buffer {index}: URI {uri:?} (only relative paths inside the file's folder are read)")));
    }
    let path = base.join(relative);
    std::fs::read(&path).map_err(|error| MeshError::Io { path, error })
}

fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        if b == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Standard (and URL-safe) base64; stops at padding, skips whitespace.
fn decode_base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut bits: u32 = 0;
    let mut held = 0u32;
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\t' | b'\r' | b'\n' => continue,
            _ => return None,
        };
        bits = (bits << 6) | u32::from(v);
        held += 6;
        if held >= 8 {
            held -= 8;
            out.push((bits >> held) as u8);
            bits &= (1 << held) - 1;
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_strings() {
        assert_eq!(decode_base64("TWFu").as_deref(), Some(&b"Man"[..]));
        assert_eq!(decode_base64("TWE=").as_deref(), Some(&b"Ma"[..]));
        assert_eq!(decode_base64("TQ==").as_deref(), Some(&b"M"[..]));
        assert_eq!(decode_base64("AAECAwQFBgc=").as_deref(), Some(&[0u8, 1, 2, 3, 4, 5, 6, 7][..]));
        assert_eq!(decode_base64("TW*u"), None);
    }

    #[test]
    fn percent_decoding_rejects_broken_escapes() {
        assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
        assert_eq!(percent_decode("%ff%fe"), None);
        assert_eq!(percent_decode("%4"), None);
        assert_eq!(percent_decode("%zz"), None);
    }

    #[test]
    fn slerp_takes_the_short_way_and_normalises() {
        let a = Quat::IDENTITY;
        let b = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let half = slerp(a, -b, 0.5);
        let want = Quat::from_rotation_z(std::f32::consts::FRAC_PI_4);
        assert!(half.dot(want).abs() > 1.0 - 1e-6, "{half:?}");
        assert!((slerp(a * 2.0, b * 3.0, 0.25).length() - 1.0).abs() < 1e-6);
        assert_eq!(unit_quat(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)), Quat::IDENTITY);
    }

    #[test]
    fn glb_splitting_rejects_bad_lengths() {
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(4u32.to_le_bytes()); // shorter than the header itself
        assert!(split_glb(&glb).is_err());
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(28u32.to_le_bytes());
        glb.extend(100u32.to_le_bytes()); // chunk longer than the file
        glb.extend(b"JSON");
        glb.extend(b"{}  ");
        assert!(split_glb(&glb).is_err());
    }
}
