//! `pmcodec decode --skinned-glb` (issue 19 item 4): a fitted rig comes out as a skinned GLB
//! that the gltf crate reads, whose animation, applied by hand to its bind positions with its
//! weights, gives back the decoded frames; a file without a skin is refused and nothing is
//! written.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::{Mat4, Quat, Vec3};
use std::path::PathBuf;
use std::process::Command;

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pmcodec-rig-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn pmcodec(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pmcodec")).args(args).output().unwrap()
}

#[test]
fn a_fitted_rig_plays_back_the_decoded_frames() {
    let dir = temp("fitted");
    let mut seq = pmcodec_mesh::samples::rigid_parts(3, 10);
    let fit = pmcodec_mesh::skin_fit::FitOptions { bones: Some(3), ..Default::default() };
    let (skin, _) = pmcodec_mesh::skin_fit::fit_skin(&seq, &fit).unwrap();
    seq.skin = Some(skin);
    let bytes = pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap();
    let pmc = dir.join("parts.pmc");
    std::fs::write(&pmc, &bytes).unwrap();
    let glb = dir.join("rig.glb");
    let out = pmcodec(&["decode".as_ref(), pmc.as_os_str(), "--skinned-glb".as_ref(), "-o".as_ref(), glb.as_os_str(), "--json".as_ref()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["frames"], 10);
    assert_eq!(report["vertices"], seq.vertex_count());
    // Three rigid parts, three bones: the rig explains the motion up to quantization.
    assert!(report["rms_error"].as_f64().unwrap() < 1e-3, "{report}");

    let (doc, buffers, _) = gltf::import(&glb).expect("a GLB the gltf crate imports");
    let skin = doc.skins().next().expect("a skin");
    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    assert!(joints.len() >= 4, "a root and the bones: {joints:?}");
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let r = prim.reader(|b| Some(&buffers[b.index()]));
    let rest: Vec<Vec3> = r.read_positions().unwrap().map(Vec3::from).collect();
    let js: Vec<[u16; 4]> = r.read_joints(0).unwrap().into_u16().collect();
    let ws: Vec<[f32; 4]> = r.read_weights(0).unwrap().into_f32().collect();
    assert_eq!(rest.len(), seq.vertex_count());
    // Every node's transform at each frame, from the animation's samples.
    let anim = doc.animations().next().expect("an animation");
    let mut trs: Vec<Vec<(Vec3, Quat, Vec3)>> = vec![vec![(Vec3::ZERO, Quat::IDENTITY, Vec3::ONE); 10]; doc.nodes().count()];
    for ch in anim.channels() {
        let node = ch.target().node().index();
        let rd = ch.reader(|b| Some(&buffers[b.index()]));
        match rd.read_outputs().unwrap() {
            gltf::animation::util::ReadOutputs::Translations(t) => t.enumerate().for_each(|(f, v)| trs[node][f].0 = v.into()),
            gltf::animation::util::ReadOutputs::Rotations(q) => {
                q.into_f32().enumerate().for_each(|(f, v)| trs[node][f].1 = Quat::from_array(v))
            }
            gltf::animation::util::ReadOutputs::Scales(s) => s.enumerate().for_each(|(f, v)| trs[node][f].2 = v.into()),
            _ => panic!("only bones are animated"),
        }
    }
    let reader = pmcodec_container::Reader::open(bytes.as_slice()).unwrap();
    let mut dec = pmcodec_container::Decoder::new(reader.borrowed(), 0).unwrap();
    let h = reader.header();
    let diagonal = (Vec3::from_array(h.bbox_max) - Vec3::from_array(h.bbox_min)).length();
    for f in 0..10u32 {
        dec.seek(f).unwrap();
        let decoded = dec.positions();
        // The bones hang under a still root: a joint's world transform is its own.
        let world: Vec<Mat4> = joints
            .iter()
            .map(|&n| {
                let (t, q, s) = trs[n][f as usize];
                if n == joints[0] { Mat4::IDENTITY } else { Mat4::from_scale_rotation_translation(s, q, t) }
            })
            .collect();
        let mut worst = 0.0f32;
        for v in 0..rest.len() {
            let p: Vec3 = (0..4).map(|k| ws[v][k] * world[js[v][k] as usize].transform_point3(rest[v])).sum();
            worst = worst.max(p.distance(decoded[v]));
        }
        assert!(worst < 0.01 * diagonal, "frame {f}: the rig misses a vertex by {worst} (diagonal {diagonal})");
    }
}

#[test]
fn a_file_without_a_skin_is_refused_and_nothing_written() {
    let dir = temp("plain");
    let seq = pmcodec_mesh::samples::twisting_tube(8, 6, 4);
    let pmc = dir.join("tube.pmc");
    std::fs::write(&pmc, pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap()).unwrap();
    let glb = dir.join("rig.glb");
    let out = pmcodec(&["decode".as_ref(), pmc.as_os_str(), "--skinned-glb".as_ref(), "-o".as_ref(), glb.as_os_str()]);
    assert_eq!(out.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&out.stderr).contains("has no skin"), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!glb.exists());
    let obj = dir.join("rig.obj");
    let out = pmcodec(&["decode".as_ref(), pmc.as_os_str(), "--skinned-glb".as_ref(), "-o".as_ref(), obj.as_os_str()]);
    assert_eq!(out.status.code(), Some(2), "a usage error");
    let out = pmcodec(&[
        "decode".as_ref(),
        pmc.as_os_str(),
        "--skinned-glb".as_ref(),
        "--level".as_ref(),
        "1".as_ref(),
        "-o".as_ref(),
        glb.as_os_str(),
    ]);
    assert_eq!(out.status.code(), Some(2), "--level conflicts with --skinned-glb");
}
