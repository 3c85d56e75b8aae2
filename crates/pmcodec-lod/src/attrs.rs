//! The vertex record the simplifier carries, and how it is posed.
//!
//! A welded vertex belongs to a *class*: the transform set that poses it. Vertices of a skinned
//! instance without morph targets share the class of their skin (the loader welds them across
//! instances of one skin); vertices of an instance with morph targets, or of a rigid instance,
//! have their instance's class. Collapses only join vertices of one class, so a collapsed vertex
//! is always posed by the same machinery as its parents.
//!
//! In every pose, a vertex is an affine function of its rest position `p`:
//! `x = M (p + sum_k w_k d_k) = L p + (L m + t)` with `M = [L | t]` the blended skin matrix (or
//! the node's world transform for rigid parts) and `m` the morph offset. Pulling a pose's
//! quadric back through that map gives a quadric in rest space, which is how the optimal
//! placements are solved (see [`crate::placement`]).

use crate::poses::Pose;
use glam::{Mat3, Mat4, Vec3};
use pmcodec_mesh::gltf_input::RiggedMesh;

/// What poses the vertices of one class.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassInfo {
    /// Index into the rig's instances: whose morph weights and node apply.
    pub instance: usize,
    /// The node of that instance (world transform for rigid parts).
    pub node: usize,
    pub skin: Option<usize>,
    /// Morph targets of the class (its instance's), 0 for a shared-skin class.
    pub morph_count: usize,
}

/// One vertex: rest position (mesh or bind space), up to four influences summing to 1
/// (all zero when rigid), and one delta per morph target of its class.
#[derive(Clone, Debug, PartialEq)]
pub struct Vertex {
    pub rest: Vec3,
    pub joints: [u16; 4],
    pub weights: [f32; 4],
    pub morph: Vec<Vec3>,
    pub class: u32,
}

/// The welded vertices of a rig with their classes.
#[derive(Clone, Debug, Default)]
pub struct VertexAttrs {
    pub verts: Vec<Vertex>,
    pub classes: Vec<ClassInfo>,
    /// Convenience copy of the rest positions.
    pub rest: Vec<Vec3>,
}

impl VertexAttrs {
    /// The records of a (welded) rig.
    pub fn from_rig(rig: &RiggedMesh) -> Result<Self, crate::LodError> {
        let mut classes: Vec<ClassInfo> = Vec::new();
        let mut verts = Vec::with_capacity(rig.vertex_count());
        let mut skin_class: Vec<Option<u32>> = vec![None; rig.skins.len()];
        for (i, inst) in rig.instances.iter().enumerate() {
            let class = match inst.skin {
                Some(s) if inst.morph_targets.is_empty() && s < skin_class.len() => *skin_class[s].get_or_insert_with(|| {
                    classes.push(ClassInfo { instance: i, node: inst.node, skin: Some(s), morph_count: 0 });
                    classes.len() as u32 - 1
                }),
                skin => {
                    classes.push(ClassInfo { instance: i, node: inst.node, skin, morph_count: inst.morph_targets.len() });
                    classes.len() as u32 - 1
                }
            };
            if inst.vertices.start != verts.len() {
                return Err(crate::LodError::BadRig(format!("instance {i} starts at vertex {}", inst.vertices.start)));
            }
            for (k, v) in inst.vertices.clone().enumerate() {
                let skinned = inst.skin.is_some();
                verts.push(Vertex {
                    rest: rig.positions.get(v).copied().unwrap_or(Vec3::ZERO),
                    joints: if skinned { rig.joints.get(v).copied().unwrap_or_default() } else { [0; 4] },
                    weights: if skinned { rig.weights.get(v).copied().unwrap_or_default() } else { [0.0; 4] },
                    morph: inst.morph_targets.iter().map(|t| t.get(k).copied().unwrap_or(Vec3::ZERO)).collect(),
                    class,
                });
            }
        }
        if verts.len() != rig.vertex_count() {
            return Err(crate::LodError::BadRig(format!("instances cover {} of {} vertices", verts.len(), rig.vertex_count())));
        }
        let rest = verts.iter().map(|v| v.rest).collect();
        Ok(VertexAttrs { verts, classes, rest })
    }

    pub fn len(&self) -> usize {
        self.verts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.verts.is_empty()
    }

