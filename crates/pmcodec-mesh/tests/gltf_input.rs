//! glTF input on the real skinned and morph-target files, and on small files generated here that
//! pin down interpolation, skinning, morphing, welding, topology conversion and error reporting.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_mesh::gltf_input::{
    AnimationSelector, GltfOptions, RiggedMesh, list_animations, list_animations_bytes, load_gltf, load_gltf_bytes,
};
use pmcodec_mesh::{MeshError, Sequence};
use serde_json::json;
use std::collections::BTreeSet;

use crate::common;
use common::{Bin, TRIANGLE, animated_triangle, bent_strip, data, load, opts};

// ------------------------------------------------------------------------------------------------
// Helpers
// ------------------------------------------------------------------------------------------------

fn diag(points: &[Vec3]) -> f32 {
    let (lo, hi) = pmcodec_mesh::bounds_of(points).expect("points");
    (hi - lo).length()
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).length() <= tol
}

/// Number of connected pieces of the surface (vertices joined by triangle edges).
fn components(vertex_count: usize, triangles: &[[u32; 3]]) -> usize {
    let mut parent: Vec<usize> = (0..vertex_count).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for t in triangles {
        let a = find(&mut parent, t[0] as usize);
        for &c in &t[1..] {
            let b = find(&mut parent, c as usize);
            parent[b] = a;
        }
    }
    let used: BTreeSet<u32> = triangles.iter().flatten().copied().collect();
    used.iter().map(|&v| find(&mut parent, v as usize)).collect::<BTreeSet<_>>().len()
}

/// Checks every frame of an animated sequence: finite, of a plausible size (a broken skinning
/// transform blows the mesh up or collapses it), and actually moving.
fn check_animated(seq: &Sequence, rest_diag: f32) {
    seq.validate().expect("valid");
    for (f, frame) in seq.frames.iter().enumerate() {
        assert!(frame.iter().all(|p| p.is_finite()), "frame {f}");
        let d = diag(frame);
        assert!(d < 3.0 * rest_diag && d > rest_diag / 3.0, "frame {f}: diagonal {d} vs rest {rest_diag}");
    }
    let moved = |a: &[Vec3], b: &[Vec3]| a.iter().zip(b).filter(|(p, q)| (**p - **q).length() > 1e-3 * rest_diag).count();
    let n = seq.frame_count();
    assert!(n >= 2);
    let m = moved(&seq.frames[0], &seq.frames[n / 2]);
    assert!(m > seq.vertex_count() / 20, "only {m} of {} vertices move", seq.vertex_count());
    let distinct = seq.frames.windows(2).filter(|w| w[0] != w[1]).count();
    assert!(distinct * 2 >= n - 1, "only {distinct} of {} consecutive frame pairs differ", n - 1);
    assert_eq!(seq.source.len(), seq.vertex_count());
    assert_eq!(seq.frame_names.len(), n);
}

fn triangle_x(path_values: &[f32], interpolation: &str, times: &[f32], fps: f32) -> Vec<f32> {
    let (bin, doc) = animated_triangle("translation", interpolation, times, path_values);
    let seq = load(&bin.glb(doc), fps).unwrap();
    // Vertex 0 sits at the origin, so it shows the node's translation.
    seq.frames.iter().map(|f| f[0].x).collect()
}

// ------------------------------------------------------------------------------------------------
// Real files
// ------------------------------------------------------------------------------------------------

