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

/// What [`multi_part_character`] builds.
#[derive(Clone, Copy, Debug)]
pub struct CharacterSpec {
    /// Seeds every choice: one seed, one character.
    pub seed: u64,
    /// Disconnected parts (before some are attached to others, see `touching`).
    pub parts: usize,
    /// Meshes sharing the skeleton's skin; the parts are dealt among them.
    pub meshes: usize,
    /// Split half of the parts into strips whose copies of the seam vertices carry slightly
    /// different weights, so welding keeps them apart (open seams, many boundary vertices).
    pub unwelded: bool,
    /// Attach about a third of the parts to the part before by a shared vertex (a pinch) or a
    /// shared edge (a fin: three triangles on one edge), as hair cards and buttons are.
    pub touching: bool,
    /// Give the last mesh a morph target driven by the animation (a class of its own).
    pub morph: bool,
}

impl Default for CharacterSpec {
    fn default() -> Self {
        CharacterSpec { seed: 1, parts: 60, meshes: 6, unwelded: true, touching: true, morph: false }
    }
}

/// The fixture's random choices, from the workspace's one deterministic generator
/// ([`pmcodec_eval::SplitMix64`]): the same seed gives the same character on every platform.
struct Rng(pmcodec_eval::SplitMix64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `lo..=hi`.
    fn range(&mut self, lo: usize, hi: usize) -> usize {
        lo + (self.next() % (hi - lo + 1) as u64) as usize
    }

    /// Uniform in `[lo, hi)`.
    fn float(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next() >> 40) as f32 / (1u64 << 24) as f32)
    }
}

/// One part in its own unit box: positions and triangles.
struct Part {
    pos: Vec<Vec3>,
    tris: Vec<[u32; 3]>,
}

/// An open `nx` x `ny` grid in the xy plane (vertex 0 and 1 share a boundary edge).
fn grid(nx: usize, ny: usize) -> Part {
    let mut pos = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            pos.push(Vec3::new(i as f32 / nx as f32 - 0.5, j as f32 / ny as f32 - 0.5, 0.0));
        }
    }
    let at = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut tris = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            tris.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
            tris.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Part { pos, tris }
}

/// A closed, capped tube along y.
fn tube(around: usize, rings: usize) -> Part {
    let mut pos = Vec::new();
    for r in 0..rings {
        for a in 0..around {
            let phi = std::f32::consts::TAU * a as f32 / around as f32;
            pos.push(Vec3::new(0.3 * phi.cos(), r as f32 / (rings - 1) as f32 - 0.5, 0.3 * phi.sin()));
        }
    }
    let (bottom, top) = (pos.len() as u32, pos.len() as u32 + 1);
    pos.extend([Vec3::new(0.0, -0.5, 0.0), Vec3::new(0.0, 0.5, 0.0)]);
    let at = |r: usize, a: usize| (r * around + a % around) as u32;
    let mut tris = Vec::new();
    for r in 0..rings - 1 {
        for a in 0..around {
            tris.push([at(r, a), at(r + 1, a), at(r, a + 1)]);
            tris.push([at(r, a + 1), at(r + 1, a), at(r + 1, a + 1)]);
        }
    }
    for a in 0..around {
        tris.push([bottom, at(0, a), at(0, a + 1)]);
        tris.push([top, at(rings - 1, a + 1), at(rings - 1, a)]);
    }
    Part { pos, tris }
}

/// A disc: a centre and `k` rim vertices (every rim vertex on the boundary, the centre not).
fn fan(k: usize) -> Part {
    let mut pos = vec![Vec3::ZERO];
    for a in 0..k {
        let phi = std::f32::consts::TAU * a as f32 / k as f32;
        pos.push(Vec3::new(0.5 * phi.cos(), 0.5 * phi.sin(), 0.0));
    }
    let tris = (0..k).map(|a| [0, 1 + a as u32, 1 + ((a + 1) % k) as u32]).collect();
    Part { pos, tris }
}