    /// Position of vertex `v` in `pose`.
    pub fn posed(&self, v: usize, pose: &Pose) -> Vec3 {
        let (l, c) = self.affine(&self.verts[v], pose);
        l * self.verts[v].rest + c
    }

    /// `(L, c)` with `x = L p + c` for a record's rest position `p` in `pose`.
    pub fn affine(&self, vert: &Vertex, pose: &Pose) -> (Mat3, Vec3) {
        let Some(class) = self.classes.get(vert.class as usize) else { return (Mat3::IDENTITY, Vec3::ZERO) };
        let mut m = Vec3::ZERO;
        if let Some(w) = pose.morph.get(class.instance) {
            for (d, &w) in vert.morph.iter().zip(w) {
                m += *d * w;
            }
        }
        let mat = self.matrix(vert, class, pose);
        let l = Mat3::from_mat4(mat);
        (l, l * m + mat.w_axis.truncate())
    }

    fn matrix(&self, vert: &Vertex, class: &ClassInfo, pose: &Pose) -> Mat4 {
        match class.skin.and_then(|s| pose.joints.get(s)) {
            Some(mats) => {
                let mut blended = Mat4::ZERO;
                for (&j, &w) in vert.joints.iter().zip(&vert.weights) {
                    if w != 0.0 {
                        blended += mats.get(j as usize).copied().unwrap_or(Mat4::IDENTITY) * w;
                    }
                }
                blended
            }
            None => pose.world.get(class.node).copied().unwrap_or(Mat4::IDENTITY),
        }
    }

    /// The single transform that dominates vertex `v` in `pose`: its heaviest joint's matrix, or
    /// its node's world transform.
    pub fn dominant(&self, v: usize, pose: &Pose) -> Mat4 {
        let vert = &self.verts[v];
        let Some(class) = self.classes.get(vert.class as usize) else { return Mat4::IDENTITY };
        match class.skin.and_then(|s| pose.joints.get(s)) {
            Some(mats) => {
                let mut best = 0;
                for k in 1..4 {
                    if vert.weights[k] > vert.weights[best] {
                        best = k;
                    }
                }
                mats.get(vert.joints[best] as usize).copied().unwrap_or(Mat4::IDENTITY)
            }
            None => pose.world.get(class.node).copied().unwrap_or(Mat4::IDENTITY),
        }
    }
}

/// Blends two influence sets `(1 - t) a + t b`, keeps the four heaviest joints and renormalises
/// them to sum to 1 (Mohr & Gleicher's "optimal" LBS variant, cut to the four influences glTF
/// allows). Unused slots get joint 0 and weight 0.
pub fn blend_influences(a: ([u16; 4], [f32; 4]), b: ([u16; 4], [f32; 4]), t: f32) -> ([u16; 4], [f32; 4]) {
    let mut acc: Vec<(u16, f32)> = Vec::with_capacity(8);
    for (joints, weights, s) in [(a.0, a.1, 1.0 - t), (b.0, b.1, t)] {
        for (&j, &w) in joints.iter().zip(&weights) {
            if w > 0.0 {
                match acc.iter_mut().find(|(k, _)| *k == j) {
                    Some(slot) => slot.1 += w * s,
                    None => acc.push((j, w * s)),
                }
            }
        }
    }
    acc.retain(|&(_, w)| w > 0.0);
    acc.sort_by(|x, y| y.1.total_cmp(&x.1).then(x.0.cmp(&y.0)));
    acc.truncate(4);
    let sum: f32 = acc.iter().map(|x| x.1).sum();
    let mut joints = [0u16; 4];
    let mut weights = [0f32; 4];
    if sum > 0.0 {
        for (k, &(j, w)) in acc.iter().enumerate() {
            joints[k] = j;
            weights[k] = w / sum;
        }
    }
    (joints, weights)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blend_keeps_four_and_normalises() {
        let a = ([1, 2, 3, 4], [0.4, 0.3, 0.2, 0.1]);
        let b = ([5, 1, 0, 0], [0.9, 0.1, 0.0, 0.0]);
        let (j, w) = blend_influences(a, b, 0.5);
        assert_eq!(j[0], 5);
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert_eq!(w.iter().filter(|&&x| x > 0.0).count(), 4);
        let (j, w) = blend_influences(a, b, 0.0);
        assert_eq!((j, w), ([1, 2, 3, 4], [0.4, 0.3, 0.2, 0.1]));
    }
}