#[test]
fn fox_is_welded_into_one_connected_skinned_surface() {
    let path = data("Fox.glb");
    let anims = list_animations(&path).unwrap();
    let names: Vec<&str> = anims.iter().map(|a| a.name.as_deref().unwrap()).collect();
    assert_eq!(names, ["Run", "Survey", "Walk"]);

    let rig = RiggedMesh::from_path(&path).unwrap();
    assert_eq!(rig.vertex_count(), 1728, "every triangle has its own corners before welding");
    assert_eq!(rig.skins.len(), 1);
    assert_eq!(rig.skins[0].joints.len(), 24);
    assert_eq!(rig.instances.len(), 1);
    for w in &rig.weights {
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{w:?}");
    }
    assert!(components(1728, &rig.triangles) > 100, "unwelded, the fox is in pieces");

    let seq = load_gltf(&path, &GltfOptions::default()).unwrap();
    assert_eq!(seq.triangles.len(), 576);
    assert!(seq.vertex_count() < 1728 / 2, "welded to {} vertices", seq.vertex_count());
    assert_eq!(components(seq.vertex_count(), &seq.triangles), 1, "welded, the fox is one piece");
    // The default is the first animation, Run.
    assert_eq!(seq.frame_count(), (anims[0].duration * 30.0).floor() as usize + 1);
    assert!(seq.frame_names[0].starts_with("Run@0.000s"), "{}", seq.frame_names[0]);
    assert!(seq.morph_displacement.is_empty(), "skinned only: no morph weights");
    // The source map leads back to the authored vertex.
    let mut welded = rig.clone();
    welded.weld();
    assert_eq!(welded.vertex_count(), seq.vertex_count());
    assert_eq!(welded.source, seq.source);
    for (v, s) in welded.source.iter().enumerate() {
        assert_eq!(s.primitive, 0);
        assert_eq!(welded.positions[v], rig.positions[s.index as usize]);
        assert_eq!(welded.joints[v], rig.joints[s.index as usize]);
    }
    let rest = diag(&rig.pose(None, 0.0));
    check_animated(&seq, rest);

    // Every animation, by name and by index.
    for (i, a) in anims.iter().enumerate() {
        let name = a.name.clone().unwrap();
        let by_name = load_gltf(&path, &opts(Some(AnimationSelector::Name(name.clone())), 30.0, true)).unwrap();
        let by_index = load_gltf(&path, &opts(Some(AnimationSelector::Index(i)), 30.0, true)).unwrap();
        assert_eq!(by_name.frames, by_index.frames, "{name}");
        assert_eq!(by_name.frame_count(), (a.duration * 30.0).floor() as usize + 1, "{name}");
        assert!(by_name.frame_names.iter().all(|f| f.starts_with(&format!("{name}@"))));
        check_animated(&by_name, rest);
    }
    let survey = load_gltf(&path, &opts(Some(AnimationSelector::Name("Survey".into())), 30.0, true)).unwrap();
    assert_ne!(survey.frames[survey.frame_count() / 2], seq.frames[seq.frame_count() / 2]);

    let e = load_gltf(&path, &opts(Some(AnimationSelector::Name("Fly".into())), 30.0, true)).unwrap_err();
    assert!(matches!(&e, MeshError::NoSuchAnimation { available, .. } if available.len() == 3), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("Fly") && msg.contains("Run") && msg.contains("Survey") && msg.contains("Walk"), "{msg}");
    let e = load_gltf(&path, &opts(Some(AnimationSelector::Index(3)), 30.0, true)).unwrap_err();
    assert!(matches!(e, MeshError::NoSuchAnimation { .. }), "{e}");

    let unwelded = load_gltf(&path, &opts(None, 30.0, false)).unwrap();
    assert_eq!(unwelded.vertex_count(), 1728);
    assert!(unwelded.source.iter().enumerate().all(|(v, s)| s.index as usize == v && s.primitive == 0));
    // Welding changes no position: each welded vertex moves exactly like its source.
    for (f, frame) in seq.frames.iter().enumerate() {
        for (v, s) in seq.source.iter().enumerate() {
            assert_eq!(frame[v], unwelded.frames[f][s.index as usize], "frame {f} vertex {v}");
        }
    }
}