/// A closed box, `n` quads per edge on every face, welded along its edges.
fn cube(n: usize) -> Part {
    let mut part = Part { pos: Vec::new(), tris: Vec::new() };
    let mut index: std::collections::HashMap<[i32; 3], u32> = std::collections::HashMap::new();
    // Each face: a normal axis, its sign, and the two in-plane axes in counter-clockwise order.
    for (axis, sign) in [(0, 1.0f32), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)] {
        let (u, v) = if sign > 0.0 { ((axis + 1) % 3, (axis + 2) % 3) } else { ((axis + 2) % 3, (axis + 1) % 3) };
        let mut id = |i: usize, j: usize| {
            let mut key = [0i32; 3];
            key[axis] = if sign > 0.0 { n as i32 } else { 0 };
            key[u] = i as i32;
            key[v] = j as i32;
            *index.entry(key).or_insert_with(|| {
                part.pos.push(Vec3::from_array(key.map(|x| x as f32 / n as f32 - 0.5)));
                part.pos.len() as u32 - 1
            })
        };
        let mut face = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                face.push([a, b, c]);
                face.push([a, c, d]);
            }
        }
        part.tris.extend(face);
    }
    part
}

/// A skinned character made of many small disconnected parts, like the Khronos sample
/// characters (BrainStem: 59 meshes on one 18-joint skeleton): an 18-joint humanoid skeleton,
/// `spec.parts` parts of one to about fifty triangles each (grids, capped tubes, discs, boxes,
/// single triangles and quads), each near a joint and skinned to it and its parent, dealt among
/// `spec.meshes` meshes that share one skin, and a "walk" animation swinging the limbs. The
/// same spec always gives the same character. Positions are rest (bind) space; call
/// [`RiggedMesh::weld`] before making LODs, as `pmcodec lod` does.
pub fn multi_part_character(spec: &CharacterSpec) -> RiggedMesh {
    let mut rng = Rng(pmcodec_eval::SplitMix64::new(spec.seed));
    let meshes = spec.meshes.max(1);
    let (parents, offsets) = humanoid_skeleton();
    let joint_count = parents.len();
    let mut world = vec![Vec3::ZERO; joint_count];
    for j in 0..joint_count {
        world[j] = parents[j].map_or(Vec3::ZERO, |p| world[p]) + offsets[j];
    }
    let mut rig = RiggedMesh {
        nodes: offsets.iter().map(|&t| NodeTransform { translation: t, ..Default::default() }).collect(),
        parents: parents.clone(),
        skins: vec![Skin {
            joints: (0..joint_count).collect(),
            inverse_bind_matrices: world.iter().map(|&w| Mat4::from_translation(-w)).collect(),
        }],
        ..Default::default()
    };
    // Per mesh: positions, joints, weights, triangles (local indices).
    type Buffers = (Vec<Vec3>, Vec<[u16; 4]>, Vec<[f32; 4]>, Vec<[u32; 3]>);
    let mut bufs: Vec<Buffers> = vec![Default::default(); meshes];
    for p in 0..spec.parts {
        let m = p % meshes;
        let part = match rng.range(0, 6) {
            0 => grid(rng.range(1, 5), rng.range(1, 4)),
            1 => tube(rng.range(3, 6), rng.range(2, 4)),
            2 => fan(rng.range(3, 12)),
            3 => cube(rng.range(1, 2)),
            4 => grid(1, 1),
            5 => Part { pos: vec![Vec3::ZERO, Vec3::X * 0.5, Vec3::Y * 0.5], tris: vec![[0, 1, 2]] },
            _ => grid(rng.range(2, 6), 1),
        };
        let joint = rng.range(1, joint_count - 1);
        let parent = parents[joint].unwrap_or(0);
        let scale = rng.float(0.03, 0.12);
        let centre = world[joint] + Vec3::new(rng.float(-0.1, 0.1), rng.float(-0.1, 0.1), rng.float(-0.1, 0.1));
        let turn = Quat::from_euler(glam::EulerRot::XYZ, rng.float(0.0, 3.0), rng.float(0.0, 3.0), rng.float(0.0, 3.0));
        let rigid = rng.range(0, 3) == 0;
        let mut pos: Vec<Vec3> = part.pos.iter().map(|&q| centre + turn * (q * scale)).collect();
        let mut skin: Vec<([u16; 4], [f32; 4])> = part
            .pos
            .iter()
            .map(|q| {
                let a = if rigid { 1.0 } else { (0.5 + q.y).clamp(0.0, 1.0) };
                ([joint as u16, parent as u16, 0, 0], [a, 1.0 - a, 0.0, 0.0])
            })
            .collect();
        let (bp, bj, bw, bt) = &mut bufs[m];
        // Attach to the part before in this mesh: its last triangle's first corner (a pinch)
        // or first edge (a fin), copied exactly so that welding joins them.
        if spec.touching && !bt.is_empty() && rng.range(0, 2) == 0 {
            let last = bt[bt.len() - 1];
            let shared = if rng.range(0, 1) == 0 { 1 } else { 2 };
            for k in 0..shared.min(pos.len()) {
                let v = last[k] as usize;
                pos[k] = bp[v];
                skin[k] = (bj[v], bw[v]);
            }
        }
        let mut tris = part.tris.clone();
        // Unwelded: runs of three triangles get their own copies of their corners, the copies
        // after the first run with weights moved by a little, so welding cannot join them.
        if spec.unwelded && p % 2 == 1 {
            (pos, skin) = split_runs(&mut tris, &pos, &skin);
        }
        let base = bp.len() as u32;
        bp.extend(&pos);
        bj.extend(skin.iter().map(|s| s.0));
        bw.extend(skin.iter().map(|s| s.1));
        bt.extend(tris.iter().map(|t| t.map(|c| c + base)));
    }
    // One node per mesh (after the joints), and the optional morph target on the last mesh.
    let mut morph_node = None;
    for (m, (bp, bj, bw, bt)) in bufs.into_iter().enumerate() {
        if bt.is_empty() {
            continue;
        }
        let node = rig.nodes.len();
        rig.nodes.push(NodeTransform::default());
        rig.parents.push(None);
        let start = rig.positions.len();
        let morph = spec.morph && m == meshes - 1;
        let targets = if morph { vec![bp.iter().map(|p| Vec3::new(0.0, 0.0, 0.05 * (p.y * 9.0).sin())).collect()] } else { Vec::new() };
        if morph {
            morph_node = Some(node);
        }
        rig.triangles.extend(bt.iter().map(|t| t.map(|c| c + start as u32)));
        rig.source.extend((0..bp.len() as u32).map(|index| SourceVertex { primitive: rig.primitives.len() as u32, index }));
        rig.positions.extend(bp);
        rig.joints.extend(bj);
        rig.weights.extend(bw);
        rig.primitives.push(PrimitiveRef { node, mesh: m, primitive: 0 });
        let default_weights = if morph { vec![0.0] } else { Vec::new() };
        rig.instances.push(MeshInstance {
            node,
            mesh: m,
            skin: Some(0),
            vertices: start..rig.positions.len(),
            morph_targets: targets,
            default_weights,
        });
    }
    rig.animations = vec![walk(morph_node)];
    rig
}

