//! A generated skinned character: many separate parts (capped tubes) hung on one skeleton of
//! limb chains, with one long animation. Issue 17's encode-cost bar is about a character of
//! 34,159 vertices in 59 meshes with one skeleton and 35 s of animation; this writes one of
//! that shape from code, at any size, so the cost can be measured and tested without a
//! third-party file. Deterministic: the same options give the same bytes.

use crate::MeshError;
use crate::glb::{ARRAY_BUFFER, GlbBuilder, TRIANGLES};
use glam::{Mat4, Quat, Vec3};
use serde_json::{Value, json};
use std::f32::consts::TAU;

/// The shape of a generated character.
#[derive(Clone, Debug, PartialEq)]
pub struct CharacterOptions {
    /// Separate meshes (each one node with the shared skin).
    pub parts: u32,
    /// Limb chains radiating from the root joint.
    pub limbs: u32,
    /// Bones per limb chain.
    pub chain: u32,
    /// Vertices around each tube.
    pub segments: u32,
    /// Rings along each tube (each part has `segments * rings + 2` vertices).
    pub rings: u32,
    /// Length of the animation in seconds.
    pub seconds: f32,
    /// Keyframes per second of the animation (LINEAR interpolation between them).
    pub keys_per_second: f32,
    /// Varies the proportions and the motion.
    pub seed: u64,
}

impl Default for CharacterOptions {
    /// Issue 17's character: 59 parts of 578 vertices (34,102 vertices), 8 limbs of 7 bones
    /// (57 joints), 35 s.
    fn default() -> Self {
        CharacterOptions { parts: 59, limbs: 8, chain: 7, segments: 24, rings: 24, seconds: 35.0, keys_per_second: 10.0, seed: 17 }
    }
}

/// A small deterministic generator (64-bit LCG, Knuth's MMIX constants).
struct Lcg(u64);

