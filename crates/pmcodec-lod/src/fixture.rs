//! A small deterministic rig built in code, for tests, demos and the validator run in
//! `tests/run-all.sh` (see the `write_fixture` example): a skinned tube bent by an animation
//! and a morph-target grid driven by a weights animation.

use glam::{Mat4, Quat, Vec3};
use pmcodec_mesh::SourceVertex;
use pmcodec_mesh::gltf_input::{
    AnimatedProperty, Animation, Channel, Interpolation, MeshInstance, NodeTransform, PrimitiveRef, RiggedMesh, Skin,
};

/// A closed tube along +y (rings of `around` vertices, capped), skinned to two joints that
/// blend over the middle, with an animation bending the upper joint by 90 degrees; plus a
/// morph-target grid on its own node with one target (a bump) driven by a weights animation.
pub fn bending_tube_and_face(rings: usize, around: usize) -> RiggedMesh {
    let (rings, around) = (rings.max(2), around.max(3));
    // Nodes: 0 root joint, 1 upper joint (child of 0, at y = 1), 2 skinned mesh node, 3 face node.
    let mut rig = RiggedMesh {
        nodes: vec![
            NodeTransform::default(),
            NodeTransform { translation: Vec3::new(0.0, 1.0, 0.0), ..Default::default() },
            NodeTransform::default(),
            NodeTransform { translation: Vec3::new(3.0, 0.0, 0.0), ..Default::default() },
        ],
        parents: vec![None, Some(0), None, None],
        skins: vec![Skin {
            joints: vec![0, 1],
            inverse_bind_matrices: vec![Mat4::IDENTITY, Mat4::from_translation(Vec3::new(0.0, -1.0, 0.0))],
        }],
        ..Default::default()
    };
    // Tube: y from 0 to 2.
    for r in 0..rings {
        let y = 2.0 * r as f32 / (rings - 1) as f32;
        let upper = ((y - 0.7) / 0.6).clamp(0.0, 1.0);
        for a in 0..around {
            let phi = std::f32::consts::TAU * a as f32 / around as f32;
            rig.positions.push(Vec3::new(0.3 * phi.cos(), y, 0.3 * phi.sin()));
            rig.joints.push([0, 1, 0, 0]);
            rig.weights.push([1.0 - upper, upper, 0.0, 0.0]);
        }
    }
    let bottom = rig.positions.len() as u32;
    rig.positions.push(Vec3::ZERO);
    rig.joints.push([0, 0, 0, 0]);
    rig.weights.push([1.0, 0.0, 0.0, 0.0]);
    let top = rig.positions.len() as u32;
    rig.positions.push(Vec3::new(0.0, 2.0, 0.0));
    rig.joints.push([1, 0, 0, 0]);
    rig.weights.push([1.0, 0.0, 0.0, 0.0]);
    let at = |r: usize, a: usize| (r * around + a % around) as u32;
    for r in 0..rings - 1 {
        for a in 0..around {
            rig.triangles.push([at(r, a), at(r + 1, a), at(r, a + 1)]);
            rig.triangles.push([at(r, a + 1), at(r + 1, a), at(r + 1, a + 1)]);
        }
    }
    for a in 0..around {
        rig.triangles.push([bottom, at(0, a), at(0, a + 1)]);
        rig.triangles.push([top, at(rings - 1, a + 1), at(rings - 1, a)]);
    }
    let tube_end = rig.positions.len();
    rig.instances.push(MeshInstance {
        node: 2,
        mesh: 0,
        skin: Some(0),
        vertices: 0..tube_end,
        morph_targets: Vec::new(),
        default_weights: Vec::new(),
    });
    // Face: an n x n grid in the xy plane with a bump target in the middle.
    let n = 12;
    let mut bump = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 / (n - 1) as f32, j as f32 / (n - 1) as f32);
            rig.positions.push(Vec3::new(x, y, 0.0));
            rig.joints.push([0; 4]);
            rig.weights.push([0.0; 4]);
            let d = ((x - 0.5).powi(2) + (y - 0.5).powi(2)).sqrt();
            bump.push(Vec3::new(0.0, 0.0, 0.3 * (1.0 - d / 0.3).max(0.0)));
        }
    }
    let g = |i: usize, j: usize| (tube_end + j * n + i) as u32;
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            rig.triangles.push([g(i, j), g(i + 1, j), g(i, j + 1)]);
            rig.triangles.push([g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)]);
        }
    }
    rig.instances.push(MeshInstance {
        node: 3,
        mesh: 1,
        skin: None,
        vertices: tube_end..rig.positions.len(),
        morph_targets: vec![bump],
        default_weights: vec![0.0],
    });
    rig.source = (0..rig.positions.len() as u32).map(|i| SourceVertex { primitive: 0, index: i }).collect();
    rig.primitives = vec![PrimitiveRef { node: 2, mesh: 0, primitive: 0 }, PrimitiveRef { node: 3, mesh: 1, primitive: 0 }];
    let bend = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
    rig.animations = vec![Animation {
        index: 0,
        name: Some("bend".into()),
        duration: 1.0,
        channels: vec![
            Channel {
                node: 1,
                property: AnimatedProperty::Rotation,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 1.0],
                values: [Quat::IDENTITY.to_array(), bend.to_array()].concat(),
                width: 4,
            },
            Channel {
                node: 3,
                property: AnimatedProperty::MorphWeights,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 1.0],
                values: vec![0.0, 1.0],
                width: 1,
            },
        ],
    }];
    rig
}
