//! The rigged mesh: vertices, skins, morph targets and node transforms, posed and welded.

use super::*;

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
    /// Per-corner attributes and materials, parallel to `triangles`; `None` when not read.
    pub appearance: Option<crate::Appearance>,
    /// What reading changed or doubts in the input (influences beyond four dropped, weights
    /// renormalised), naming the primitive and skin; copied into `SequenceSkin::warnings`.
    pub warnings: Vec<String>,
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
    /// Index into the file's `nodes`: the node that instantiates the mesh.
    pub node: usize,
    /// Index into the file's `meshes`.
    pub mesh: usize,
    /// Index into the mesh's `primitives`.
    pub primitive: usize,
}

/// A node's rest transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeTransform {
    /// Local translation.
    pub translation: Vec3,
    /// Local rotation, a unit quaternion.
    pub rotation: Quat,
    /// Local non-uniform scale.
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
    /// Joint nodes (indices into the file's `nodes`); a vertex's joint index `j` names `joints[j]`.
    pub joints: Vec<usize>,
    /// One matrix per joint, from the mesh's space into the joint's space at bind time.
    pub inverse_bind_matrices: Vec<Mat4>,
}

/// What the rest of a file may still add while it is read: vertex records (a vertex plus one per
/// morph target) up to [`MAX_ELEMENTS`], and vertices and triangles up to the input limits.
pub(super) struct Budget<'a> {
    records: usize,
    limits: &'a InputLimits,
}

/// Most positions a sequence may hold (frames times vertices), and most frames: a hostile
/// duration or frame rate must not exhaust memory.
pub(super) const MAX_POSITIONS: usize = 1 << 28;
pub(super) const MAX_FRAMES: usize = 1 << 20;
/// Most components one accessor may decode to, and most vertex records (a vertex plus one per
/// morph target) a file may expand to: a few kilobytes of JSON can otherwise ask for terabytes
/// (a huge `count` without a bufferView, a million empty morph targets, a mesh instanced by a
/// million nodes).
pub(super) const MAX_ELEMENTS: usize = 1 << 27;

impl RiggedMesh {
    /// Reads a `.glb` or `.gltf` file (external buffers from its folder).
    pub fn from_path(path: &Path) -> Result<Self, MeshError> {
        Self::from_path_with(path, &InputLimits::default())
    }

    /// [`RiggedMesh::from_path`] under the given limits on vertices and triangles.
    pub fn from_path_with(path: &Path, limits: &InputLimits) -> Result<Self, MeshError> {
        let file = GltfFile::open(path, limits)?;
        Self::from_file(&file, limits).map_err(|e| at_path(path, e))
    }