impl Lcg {
    /// Uniform in [0, 1).
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

/// One joint of the skeleton: parent, rest translation in the parent's space (joints have no
/// rest rotation, so bind space is world space translated), and its motion.
struct Joint {
    parent: Option<usize>,
    offset: Vec3,
    /// Swing axis, amplitude (radians), frequency (Hz) and phase of its rotation.
    axis: Vec3,
    amplitude: f32,
    frequency: f32,
    phase: f32,
}

/// The character as a GLB. Errors only on options out of range (no parts, no limbs, fewer than
/// 3 segments or 2 rings, a duration or key rate that is not a positive number).
pub fn skinned_character(opts: &CharacterOptions) -> Result<Vec<u8>, MeshError> {
    let bad = |m: &str| Err(MeshError::Invalid(format!("generated character: {m}")));
    if opts.parts == 0 || opts.limbs == 0 || opts.chain == 0 || opts.segments < 3 || opts.rings < 2 {
        return bad("use at least one part, limb and bone, 3 segments and 2 rings");
    }
    if !(opts.seconds.is_finite() && opts.seconds > 0.0 && opts.keys_per_second.is_finite() && opts.keys_per_second > 0.0) {
        return bad("use a positive duration and key rate");
    }
    if (opts.segments as u64 * opts.rings as u64 + 2) * opts.parts as u64 > 1 << 24 || opts.limbs as u64 * opts.chain as u64 > 4096 {
        return bad("too large");
    }
    let mut rng = Lcg(opts.seed ^ 0x9E37_79B9_7F4A_7C15);
    let joints = skeleton(opts, &mut rng);
    // Rest world positions (joints carry no rest rotation).
    let mut world = vec![Vec3::ZERO; joints.len()];
    for (j, joint) in joints.iter().enumerate() {
        world[j] = joint.parent.map_or(Vec3::ZERO, |p| world[p]) + joint.offset;
    }
    let bones: Vec<usize> = (1..joints.len()).collect();
    let mut b = GlbBuilder::default();
    let mut meshes = Vec::new();
    let mut nodes: Vec<Value> = Vec::new();
    // Joint nodes first (node j is joint j), then one node per part.
    for (j, joint) in joints.iter().enumerate() {
        let children: Vec<usize> = (0..joints.len()).filter(|&c| joints[c].parent == Some(j)).collect();
        let mut node = json!({"name": format!("joint {j}"), "translation": joint.offset.to_array()});
        if !children.is_empty() {
            node["children"] = json!(children);
        }
        nodes.push(node);
    }
    for p in 0..opts.parts as usize {
        // Parts beyond one per bone go round again, beside the first ones (armour plates).
        let bone = bones[p % bones.len()];
        let round = (p / bones.len()) as f32;
        let joint = &joints[bone];
        let parent = joint.parent.unwrap_or(0);
        let child = (0..joints.len()).find(|&c| joints[c].parent == Some(bone));
        let start = world[bone];
        let end = child.map_or(start + joint.offset * 0.8, |c| world[c]);
        let radius = rng.range(0.05, 0.12) * (1.0 - 0.3 * round.min(2.0));
        let side = if round > 0.0 { joint.axis * (radius * 2.5 * round) } else { Vec3::ZERO };
        let part = tube(opts, (start + side, end + side), radius, [parent, bone, child.unwrap_or(bone)]);
        let position = b.vec3s(&part.positions, Some(ARRAY_BUFFER), true);
        let joints_acc = b.joints(&part.joints);
        let weights: Vec<f32> = part.weights.iter().flatten().copied().collect();
        let weights_acc = b.floats(&weights, Some(ARRAY_BUFFER), "VEC4", 4, false);
        let flat: Vec<u32> = part.triangles.iter().flatten().copied().collect();
        let indices = b.indices(&flat, part.positions.len());
        meshes.push(json!({"name": format!("part {p}"), "primitives": [{
            "attributes": {"POSITION": position, "JOINTS_0": joints_acc, "WEIGHTS_0": weights_acc},
            "indices": indices,
            "mode": TRIANGLES,
        }]}));
        nodes.push(json!({"name": format!("part {p}"), "mesh": p, "skin": 0}));
    }
    let ibm: Vec<f32> = world.iter().flat_map(|&w| Mat4::from_translation(-w).to_cols_array()).collect();
    let ibm_acc = b.floats(&ibm, None, "MAT4", 16, false);

    // The animation: every joint swings about its axis, its amplitude breathing slowly so that
    // the motion changes over the whole clip (as clips played back to back do); the root walks
    // a circle and turns with it.
    let keys = (opts.seconds * opts.keys_per_second).ceil() as usize + 1;
    let times: Vec<f32> = (0..keys).map(|k| (k as f32 / opts.keys_per_second).min(opts.seconds)).collect();
    let input = b.floats(&times, None, "SCALAR", 1, true);
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    for (j, joint) in joints.iter().enumerate() {
        let mut rotations = Vec::with_capacity(keys * 4);
        for &t in &times {
            let envelope = 0.6 + 0.4 * (TAU * t / 11.0 + joint.phase).sin();
            let angle = joint.amplitude * envelope * (TAU * joint.frequency * t + joint.phase).sin();
            let turn = if j == 0 { Quat::from_rotation_y(TAU * t / 20.0) } else { Quat::IDENTITY };
            rotations.extend((turn * Quat::from_axis_angle(joint.axis, angle)).to_array());
        }
        samplers.push(json!({"input": input, "output": b.floats(&rotations, None, "VEC4", 4, false), "interpolation": "LINEAR"}));
        channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": j, "path": "rotation"}}));
    }
    let walk: Vec<f32> = times
        .iter()
        .flat_map(|&t| [2.0 * (TAU * t / 20.0).sin(), 0.1 * (TAU * t * 1.5).sin().abs(), 2.0 * (TAU * t / 20.0).cos()])
        .collect();
    samplers.push(json!({"input": input, "output": b.floats(&walk, None, "VEC3", 3, false), "interpolation": "LINEAR"}));
    channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": 0, "path": "translation"}}));

    let part_nodes: Vec<usize> = (joints.len()..joints.len() + opts.parts as usize).collect();
    let mut scene_nodes = vec![0];
    scene_nodes.extend(&part_nodes);
    let root = json!({
        "asset": {"version": "2.0", "generator": "pmcodec samples::skinned_character"},
        "scene": 0,
        "scenes": [{"nodes": scene_nodes}],
        "nodes": nodes,
        "meshes": meshes,
        "skins": [{"joints": (0..joints.len()).collect::<Vec<_>>(), "skeleton": 0, "inverseBindMatrices": ibm_acc}],
        "animations": [{"name": "generated", "samplers": samplers, "channels": channels}],
    });
    b.finish(root)
}

/// Joint 0 at the origin, then `limbs` chains of `chain` joints each, fanning out from it.
fn skeleton(opts: &CharacterOptions, rng: &mut Lcg) -> Vec<Joint> {
    let mut joints = vec![Joint { parent: None, offset: Vec3::ZERO, axis: Vec3::Y, amplitude: 0.15, frequency: 0.3, phase: 0.0 }];
    for l in 0..opts.limbs {
        // Directions spread over the sphere (a golden-angle spiral), each chain bending a little.
        let y = 1.0 - 2.0 * (l as f32 + 0.5) / opts.limbs as f32;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let a = l as f32 * 2.399_963;
        let mut dir = Vec3::new(r * a.cos(), y, r * a.sin()).normalize_or(Vec3::Y);
        let mut parent = 0;
        for _ in 0..opts.chain {
            let length = rng.range(0.2, 0.4);
            let axis = dir.any_orthonormal_vector();
            let axis = Quat::from_axis_angle(dir, rng.range(0.0, TAU)) * axis;
            joints.push(Joint {
                parent: Some(parent),
                offset: dir * length,
                axis,
                amplitude: rng.range(0.2, 0.7),
                frequency: rng.range(0.2, 1.2),
                phase: rng.range(0.0, TAU),
            });
            parent = joints.len() - 1;
            dir = (dir + 0.3 * Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0))).normalize_or(dir);
        }
    }
    joints
}