#[test]
fn robot_merges_nineteen_primitives_of_rigid_skinned_and_morphing_parts() {
    let path = data("RobotExpressive.glb");
    let rig = RiggedMesh::from_path(&path).unwrap();
    assert_eq!(rig.primitives.len(), 19);
    assert_eq!(rig.instances.len(), 14);
    assert_eq!(rig.instances.iter().filter(|i| i.skin.is_some()).count(), 2, "the hands are skinned");
    assert_eq!(rig.instances.iter().filter(|i| !i.morph_targets.is_empty()).count(), 1, "the head morphs");
    assert_eq!(rig.animations.len(), 14);

    let seq = load_gltf(&path, &GltfOptions::default()).unwrap();
    let prims: BTreeSet<u32> = seq.source.iter().map(|s| s.primitive).collect();
    assert_eq!(prims, (0..19).collect());
    // Every source entry is an authored vertex of that primitive, and welding never merges
    // across primitives of different mesh nodes.
    let authored: BTreeSet<(u32, u32)> = rig.source.iter().map(|s| (s.primitive, s.index)).collect();
    for s in &seq.source {
        assert!(authored.contains(&(s.primitive, s.index)), "{s:?}");
    }
    for t in &seq.triangles {
        let nodes: BTreeSet<usize> = t.iter().map(|&v| rig.primitives[seq.source[v as usize].primitive as usize].node).collect();
        assert_eq!(nodes.len(), 1, "{t:?}");
    }
    // Morph displacement only where the head's targets move vertices.
    assert_eq!(seq.morph_displacement.len(), seq.vertex_count());
    let head = rig.instances.iter().find(|i| !i.morph_targets.is_empty()).unwrap().mesh;
    let mut displaced = 0;
    for (v, &d) in seq.morph_displacement.iter().enumerate() {
        assert!(d >= 0.0 && d.is_finite());
        if d > 0.0 {
            displaced += 1;
            assert_eq!(rig.primitives[seq.source[v].primitive as usize].mesh, head, "vertex {v}");
        }
    }
    assert!(displaced > 10, "{displaced} displaced vertices");

    let rest = diag(&rig.pose(None, 0.0));
    for a in &rig.animations {
        let label = a.label();
        let s = load_gltf(&path, &opts(Some(AnimationSelector::Name(label.clone())), 30.0, true)).unwrap();
        assert_eq!(s.frame_count(), (a.duration * 30.0).floor() as usize + 1, "{label}");
        assert_eq!(s.vertex_count(), seq.vertex_count());
        check_animated(&s, rest);
    }

    // Rigid parts follow their bones: in "No" the head (attached to the Head bone) turns.
    let no = load_gltf(&path, &opts(Some(AnimationSelector::Name("No".into())), 30.0, true)).unwrap();
    let head_vertices: Vec<usize> =
        (0..no.vertex_count()).filter(|&v| rig.primitives[no.source[v].primitive as usize].mesh == head).collect();
    let max_move =
        no.frames.iter().map(|f| head_vertices.iter().map(|&v| (f[v] - no.frames[0][v]).length()).fold(0.0, f32::max)).fold(0.0, f32::max);
    assert!(max_move > 0.01 * rest, "the head moves by {max_move}");
}

