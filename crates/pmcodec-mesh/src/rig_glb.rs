//! A skinned GLB of a rig given as rest positions, at most four influences per vertex and one
//! transform per bone per frame: what `pmcodec decode --skinned-glb` writes, so that a skin
//! fitted to a simulation or a capture (Le and Deng, "Smooth skinning decomposition with rigid
//! bones", 2012) can be taken into an engine as a skinned mesh.
//!
//! The bones are joints without a bind pose of their own: their inverse bind matrices are the
//! identity, so a bone's animated world transform *is* its skinning transform, which is what a
//! fitted rig has (a bone maps rest positions to posed positions; there is no skeleton). They
//! hang under one still root joint, so the skin has the common root glTF requires, and that
//! root also carries vertices without influences, which then stay at their rest position.
//! A transform is written as translation, rotation and scale (glTF animates nothing else): its
//! scale is the length of each column and its rotation the rest, so shear, which rigid bones do
//! not have, is dropped.

use crate::MeshError;
use crate::glb::{ARRAY_BUFFER, GlbBuilder, TRIANGLES};
use glam::{Mat4, Quat, Vec3};
use serde_json::{Value, json};

/// Bones a rig may have: joint indices are 16-bit in the GLB and the root takes one.
pub const MAX_BONES: usize = u16::MAX as usize - 1;

/// A rig to write: every vector has one entry per vertex, `poses` one per frame.
#[derive(Clone, Debug, Default)]
pub struct Rig {
    /// Positions before skinning.
    pub rest: Vec<Vec3>,
    /// Triangles as indices into `rest`.
    pub triangles: Vec<[u32; 3]>,
    /// Up to four bones per vertex (indices into each pose); a slot of weight 0 is unused.
    pub bones: Vec<[u16; 4]>,
    /// The four weights, non-negative and summing to 1, or all zero for a vertex no bone moves.
    pub weights: Vec<[f32; 4]>,
    /// Per frame, per bone: the transform from rest positions to that frame's positions.
    pub poses: Vec<Vec<Mat4>>,
    /// Frames per second of the animation.
    pub frame_rate: f32,
}

impl Rig {
    /// Checks that the parts agree, naming the first that does not.
    fn check(&self) -> Result<usize, MeshError> {
        let bad = |m: String| Err(MeshError::Invalid(format!("skinned GLB: {m}")));
        let n = self.rest.len();
        if self.bones.len() != n || self.weights.len() != n {
            return bad(format!("{n} vertices but {} bone sets and {} weight sets", self.bones.len(), self.weights.len()));
        }
        let Some(first) = self.poses.first() else { return bad("no frames".into()) };
        let bones = first.len();
        if bones == 0 || bones > MAX_BONES {
            return bad(format!("{bones} bones (1 to {MAX_BONES})"));
        }
        if let Some(f) = self.poses.iter().position(|p| p.len() != bones) {
            return bad(format!("frame {f} has {} bone transforms, frame 0 has {bones}", self.poses[f].len()));
        }
        if !(self.frame_rate.is_finite() && self.frame_rate > 0.0) {
            return bad(format!("frame rate {}", self.frame_rate));
        }
        if let Some(v) = self.rest.iter().position(|p| !p.is_finite()) {
            return bad(format!("vertex {v}: rest position is not finite"));
        }
        for (v, (b, w)) in self.bones.iter().zip(&self.weights).enumerate() {
            for k in 0..4 {
                if !(w[k].is_finite() && w[k] >= 0.0) {
                    return bad(format!("vertex {v}: weight {} is not a finite non-negative number", w[k]));
                }
                if w[k] > 0.0 && b[k] as usize >= bones {
                    return bad(format!("vertex {v}: bone {} of {bones}", b[k]));
                }
            }
        }
        if let Some(t) = self.triangles.iter().position(|t| t.iter().any(|&c| c as usize >= n)) {
            return bad(format!("triangle {t} indexes past the {n} vertices"));
        }
        for (f, pose) in self.poses.iter().enumerate() {
            if let Some(b) = pose.iter().position(|m| !m.is_finite()) {
                return bad(format!("frame {f}: bone {b}'s transform is not finite"));
            }
        }
        Ok(bones)
    }
}