struct Part {
    positions: Vec<Vec3>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    triangles: Vec<[u32; 3]>,
}

/// A capped tube from `ends.0` to `ends.1`, skinned to its bone (`[parent, bone, child]`'s
/// middle), blending into the parent joint over its first third and into the child over its
/// last, as a limb's skin does at the elbow.
fn tube(opts: &CharacterOptions, (a, b): (Vec3, Vec3), radius: f32, [parent, bone, child]: [usize; 3]) -> Part {
    let (s, r) = (opts.segments as usize, opts.rings as usize);
    let axis = (b - a).normalize_or(Vec3::Y);
    let u = axis.any_orthonormal_vector();
    let v = axis.cross(u);
    let mut part = Part { positions: Vec::new(), joints: Vec::new(), weights: Vec::new(), triangles: Vec::new() };
    let influences = |t: f32| -> ([u16; 4], [f32; 4]) {
        let to_parent = (0.5 * (1.0 - t / 0.33)).max(0.0);
        let to_child = (0.5 * ((t - 0.67) / 0.33)).max(0.0);
        let own = 1.0 - to_parent - to_child;
        ([bone as u16, parent as u16, child as u16, 0], [own, to_parent, to_child, 0.0])
    };
    for i in 0..r {
        let t = i as f32 / (r - 1) as f32;
        // Bulging like a muscle.
        let rad = radius * (1.0 + 0.3 * (t * std::f32::consts::PI).sin());
        let (joints, weights) = influences(t);
        for k in 0..s {
            let phi = TAU * k as f32 / s as f32;
            part.positions.push(a + (b - a) * t + (u * phi.cos() + v * phi.sin()) * rad);
            part.joints.push(joints);
            part.weights.push(weights);
        }
    }
    let ring = |i: usize, k: usize| (i * s + k % s) as u32;
    for i in 0..r - 1 {
        for k in 0..s {
            part.triangles.push([ring(i, k), ring(i, k + 1), ring(i + 1, k + 1)]);
            part.triangles.push([ring(i, k), ring(i + 1, k + 1), ring(i + 1, k)]);
        }
    }
    // Caps: a centre vertex at each end.
    for (end, at, i, flip) in [(0.0f32, a, 0, true), (1.0, b, r - 1, false)] {
        let c = part.positions.len() as u32;
        let (joints, weights) = influences(end);
        part.positions.push(at);
        part.joints.push(joints);
        part.weights.push(weights);
        for k in 0..s {
            let (p, q) = (ring(i, k), ring(i, k + 1));
            part.triangles.push(if flip { [c, q, p] } else { [c, p, q] });
        }
    }
    part
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> CharacterOptions {
        CharacterOptions { parts: 5, limbs: 2, chain: 2, segments: 6, rings: 4, seconds: 2.0, keys_per_second: 4.0, seed: 3 }
    }

    #[test]
    fn same_options_same_bytes_and_it_reads_back_skinned() {
        let a = skinned_character(&small()).unwrap();
        assert_eq!(a, skinned_character(&small()).unwrap());
        assert_ne!(a, skinned_character(&CharacterOptions { seed: 4, ..small() }).unwrap());
        let rig = crate::gltf_input::RiggedMesh::from_bytes(&a).unwrap();
        assert_eq!(rig.instances.len(), 5);
        assert!(rig.instances.iter().all(|i| i.skin == Some(0)));
        assert_eq!(rig.vertex_count(), 5 * (6 * 4 + 2));
        assert!((rig.animations[0].duration - 2.0).abs() < 1e-6);
        // It moves: the last frame differs from the first.
        let anim = &rig.animations[0];
        assert_ne!(rig.pose(Some(anim), 0.0), rig.pose(Some(anim), 1.7));
    }

    #[test]
    fn options_out_of_range_are_refused() {
        assert!(skinned_character(&CharacterOptions { parts: 0, ..small() }).is_err());
        assert!(skinned_character(&CharacterOptions { seconds: f32::NAN, ..small() }).is_err());
        assert!(skinned_character(&CharacterOptions { segments: 2, ..small() }).is_err());
    }
}