#[test]
fn horse_gallop_hits_each_morph_target_on_its_keyframe() {
    let path = data("Horse.glb");
    let rig = {
        let mut r = RiggedMesh::from_path(&path).unwrap();
        r.weld();
        r
    };
    assert_eq!(rig.instances.len(), 1);
    let targets = &rig.instances[0].morph_targets;
    assert_eq!(targets.len(), 15);
    let anims = list_animations(&path).unwrap();
    assert_eq!(anims.len(), 1);

    let seq = load_gltf(&path, &GltfOptions::default()).unwrap();
    assert_eq!(seq.frame_count(), (anims[0].duration * 30.0).floor() as usize + 1);
    assert_eq!(seq.frame_count(), 46);
    assert_eq!(seq.vertex_count(), rig.vertex_count());
    let unwelded = RiggedMesh::from_path(&path).unwrap();
    assert_eq!(unwelded.vertex_count(), 796);
    assert!(seq.vertex_count() < 796, "seams welded to {}", seq.vertex_count());
    check_animated(&seq, diag(&rig.positions));
    // Keys every 0.1 s put all weight on target k at time k/10, which is frame 3k at 30 fps.
    let size = diag(&rig.positions);
    for (k, target) in targets.iter().enumerate() {
        for (v, p) in seq.frames[3 * k].iter().enumerate() {
            let want = rig.positions[v] + target[v];
            assert!(close(*p, want, 1e-5 * size), "target {k} vertex {v}: {p} vs {want}");
        }
    }
    assert_eq!(seq.morph_displacement.len(), seq.vertex_count());
    for (v, &d) in seq.morph_displacement.iter().enumerate() {
        let want: f32 = targets.iter().map(|t| t[v].length()).sum();
        assert!((d - want).abs() <= 1e-5 * want.max(1.0), "vertex {v}");
    }
    assert!(seq.morph_displacement.iter().any(|&d| d > 0.0));
}

// ------------------------------------------------------------------------------------------------
// Generated files: sampling
// ------------------------------------------------------------------------------------------------

#[test]
fn linear_and_step_sampling_clamp_outside_the_keys() {
    // Keys at 0.5 s (x = 1) and 1.5 s (x = 3), sampled at 4 fps: t = 0, 0.25, ..., 1.5.
    let x = triangle_x(&[1.0, 0.0, 0.0, 3.0, 0.0, 0.0], "LINEAR", &[0.5, 1.5], 4.0);
    assert_eq!(x.len(), 7);
    let want = [1.0, 1.0, 1.0, 1.5, 2.0, 2.5, 3.0];
    for (got, want) in x.iter().zip(want) {
        assert!((got - want).abs() < 1e-6, "{x:?}");
    }
    let x = triangle_x(&[1.0, 0.0, 0.0, 3.0, 0.0, 0.0], "STEP", &[0.5, 1.5], 4.0);
    assert_eq!(x, [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 3.0]);
}

#[test]
fn cubic_spline_uses_tangents_scaled_by_the_key_interval() {
    // Two keys 2 s apart, values 0 and 2; out-tangent of key 0 is 1, in-tangent of key 1 is 0.
    // p(u) = h10(u) * 2 * 1 + h01(u) * 2: p(0.25) = 0.59375, p(0.5) = 1.25.
    #[rustfmt::skip]
    let values = [
        9.0, 9.0, 9.0,  0.0, 0.0, 0.0,  1.0, 0.0, 0.0, // key 0: in, value, out
        0.0, 0.0, 0.0,  2.0, 0.0, 0.0,  9.0, 9.0, 9.0, // key 1
    ];
    let x = triangle_x(&values, "CUBICSPLINE", &[0.0, 2.0], 2.0);
    assert_eq!(x.len(), 5);
    // p(0.75) = h10 * 2 + h01 * 2 with h10 = 0.046875, h01 = 0.84375: 0.09375 + 1.6875.
    let want = [0.0, 0.59375, 1.25, 1.78125, 2.0];
    for (got, want) in x.iter().zip(want) {
        assert!((got - want).abs() < 1e-5, "{x:?}");
    }
}

