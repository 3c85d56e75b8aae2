//! The discrete LOD chain: one rig per level (level 0 is the welded input), and for every
//! level but the last a correspondence table from its vertices to the next coarser level's.
//!
//! All levels come from one collapse run ([`crate::simplify`]), so they are nested: every
//! vertex of level k was merged into exactly one survivor of level k + 1, and that survivor is
//! where it should move to when an engine geomorphs from k to k + 1 (Houle & Poulin,
//! "Simplification and Real-time Smooth Transitions of Articulated Meshes", 2001,
//! section 5). Because a level's vertex is posed by the same skin as the survivor it maps to
//! (collapses stay within a class), the morph can run after skinning in any pose.
//!
//! Output layout of a level: one instance (one glTF mesh) per vertex class that has triangles,
//! in class order. A triangle goes to the class of its first corner that is not a shared-skin
//! class (morph or rigid parts win), else its first corner's class; corners of another class
//! are copied into it (same skin; zero morph deltas). Level vertex numbers run over the
//! instances in order: that numbering is what the tables index.

use crate::attrs::{Vertex, VertexAttrs};
use crate::poses::{displacement, importance, sample_poses};
use crate::refit::{RefitOptions, refit};
use crate::simplify::{simplify, thin_poses};
use crate::wedges::Wedges;
use crate::{LodError, LodOptions, Placement};
use glam::Vec3;
use pmcodec_mesh::gltf_input::{MeshInstance, PrimitiveRef, RiggedMesh};
use pmcodec_mesh::{Appearance, SourceVertex};
use std::collections::HashMap;

/// One level of the chain.
#[derive(Clone, Debug)]
pub struct LodLevel {
    /// Poses exactly like the input (same nodes, skins and animations).
    pub rig: RiggedMesh,
    /// The triangle target asked for (`None` for level 0).
    pub target: Option<usize>,
    /// Per level vertex: its class and its id in the welded input.
    pub ids: Vec<(u32, u32)>,
    /// Per level vertex, the vertex of the next coarser level it morphs to (empty for the last).
    pub to_coarser: Vec<u32>,
}

/// The input (welded), the levels, and how they were made.
#[derive(Clone, Debug)]
pub struct LodChain {
    /// The rig the chain was built from, as given; every level keeps its nodes, skins and animations.
    pub input: RiggedMesh,
    /// The input's vertices welded across seams (rest position, influences, morph deltas) with
    /// their classes; a level vertex's id indexes these.
    pub attrs: VertexAttrs,
    /// The levels, finest first, each nested in the one before.
    pub levels: Vec<LodLevel>,
    /// Number of example poses the costs were summed over.
    pub pose_count: usize,
}

fn is_shared_skin(attrs: &VertexAttrs, class: u32) -> bool {
    attrs.classes.get(class as usize).is_some_and(|c| c.skin.is_some() && c.morph_count == 0)
}

/// The appearance of a level's triangles: per triangle its corner wedges and material, and
/// the attribute values of every wedge (see [`crate::wedges`]).
#[derive(Clone, Copy)]
pub struct LevelLooks<'a> {
    pub wedges: &'a Wedges,
    pub corner: &'a [[u32; 3]],
    pub material: &'a [u32],
    pub values: &'a [f32],
}