/// The character's skeleton: hips, spine (3), neck, head, two arms and two legs of three joints
/// each, as each joint's parent and its offset from it.
fn humanoid_skeleton() -> (Vec<Option<usize>>, [Vec3; 18]) {
    let parents: Vec<Option<usize>> = vec![
        None,
        Some(0),
        Some(1),
        Some(2),
        Some(3),
        Some(4),
        Some(3),
        Some(6),
        Some(7),
        Some(3),
        Some(9),
        Some(10),
        Some(0),
        Some(12),
        Some(13),
        Some(0),
        Some(15),
        Some(16),
    ];
    let offsets = [
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.15, 0.0),
        Vec3::new(0.0, 0.15, 0.0),
        Vec3::new(0.0, 0.15, 0.0),
        Vec3::new(0.0, 0.12, 0.0),
        Vec3::new(0.0, 0.1, 0.0),
        Vec3::new(0.15, 0.0, 0.0),
        Vec3::new(0.25, 0.0, 0.0),
        Vec3::new(0.25, 0.0, 0.0),
        Vec3::new(-0.15, 0.0, 0.0),
        Vec3::new(-0.25, 0.0, 0.0),
        Vec3::new(-0.25, 0.0, 0.0),
        Vec3::new(0.1, -0.05, 0.0),
        Vec3::new(0.0, -0.45, 0.0),
        Vec3::new(0.0, -0.45, 0.0),
        Vec3::new(-0.1, -0.05, 0.0),
        Vec3::new(0.0, -0.45, 0.0),
        Vec3::new(0.0, -0.45, 0.0),
    ];
    (parents, offsets)
}