#[test]
fn rotations_slerp_on_the_short_arc_and_are_normalised() {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    // 0 to 90 degrees about z, the end written as the negated quaternion: the short way is
    // still 90 degrees, so halfway is 45 (the long way would pass -135).
    let (bin, doc) = animated_triangle("rotation", "LINEAR", &[0.0, 1.0], &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -s, -s]);
    let seq = load(&bin.glb(doc), 2.0).unwrap();
    assert_eq!(seq.frame_count(), 3);
    let half = Vec3::new(s, s, 0.0);
    assert!(close(seq.frames[1][1], half, 1e-5), "{}", seq.frames[1][1]);
    assert!(close(seq.frames[2][1], Vec3::new(0.0, 1.0, 0.0), 1e-5), "{}", seq.frames[2][1]);

    // A cubic spline between the same rotations with zero tangents blends components to a
    // quaternion of length 0.92 at the middle; normalised, it must not shrink the mesh.
    #[rustfmt::skip]
    let values = [
        0.0, 0.0, 0.0, 0.0,  0.0, 0.0, 0.0, 1.0,  0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 0.0,  0.0, 0.0, s, s,      0.0, 0.0, 0.0, 0.0,
    ];
    let (bin, doc) = animated_triangle("rotation", "CUBICSPLINE", &[0.0, 1.0], &values);
    let bytes = bin.glb(doc);
    let seq = load(&bytes, 2.0).unwrap();
    let mid = seq.frames[1][1];
    assert!((mid.length() - 1.0).abs() < 1e-5, "{mid}");
    assert!(close(mid, half, 1e-5), "{mid}");
    // The public sampler itself returns unit quaternions.
    let rig = RiggedMesh::from_bytes(&bytes).unwrap();
    let q = rig.animations[0].channels[0].sample(0.5);
    let len = q.iter().map(|c| c * c).sum::<f32>().sqrt();
    assert!((len - 1.0).abs() < 1e-6, "{q:?}");
    assert!((q[2] - (std::f32::consts::PI / 8.0).sin()).abs() < 1e-5, "{q:?}");
}

#[test]
fn frame_count_names_and_rate() {
    let (bin, doc) = animated_triangle("translation", "LINEAR", &[0.0, 1.0], &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
    let bytes = bin.glb(doc.clone());
    let seq = load(&bytes, 30.0).unwrap();
    assert_eq!(seq.frame_count(), 31);
    assert_eq!(seq.frame_rate, 30.0);
    assert_eq!(seq.frame_names[0], "move@0.000s");
    assert_eq!(seq.frame_names[1], "move@0.033s");
    assert_eq!(seq.frame_names[30], "move@1.000s");
    assert_eq!(load(&bytes, 24.0).unwrap().frame_count(), 25);
    assert_eq!(load(&bytes, 7.0).unwrap().frame_count(), 8);
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(load(&bytes, bad).is_err(), "{bad}");
    }
    // An unnamed animation is labelled by its index.
    let mut unnamed = doc;
    unnamed["animations"][0].as_object_mut().unwrap().remove("name");
    let seq = load(&bin.glb(unnamed), 2.0).unwrap();
    assert_eq!(seq.frame_names[1], "0@0.500s");
    // A huge duration is refused rather than allocated.
    let (bin, doc) = animated_triangle("translation", "LINEAR", &[0.0, 1e9], &[0.0; 6]);
    assert!(matches!(load(&bin.glb(doc), 30.0), Err(MeshError::TooLarge { .. })));

    let infos = list_animations_bytes(&bytes).unwrap();
    assert_eq!(infos.len(), 1);
    assert_eq!(infos[0].name.as_deref(), Some("move"));
    assert_eq!(infos[0].duration, 1.0);
}

#[test]
fn a_file_without_animation_gives_its_rest_pose() {
    let mut bin = Bin::default();
    let pos = bin.f32(&TRIANGLE, "VEC3");
    let bytes = bin.glb(json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [0.0, 0.0, 5.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}}]}]
    }));
    let seq = load(&bytes, 30.0).unwrap();
    assert_eq!(seq.frame_count(), 1);
    assert_eq!(seq.frame_names, ["rest@0.000s"]);
    assert_eq!(seq.frames[0][1], Vec3::new(1.0, 0.0, 5.0), "a mesh node's transform applies");
    assert!(seq.morph_displacement.is_empty());
    let e = load_gltf_bytes(&bytes, &opts(Some(AnimationSelector::Index(0)), 30.0, true)).unwrap_err();
    assert!(matches!(e, MeshError::NoSuchAnimation { .. }) && e.to_string().contains("none"), "{e}");
}