/// Builds the rig of one level from vertex records and triangles over input ids; with `looks`
/// (and an input appearance) the level gets its appearance, one wedge per (level vertex, wedge).
pub fn level_rig(
    input: &RiggedMesh,
    attrs: &VertexAttrs,
    verts: &[Vertex],
    triangles: &[[u32; 3]],
    looks: Option<LevelLooks>,
) -> (RiggedMesh, Vec<(u32, u32)>) {
    let class_of = |id: u32| verts[id as usize].class;
    let mut by_class: Vec<Vec<usize>> = vec![Vec::new(); attrs.classes.len()];
    for (t, tri) in triangles.iter().enumerate() {
        let home = tri.iter().map(|&c| class_of(c)).find(|&c| !is_shared_skin(attrs, c)).unwrap_or(class_of(tri[0]));
        if let Some(list) = by_class.get_mut(home as usize) {
            list.push(t);
        }
    }
    let looks = looks.zip(input.appearance.as_ref());
    let mut app = looks.map(|(_, a)| Appearance {
        materials: a.materials.clone(),
        textures: a.textures.clone(),
        samplers: a.samplers.clone(),
        images: a.images.clone(),
        ..Default::default()
    });
    let mut level_wedge: HashMap<(u32, u32), u32> = HashMap::new();
    let mut rig = RiggedMesh {
        nodes: input.nodes.clone(),
        parents: input.parents.clone(),
        skins: input.skins.clone(),
        animations: input.animations.clone(),
        ..Default::default()
    };
    let mut ids = Vec::new();
    for (c, tris) in by_class.iter().enumerate() {
        if tris.is_empty() {
            continue;
        }
        let info = &attrs.classes[c];
        let start = rig.positions.len();
        let mut local: HashMap<u32, u32> = HashMap::new();
        let mut morph: Vec<Vec<Vec3>> = vec![Vec::new(); info.morph_count];
        for &ti in tris {
            let tri = &triangles[ti];
            let t = tri.map(|id| {
                *local.entry(id).or_insert_with(|| {
                    let v = &verts[id as usize];
                    let index = (rig.positions.len() - start) as u32;
                    rig.positions.push(v.rest);
                    rig.joints.push(v.joints);
                    rig.weights.push(v.weights);
                    rig.source.push(SourceVertex { primitive: rig.instances.len() as u32, index });
                    let own = v.class as usize == c;
                    for (k, m) in morph.iter_mut().enumerate() {
                        m.push(if own { v.morph.get(k).copied().unwrap_or(Vec3::ZERO) } else { Vec3::ZERO });
                    }
                    ids.push((c as u32, id));
                    start as u32 + index
                })
            });
            rig.triangles.push(t);
            if let (Some(app), Some((l, _))) = (app.as_mut(), looks) {
                let cw = l.corner.get(ti).copied().unwrap_or_default();
                let corners: [u32; 3] = std::array::from_fn(|i| {
                    *level_wedge.entry((t[i], cw[i])).or_insert_with(|| {
                        push_wedge(app, l, cw[i], t[i]);
                        app.wedge_vertex.len() as u32 - 1
                    })
                });
                app.corner_wedges.push(corners);
                app.triangle_material.push(l.material.get(ti).copied().unwrap_or(0));
            }
        }
        rig.primitives.push(PrimitiveRef { node: info.node, mesh: c, primitive: 0 });
        rig.instances.push(MeshInstance {
            node: info.node,
            mesh: c,
            skin: info.skin,
            vertices: start..rig.positions.len(),
            morph_targets: morph,
            default_weights: input.instances.get(info.instance).map(|i| i.default_weights.clone()).unwrap_or_default(),
        });
    }
    rig.appearance = app;
    (rig, ids)
}

/// Appends wedge `w` of the simplifier as a level wedge on level vertex `vertex`.
fn push_wedge(app: &mut Appearance, l: LevelLooks, w: u32, vertex: u32) {
    let c = l.wedges.channels;
    let v = l.values.get(w as usize * c..(w as usize + 1) * c).unwrap_or_default();
    let mut at = 0;
    let mut take = |n: usize| {
        let s = v.get(at..at + n).unwrap_or_default();
        at += n;
        s
    };
    let layout = l.wedges.layout;
    if layout.uv0 {
        let s = take(2);
        app.uv0.push([s.first().copied().unwrap_or(0.0), s.get(1).copied().unwrap_or(0.0)]);
    }
    if layout.uv1 {
        let s = take(2);
        app.uv1.push([s.first().copied().unwrap_or(0.0), s.get(1).copied().unwrap_or(0.0)]);
    }
    if layout.colors {
        let s = take(4);
        app.colors.push(std::array::from_fn(|k| s.get(k).copied().unwrap_or(1.0).clamp(0.0, 1.0)));
    }
    if let Some(n) = l.wedges.normals.get(w as usize) {
        app.normals.push(*n);
    }
    app.wedge_vertex.push(vertex);
}

/// The simplifier's wedges of `input`: from its appearance, or one wedge per vertex and no
/// attributes when it has none.
pub fn input_wedges(input: &RiggedMesh) -> Wedges {
    match &input.appearance {
        Some(app) if app.corner_wedges.len() == input.triangles.len() => Wedges::from_appearance(app),
        _ => Wedges {
            corner: input.triangles.clone(),
            material: vec![0; input.triangles.len()],
            vertex: (0..input.vertex_count() as u32).collect(),
            ..Default::default()
        },
    }
}

/// The looks of the input's own triangles (level 0).
fn input_looks(w: &Wedges) -> LevelLooks<'_> {
    LevelLooks { wedges: w, corner: &w.corner, material: &w.material, values: &w.values }
}

impl LodChain {
    /// A chain of level 0 alone: the welded input in the output layout (to write a rig as GLB).
    pub fn single(input: RiggedMesh) -> Result<Self, LodError> {
        validate_rig(&input)?;
        let attrs = VertexAttrs::from_rig(&input)?;
        let wedges = input_wedges(&input);
        let (rig, ids) = level_rig(&input, &attrs, &attrs.verts, &input.triangles, Some(input_looks(&wedges)));
        let levels = vec![LodLevel { rig, target: None, ids, to_coarser: Vec::new() }];
        Ok(LodChain { input, attrs, levels, pose_count: 0 })
    }
}