    /// Reads a GLB or a self-contained `.gltf` from memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, MeshError> {
        Self::from_bytes_with(bytes, &InputLimits::default())
    }

    /// [`RiggedMesh::from_bytes`] under the given limits on vertices and triangles.
    pub fn from_bytes_with(bytes: &[u8], limits: &InputLimits) -> Result<Self, MeshError> {
        Self::from_file(&GltfFile::parse(bytes, None, limits)?, limits)
    }

    pub(super) fn from_file(file: &GltfFile, limits: &InputLimits) -> Result<Self, MeshError> {
        let root = &file.root;
        let mut rig = RiggedMesh { nodes: read_nodes(root)?, parents: node_parents(root)?, ..Default::default() };
        for (s, skin) in root.skins.iter().enumerate() {
            rig.skins.push(read_skin(file, s, skin)?);
        }
        rig.appearance = Some(read_document_looks(file)?);
        let mut budget = Budget { records: MAX_ELEMENTS, limits };
        for node in scene_mesh_nodes(root, &rig.parents) {
            rig.add_instance(file, node, &mut budget)?;
        }
        let targets = morph_target_counts(root);
        rig.animations = read_animations(file, &targets)?;
        rig.finish_looks();
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
        let sampler = self.sampler(animation, frame_rate, limits)?;
        let mut seq = sampler.head_unchecked();
        seq.frames.extend(sampler.frames(1));
        seq.validate()?;
        Ok(seq)
    }

    /// The frames of `animation` (as [`RiggedMesh::to_sequence_with`] samples them, under the
    /// same checks) made one at a time when asked for, so that a long animation never holds
    /// every frame's positions at once: see [`FrameSampler`].
    pub fn sampler(&self, animation: Option<usize>, frame_rate: f32, limits: &InputLimits) -> Result<FrameSampler<'_>, MeshError> {
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
        Ok(FrameSampler { rig: self, animation: anim, frame_rate, count, label })
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
        let mut out = Vec::new();
        self.pose_into(animation, t, &mut out);
        out
    }

    /// [`RiggedMesh::pose`] into `out` (resized to the vertex count), reusing its allocation.
    pub fn pose_into(&self, animation: Option<&Animation>, t: f32, out: &mut Vec<Vec3>) {
        let PoseTransforms { world, joints: joint_matrices, morph: weights } = self.pose_transforms(animation, t);
        let world_of = |n: usize| world.get(n).copied().unwrap_or(Mat4::IDENTITY);
        out.clear();
        out.resize(self.vertex_count(), Vec3::ZERO);
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
        let mut kept = Vec::with_capacity(self.triangles.len());
        let mut triangles = Vec::with_capacity(self.triangles.len());
        for (i, t) in self.triangles.iter().enumerate() {
            let Some(t) = (|| Some([map(t[0])?, map(t[1])?, map(t[2])?]))() else { continue };
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                kept.push(i);
                triangles.push(t);
            }
        }
        self.triangles = triangles;
        // Corner wedges follow their triangles; wedges follow their vertices.
        if let Some(app) = &mut self.appearance {
            app.retain_triangles(&kept);
            app.remap_vertices(remap);
        }
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

        let (joints, weights) = match inst.skin.and_then(|s| self.skins.get(s).map(|k| (s, k))) {
            Some((s, skin)) => read_influences(file, &attribute, n, skin.joints.len(), &format!("{what} (skin {s})"), &mut self.warnings)?,
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

        let looks = read_primitive_looks(file, prim, n, what)?;
        let base = self.positions.len() as u32;
        let first_triangle = self.triangles.len();
        self.positions.extend(positions);
        self.joints.extend(joints);
        self.weights.extend(weights);
        self.source.extend((0..n as u32).map(|index| SourceVertex { primitive: number, index }));
        self.triangles.extend(triangles.into_iter().filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]).map(|t| t.map(|i| i + base)));
        self.add_primitive_looks(looks, base as usize, first_triangle);
        Ok(())
    }
}

/// Per-vertex joints and weights, as stored in [`RiggedMesh::joints`] and [`RiggedMesh::weights`].
pub(super) type Influences = (Vec<[u16; 4]>, Vec<[f32; 4]>);

/// How far the (kept) weights of a vertex may sum from one before it is reported: 8-bit
/// normalised weights round each to 1/255, so four of them may miss by 2/255.
const WEIGHT_SUM_TOLERANCE: f32 = 0.01;

/// Reads every `JOINTS_n`/`WEIGHTS_n` pair of a skinned primitive and reduces each vertex to its
/// four strongest influences, normalised to sum to 1 (§3.7.3.3 asks for normalised weights;
/// exporters drift, so they are normalised rather than rejected).
pub(super) fn read_influences(
    file: &GltfFile,
    attribute: &dyn Fn(json::mesh::Semantic) -> Option<usize>,
    n: usize,
    joint_count: usize,
    what: &str,
    warnings: &mut Vec<String>,
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
    // Vertices changed on read, summarised into one warning each: (count, first vertex, detail).
    let mut beyond_four: (usize, usize, usize) = (0, 0, 0);
    let mut off_one: (usize, usize, f32) = (0, 0, 1.0);
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
        // The file's weights, before any are dropped.
        let given: f32 = influences.iter().map(|i| i.1).sum();
        if given > 0.0 && (given - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
            if off_one.0 == 0 {
                off_one = (0, v, given);
            }
            off_one.0 += 1;
        }
        if influences.len() > 4 {
            if beyond_four.0 == 0 {
                beyond_four = (0, v, influences.len());
            }
            beyond_four.0 += 1;
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
    if beyond_four.0 > 0 {
        let (count, v, k) = beyond_four;
        warnings.push(format!(
            "{what}: {count} vertices have more than four influences (vertex {v} has {k}); \
             kept the four largest of each and renormalised their weights to sum to one"
        ));
    }
    if off_one.0 > 0 {
        let (count, v, sum) = off_one;
        warnings.push(format!("{what}: {count} vertices' weights do not sum to one (vertex {v}: {sum}); renormalised to sum to one"));
    }
    Ok((joints_out, weights_out))
}

pub(super) fn to_vec3(flat: &[f32]) -> Vec<Vec3> {
    flat.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
}

/// A rotation as a unit quaternion; the identity when it has no direction (a zero or non-finite
/// quaternion cannot be normalised and would turn every vertex it touches into NaN).
pub(super) fn unit_quat(q: Quat) -> Quat {
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