/// The bone's transform as glTF's translation, rotation and scale. A singular one (a bone no
/// vertex uses may be all zero) has no rotation: it becomes its translation alone.
fn trs(m: &Mat4) -> (Vec3, Quat, Vec3) {
    let (scale, rotation, translation) = m.to_scale_rotation_translation();
    let rotation = rotation.normalize();
    if m.determinant().abs() > f32::MIN_POSITIVE && scale.is_finite() && rotation.is_finite() {
        (translation, rotation, scale)
    } else {
        (m.w_axis.truncate(), Quat::IDENTITY, Vec3::ONE)
    }
}

/// Writes `rig` as a GLB: one skinned mesh, its root and bones, and one animation that sets
/// every bone's translation and rotation (and scale, when some frame scales) at each frame.
pub fn rig_glb(rig: &Rig) -> Result<Vec<u8>, MeshError> {
    let bones = rig.check()?;
    let mut b = GlbBuilder::default();
    let position = b.vec3s(&rig.rest, Some(ARRAY_BUFFER), true);
    // Joint 0 is the root: bone i is joint i + 1. A vertex no bone moves is the root's.
    let mut joints = Vec::with_capacity(rig.rest.len());
    let mut weights = Vec::with_capacity(rig.rest.len() * 4);
    for (bs, ws) in rig.bones.iter().zip(&rig.weights) {
        let sum: f32 = ws.iter().sum();
        if sum > 0.0 {
            joints.push([0, 1, 2, 3].map(|k| if ws[k] > 0.0 { bs[k] + 1 } else { 0 }));
            weights.extend(ws.iter().map(|w| w / sum));
        } else {
            joints.push([0; 4]);
            weights.extend([1.0, 0.0, 0.0, 0.0]);
        }
    }
    let joints_acc = b.joints(&joints);
    let weights_acc = b.floats(&weights, Some(ARRAY_BUFFER), "VEC4", 4, false);
    let flat: Vec<u32> = rig.triangles.iter().flatten().copied().collect();
    let indices = b.indices(&flat, rig.rest.len());

    // Rotations of consecutive frames on the same side of the quaternion sphere, so that the
    // interpolation between samples takes the short way.
    let mut translations = vec![Vec::with_capacity(rig.poses.len() * 3); bones];
    let mut rotations = vec![Vec::with_capacity(rig.poses.len() * 4); bones];
    let mut scales = vec![Vec::with_capacity(rig.poses.len() * 3); bones];
    let mut scaled = false;
    let mut last = vec![Quat::IDENTITY; bones];
    for pose in &rig.poses {
        for (i, m) in pose.iter().enumerate() {
            let (t, mut r, s) = trs(m);
            if r.dot(last[i]) < 0.0 {
                r = -r;
            }
            last[i] = r;
            scaled |= (s - Vec3::ONE).abs().max_element() > 1e-4;
            translations[i].extend(t.to_array());
            rotations[i].extend(r.to_array());
            scales[i].extend(s.to_array());
        }
    }
    let times: Vec<f32> = (0..rig.poses.len()).map(|f| f as f32 / rig.frame_rate).collect();
    let input = b.floats(&times, None, "SCALAR", 1, true);
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let mut nodes = vec![
        json!({"name": "skinned mesh", "mesh": 0, "skin": 0}),
        json!({"name": "rig root", "children": (2..bones + 2).collect::<Vec<_>>()}),
    ];
    for i in 0..bones {
        let (t, r, s) = trs(&rig.poses[0][i]);
        let mut node = json!({"name": format!("bone {i}"), "translation": t.to_array(), "rotation": r.to_array()});
        if scaled {
            node["scale"] = json!(s.to_array());
        }
        nodes.push(node);
        let mut paths = vec![
            ("translation", b.floats(&translations[i], None, "VEC3", 3, false)),
            ("rotation", b.floats(&rotations[i], None, "VEC4", 4, false)),
        ];
        if scaled {
            paths.push(("scale", b.floats(&scales[i], None, "VEC3", 3, false)));
        }
        for (path, output) in paths {
            samplers.push(json!({"input": input, "output": output, "interpolation": "LINEAR"}));
            channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": i + 2, "path": path}}));
        }
    }
    let primitive = json!({
        "attributes": {"POSITION": position, "JOINTS_0": joints_acc, "WEIGHTS_0": weights_acc},
        "indices": indices,
        "mode": TRIANGLES,
    });
    let root: Value = json!({
        "asset": {"version": "2.0", "generator": "pmcodec"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": nodes,
        "meshes": [{"primitives": [primitive]}],
        "skins": [{"joints": (1..bones + 2).collect::<Vec<_>>(), "skeleton": 1}],
        "animations": [{"name": "fitted rig", "samplers": samplers, "channels": channels}],
    });
    b.finish(root)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_bone_rig(frames: usize) -> Rig {
        let rest = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        Rig {
            rest,
            triangles: vec![[0, 1, 2], [1, 3, 2]],
            bones: vec![[0, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 0]],
            weights: vec![[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0; 4]],
            poses: (0..frames)
                .map(|f| {
                    let a = f as f32 * 0.2;
                    vec![Mat4::from_translation(Vec3::new(f as f32, 0.0, 0.0)), Mat4::from_rotation_z(a)]
                })
                .collect(),
            frame_rate: 30.0,
        }
    }

    fn json_of(glb: &[u8]) -> Value {
        let len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        serde_json::from_slice(&glb[20..20 + len]).unwrap()
    }

    #[test]
    fn bones_are_animated_joints_under_one_root() {
        let glb = rig_glb(&two_bone_rig(5)).unwrap();
        let j = json_of(&glb);
        assert_eq!(j["skins"][0]["joints"], json!([1, 2, 3]));
        assert_eq!(j["nodes"][1]["children"], json!([2, 3]));
        // Two bones, translation and rotation each, no scale: four channels of five samples.
        assert_eq!(j["animations"][0]["channels"].as_array().unwrap().len(), 4);
        let input = j["animations"][0]["samplers"][0]["input"].as_u64().unwrap() as usize;
        assert_eq!(j["accessors"][input]["count"], json!(5));
        assert!((j["accessors"][input]["max"][0].as_f64().unwrap() - 4.0 / 30.0).abs() < 1e-6);
    }

    #[test]
    fn scale_is_animated_only_when_a_frame_scales() {
        let mut rig = two_bone_rig(3);
        rig.poses[2][1] = Mat4::from_scale(Vec3::splat(2.0));
        let j = json_of(&rig_glb(&rig).unwrap());
        let paths: Vec<&str> =
            j["animations"][0]["channels"].as_array().unwrap().iter().map(|c| c["target"]["path"].as_str().unwrap()).collect();
        assert_eq!(paths.iter().filter(|&&p| p == "scale").count(), 2);
    }

    #[test]
    fn a_singular_bone_becomes_its_translation() {
        let mut rig = two_bone_rig(2);
        rig.poses[1][1] = Mat4::ZERO;
        let glb = rig_glb(&rig).unwrap();
        let j = json_of(&glb);
        // Every number of the document (and so every node's rotation) is finite: serde_json
        // writes a NaN as null.
        assert!(!serde_json::to_string(&j).unwrap().contains("null"));
        assert_eq!(trs(&Mat4::ZERO), (Vec3::ZERO, Quat::IDENTITY, Vec3::ONE));
    }

    #[test]
    fn parts_that_disagree_are_refused_by_name() {
        let mut rig = two_bone_rig(2);
        rig.bones[1][1] = 7;
        let e = rig_glb(&rig).unwrap_err().to_string();
        assert!(e.contains("vertex 1") && e.contains("bone 7"), "{e}");
        let mut rig = two_bone_rig(2);
        rig.poses[1].pop();
        assert!(rig_glb(&rig).unwrap_err().to_string().contains("frame 1"));
        let mut rig = two_bone_rig(2);
        rig.poses.clear();
        assert!(rig_glb(&rig).unwrap_err().to_string().contains("no frames"));
        let mut rig = two_bone_rig(2);
        rig.triangles.push([0, 1, 9]);
        assert!(rig_glb(&rig).unwrap_err().to_string().contains("triangle 2"));
    }
}