// ------------------------------------------------------------------------------------------------
// Generated files: morphs and skins
// ------------------------------------------------------------------------------------------------

#[test]
fn morph_weights_scale_their_deltas() {
    // Weight 0 -> 1 over one second: at 0.5 s vertex 2 is lifted by half its delta.
    let (bin, doc) = animated_triangle("weights", "LINEAR", &[0.0, 1.0], &[0.0, 1.0]);
    let seq = load(&bin.glb(doc.clone()), 2.0).unwrap();
    assert_eq!(seq.frames[1][2], Vec3::new(0.0, 1.0, 0.5));
    assert_eq!(seq.frames[2][2], Vec3::new(0.0, 1.0, 1.0));
    assert_eq!(seq.frames[1][1], Vec3::new(1.0, 0.0, 0.0), "vertices without a delta stay");
    assert_eq!(seq.morph_displacement, [0.0, 0.0, 1.0]);

    // Two targets blended: weights (0.5, 0.25) give half of one delta and a quarter of the other.
    let mut bin = Bin::default();
    let pos = bin.f32(&TRIANGLE, "VEC3");
    let d0 = bin.f32(&[2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], "VEC3");
    let d1 = bin.f32(&[0.0, 4.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], "VEC3");
    let input = bin.f32(&[0.0, 1.0], "SCALAR");
    let output = bin.f32(&[0.0, 0.0, 1.0, 0.5], "SCALAR");
    let doc = json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "targets": [{"POSITION": d0}, {"POSITION": d1}]}]}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
                        "samplers": [{"input": input, "output": output}]}]
    });
    let seq = load(&bin.glb(doc.clone()), 2.0).unwrap();
    assert_eq!(seq.frames[1][0], Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(seq.morph_displacement, [6.0, 0.0, 0.0]);

    // Without an animation the node's weights apply, else the mesh's.
    let mut still = doc;
    still.as_object_mut().unwrap().remove("animations");
    still["meshes"][0]["weights"] = json!([0.5, 0.0]);
    assert_eq!(load(&bin.glb(still.clone()), 30.0).unwrap().frames[0][0], Vec3::new(1.0, 0.0, 0.0));
    still["nodes"][0]["weights"] = json!([0.0, 0.5]);
    assert_eq!(load(&bin.glb(still), 30.0).unwrap().frames[0][0], Vec3::new(0.0, 2.0, 0.0));
}