/// Checks what the simplifier and the writer index by: triangle corners, skins, joints.
/// [`RiggedMesh`]s read from files already pass; rigs built in code may not.
pub fn validate_rig(rig: &RiggedMesh) -> Result<(), LodError> {
    let n = rig.vertex_count();
    if rig.triangles.is_empty() {
        return Err(LodError::BadRig("no triangles".into()));
    }
    for (t, tri) in rig.triangles.iter().enumerate() {
        if tri.iter().any(|&i| i as usize >= n) || tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err(LodError::BadRig(format!("triangle {t} {tri:?} is out of range or repeats a corner ({n} vertices)")));
        }
    }
    if rig.joints.len() != n || rig.weights.len() != n {
        return Err(LodError::BadRig(format!("{} joints and {} weights for {n} vertices", rig.joints.len(), rig.weights.len())));
    }
    if rig.parents.len() != rig.nodes.len() {
        return Err(LodError::BadRig(format!("{} parents for {} nodes", rig.parents.len(), rig.nodes.len())));
    }
    for (i, inst) in rig.instances.iter().enumerate() {
        if inst.node >= rig.nodes.len() {
            return Err(LodError::BadRig(format!("instance {i} is placed by node {}, which does not exist", inst.node)));
        }
        let Some(s) = inst.skin else { continue };
        let skin = rig.skins.get(s).ok_or_else(|| LodError::BadRig(format!("instance {i} uses skin {s}, which does not exist")))?;
        if skin.joints.iter().any(|&j| j >= rig.nodes.len()) || skin.inverse_bind_matrices.len() != skin.joints.len() {
            return Err(LodError::BadRig(format!("skin {s} names missing nodes or lacks inverse bind matrices")));
        }
        for v in inst.vertices.clone() {
            let (j, w) = (rig.joints.get(v).copied().unwrap_or_default(), rig.weights.get(v).copied().unwrap_or_default());
            if j.iter().zip(&w).any(|(&j, &w)| w != 0.0 && j as usize >= skin.joints.len()) || !w.iter().all(|x| x.is_finite() && *x >= 0.0)
            {
                return Err(LodError::BadRig(format!("vertex {v}: joints {j:?} weights {w:?} do not fit skin {s}")));
            }
        }
    }
    Ok(())
}

/// Builds the chain: level 0 is the welded `input`, then one level per target (decreasing
/// triangle counts), every level refitted with the default [`RefitOptions`].
pub fn build_chain(input: RiggedMesh, targets: &[usize], opts: &LodOptions) -> Result<LodChain, LodError> {
    build_chain_with(input, targets, opts, &RefitOptions::default())
}

/// [`build_chain`] with explicit refit options (`iterations: 0` leaves the collapse positions).
/// [`Placement::Endpoint`] levels are never refitted: that policy keeps input vertices as they
/// are.
/// A separate entry point rather than a field of [`LodOptions`], which callers build literally.
pub fn build_chain_with(input: RiggedMesh, targets: &[usize], opts: &LodOptions, refit_opts: &RefitOptions) -> Result<LodChain, LodError> {
    if targets.is_empty() {
        return Err(LodError::NoTargets);
    }
    validate_rig(&input)?;
    let attrs = VertexAttrs::from_rig(&input)?;
    let poses = thin_poses(&sample_poses(&input, &opts.poses)?, attrs.len());
    let weights = importance(&displacement(&attrs, &poses), opts.poses.vertex_weighting);
    let wedges = input_wedges(&input);
    let mut snaps = simplify(&attrs, &wedges, &input.triangles, &poses, &weights, opts.placement, targets)?;
    // Endpoint placement promises input vertices unchanged (Mohr & Gleicher 4.3): no refit.
    if opts.placement != Placement::Endpoint {
        for snap in &mut snaps {
            refit(&attrs, &input.triangles, &poses, &mut snap.verts, &snap.triangles, &snap.rep, refit_opts);
        }
    }

    let (rig0, ids0) = level_rig(&input, &attrs, &attrs.verts, &input.triangles, Some(input_looks(&wedges)));
    let mut levels = vec![LodLevel { rig: rig0, target: None, ids: ids0, to_coarser: Vec::new() }];
    let mut reps: Vec<Vec<u32>> = Vec::new();
    for snap in &snaps {
        let looks = LevelLooks { wedges: &wedges, corner: &snap.corner, material: &snap.material, values: &snap.values };
        let (rig, ids) = level_rig(&input, &attrs, &snap.verts, &snap.triangles, Some(looks));
        levels.push(LodLevel { rig, target: Some(snap.target), ids, to_coarser: Vec::new() });
        reps.push(snap.rep.clone());
    }
    for k in 0..levels.len() - 1 {
        let coarse = &levels[k + 1];
        let mut exact: HashMap<(u32, u32), u32> = HashMap::new();
        let mut any: HashMap<u32, u32> = HashMap::new();
        for (i, &(c, id)) in coarse.ids.iter().enumerate() {
            exact.insert((c, id), i as u32);
            any.entry(id).or_insert(i as u32);
        }
        let rep = &reps[k];
        let mut table = Vec::with_capacity(levels[k].ids.len());
        for &(c, id) in &levels[k].ids {
            let r = rep.get(id as usize).copied().unwrap_or(id);
            let to =
                exact.get(&(c, r)).or_else(|| any.get(&r)).copied().ok_or_else(|| {
                    LodError::Internal(format!("level {k} vertex {id} merged into {r}, which level {} does not use", k + 1))
                })?;
            table.push(to);
        }
        levels[k].to_coarser = table;
    }
    Ok(LodChain { input, attrs, levels, pose_count: poses.len() })
}