/// A vertex's four joints and their weights.
type Influences = ([u16; 4], [f32; 4]);

/// Gives each run of three triangles its own copies of their corners, the copies after the
/// first run with weights moved by a little, so that welding cannot join them.
fn split_runs(tris: &mut [[u32; 3]], pos: &[Vec3], skin: &[Influences]) -> (Vec<Vec3>, Vec<Influences>) {
    let mut split_pos = Vec::new();
    let mut split_skin = Vec::new();
    for (run, chunk) in tris.chunks_mut(3).enumerate() {
        let mut local: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
        for c in chunk.iter_mut().flatten() {
            *c = *local.entry(*c).or_insert_with(|| {
                let (j, mut w) = skin[*c as usize];
                if run > 0 {
                    let e = 1e-3 * run as f32;
                    w = if w[0] > 0.5 { [w[0] - e, w[1] + e, 0.0, 0.0] } else { [w[0] + e, w[1] - e, 0.0, 0.0] };
                }
                split_pos.push(pos[*c as usize]);
                split_skin.push((j, w));
                split_pos.len() as u32 - 1
            });
        }
    }
    (split_pos, split_skin)
}

/// The character's "walk": arms and legs swing, the spine twists, over one second; the morph
/// target's weight (on `morph_node`, if any) goes from 0 to 1.
fn walk(morph_node: Option<usize>) -> Animation {
    let swing = |angle: f32, axis: Vec3| {
        [Quat::IDENTITY, Quat::from_axis_angle(axis, angle), Quat::IDENTITY, Quat::from_axis_angle(axis, -angle), Quat::IDENTITY]
            .iter()
            .flat_map(|q| q.to_array())
            .collect::<Vec<f32>>()
    };
    let times = vec![0.0, 0.25, 0.5, 0.75, 1.0];
    let mut channels: Vec<Channel> =
        [(6, 1.0, Vec3::Z), (9, -1.0, Vec3::Z), (12, 0.8, Vec3::X), (15, -0.8, Vec3::X), (13, 0.6, Vec3::X), (2, 0.3, Vec3::Y)]
            .into_iter()
            .map(|(node, angle, axis)| Channel {
                node,
                property: AnimatedProperty::Rotation,
                interpolation: Interpolation::Linear,
                times: times.clone(),
                values: swing(angle, axis),
                width: 4,
            })
            .collect();
    if let Some(node) = morph_node {
        channels.push(Channel {
            node,
            property: AnimatedProperty::MorphWeights,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![0.0, 1.0],
            width: 1,
        });
    }
    Animation { index: 0, name: Some("walk".into()), duration: 1.0, channels }
}