#[test]
fn two_joint_skin_bends_a_strip() {
    let (bin, doc) = bent_strip();
    let seq = load(&bin.glb(doc), 1.0).unwrap();
    assert_eq!(seq.frame_count(), 2);
    // Depth first from the scene's nodes [0, 2]: node 0, its child 1, its child 3 (the rigid
    // triangle, primitive 0), then node 2 (the strip, primitive 1).
    let prims: Vec<u32> = seq.source.iter().map(|s| s.primitive).collect();
    assert_eq!(prims, [0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1]);
    assert_eq!(seq.triangles.len(), 1 + 6);
    let strip = |k: usize| 3 + k;
    let (rest, bent) = (&seq.frames[0], &seq.frames[1]);
    // Rest pose: the mesh node's own translation by 100 is ignored.
    assert!(close(rest[strip(6)], Vec3::new(3.0, 0.0, 0.0), 1e-5), "{}", rest[strip(6)]);
    assert!(close(rest[strip(3)], Vec3::new(1.0, 0.1, 0.0), 1e-5), "{}", rest[strip(3)]);
    // Bent: joint 1 turned 90 degrees at x = 1.
    assert!(close(bent[strip(6)], Vec3::new(1.0, 2.0, 0.0), 1e-5), "{}", bent[strip(6)]);
    assert!(close(bent[strip(4)], Vec3::new(1.0, 1.0, 0.0), 1e-5), "{}", bent[strip(4)]);
    // Half and half: the average of (1, 0.1) unmoved and (0.9, 0) turned.
    assert!(close(bent[strip(3)], Vec3::new(0.95, 0.05, 0.0), 1e-5), "{}", bent[strip(3)]);
    assert_eq!(bent[strip(0)], rest[strip(0)], "joint-0 vertices do not move");
    assert_eq!(bent[strip(1)], rest[strip(1)]);
    // The rigid triangle hangs from joint 1: at x = 2 at rest, at (1, 1) once turned.
    assert!(close(rest[0], Vec3::new(2.0, 0.0, 0.0), 1e-5), "{}", rest[0]);
    assert!(close(bent[0], Vec3::new(1.0, 1.0, 0.0), 1e-5), "{}", bent[0]);
    assert!(close(bent[1], Vec3::new(1.0, 2.0, 0.0), 1e-5), "{}", bent[1]);
    // The strip's triangles all face the same way.
    let normal_z = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| rest[i as usize]);
        (b - a).cross(c - a).z
    };
    let signs: BTreeSet<bool> = seq.triangles[1..].iter().map(|t| normal_z(t) > 0.0).collect();
    assert_eq!(signs.len(), 1, "strip winding alternates correctly");
    // The rig keeps joints and normalised weights for a writer.
    let rig = RiggedMesh::from_bytes(&bin.glb(bent_strip().1)).unwrap();
    assert_eq!(rig.instances.len(), 2);
    assert_eq!(rig.instances[1].skin, Some(0));
    assert_eq!(rig.instances[1].vertices, 3..11);
    assert_eq!(rig.joints[strip(3)], [0, 1, 0, 0]);
    assert_eq!(rig.weights[strip(3)], [0.5, 0.5, 0.0, 0.0]);
    assert_eq!(rig.weights[strip(6)], [1.0, 0.0, 0.0, 0.0]);
    assert_eq!(rig.joints[strip(6)], [1, 0, 0, 0], "zero-weight slots are dropped");
    assert_eq!(rig.weights[0], [0.0; 4], "unskinned vertices carry no weights");
    assert_eq!(rig.pose(None, 0.0), seq.frames[0]);
    assert_eq!(rig.pose(Some(&rig.animations[0]), 1.0), seq.frames[1]);
}

#[test]
fn quantized_positions_are_decoded() {
    // KHR_mesh_quantization: normalised i16 positions, scaled back by the node.
    let mut bin = Bin::default();
    let pos = bin.i16_normalized(&[0, 0, 0, 32767, 0, 0, 0, -32767, 0, 0, 0, 0], "VEC3");
    let idx = bin.u16(&[0, 1, 2], "SCALAR");
    let bytes = bin.glb(json!({
        "extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "scale": [2.0, 2.0, 2.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}]
    }));
    let seq = load(&bytes, 30.0).unwrap();
    assert_eq!(seq.vertex_count(), 3, "the unused fourth vertex is dropped");
    assert_eq!(seq.frames[0], [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, -2.0, 0.0)]);
}

// ------------------------------------------------------------------------------------------------
// Generated files: topology and welding
// ------------------------------------------------------------------------------------------------

#[test]
fn fans_become_consistently_wound_triangles() {
    // A fan around the origin over five rim points, counter-clockwise seen from +z.
    let mut pts = vec![0.0, 0.0, 0.0];
    for i in 0..5 {
        let a = i as f32 * 0.5;
        pts.extend([a.cos(), a.sin(), 0.0]);
    }
    let mut bin = Bin::default();
    let pos = bin.f32(&pts, "VEC3");
    let bytes = bin.glb(json!({
        "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "mode": 6}]}]
    }));
    let seq = load(&bytes, 30.0).unwrap();
    assert_eq!(seq.triangles.len(), 4);
    for t in &seq.triangles {
        assert!(t.contains(&0), "{t:?} pivots on vertex 0");
        let [a, b, c] = t.map(|i| seq.frames[0][i as usize]);
        assert!((b - a).cross(c - a).z > 0.0, "{t:?} keeps the counter-clockwise winding");
    }
}

/// Three triangles written unindexed (nine vertices, four distinct points A B C D): ABC, CBD and
/// the sliver A B A', which repeats A once welded. `delta_on` puts a morph delta on one vertex.
fn loose_quad(delta_on: Option<usize>) -> Vec<u8> {
    let (a, b, c, d) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]);
    let pts: Vec<f32> = [a, b, c, c, b, d, a, b, a].concat();
    let mut bin = Bin::default();
    let pos = bin.f32(&pts, "VEC3");
    let mut prim = json!({"attributes": {"POSITION": pos}});
    if let Some(v) = delta_on {
        let mut deltas = vec![0.0f32; 27];
        deltas[3 * v + 2] = 1.0;
        prim["targets"] = json!([{"POSITION": bin.f32(&deltas, "VEC3")}]);
    }
    bin.glb(json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}], "meshes": [{"primitives": [prim]}]}))
}

#[test]
fn welding_joins_seams_keeps_order_and_drops_slivers() {
    let bytes = loose_quad(None);
    let raw = load_gltf_bytes(&bytes, &opts(None, 30.0, false)).unwrap();
    assert_eq!(raw.vertex_count(), 9);
    assert_eq!(raw.triangles.len(), 3);
    let welded = load_gltf_bytes(&bytes, &GltfOptions::default()).unwrap();
    assert_eq!(welded.vertex_count(), 4);
    assert_eq!(welded.triangles, [[0, 1, 2], [2, 1, 3]], "first occurrences in order; the sliver is gone");
    let first: Vec<u32> = welded.source.iter().map(|s| s.index).collect();
    assert_eq!(first, [0, 1, 2, 5]);
    assert_eq!(components(welded.vertex_count(), &welded.triangles), 1);

    // A copy of C that morphs differently is not the same vertex.
    let bytes = loose_quad(Some(3));
    let welded = load_gltf_bytes(&bytes, &GltfOptions::default()).unwrap();
    assert_eq!(welded.vertex_count(), 5);
    assert_eq!(welded.triangles.len(), 2);
    assert_eq!(welded.morph_displacement.iter().filter(|&&d| d > 0.0).count(), 1);
}

#[test]
fn meshes_sharing_a_skin_weld_along_their_seam() {
    // Two skinned nodes, one triangle each, sharing an edge and the skin: one surface.
    let mut bin = Bin::default();
    let left = bin.f32(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3");
    let right = bin.f32(&[0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0], "VEC3");
    let joints = bin.u8(&[0; 12], "VEC4", false);
    let weights = bin.f32(&[1.0, 0.0, 0.0, 0.0].repeat(3), "VEC4");
    let prim = |pos: usize| json!({"attributes": {"POSITION": pos, "JOINTS_0": joints, "WEIGHTS_0": weights}});
    let bytes = bin.glb(json!({
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"translation": [0.0, 0.0, 1.0]}, {"mesh": 0, "skin": 0}, {"mesh": 1, "skin": 0}],
        "skins": [{"joints": [0]}],
        "meshes": [{"primitives": [prim(left)]}, {"primitives": [prim(right)]}]
    }));
    let seq = load_gltf_bytes(&bytes, &GltfOptions::default()).unwrap();
    assert_eq!(seq.vertex_count(), 4);
    assert_eq!(components(4, &seq.triangles), 1);
    assert_eq!(seq.frames[0][3], Vec3::new(1.0, 1.0, 1.0), "posed by the joint");
    let prims: Vec<u32> = seq.source.iter().map(|s| s.primitive).collect();
    assert_eq!(prims, [0, 0, 0, 1]);
}
