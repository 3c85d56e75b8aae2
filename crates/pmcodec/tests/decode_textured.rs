//! `pmcodec decode` of a container with an appearance: a textured GLB (UVs, normals, colours,
//! both materials, the image) and an OBJ with its MTL and image that our own OBJ reader reads
//! back with the same materials.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::process::Command;

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pmcodec-textured-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&std::ffi::OsStr]) {
    let out = Command::new(env!("CARGO_BIN_EXE_pmcodec")).args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn decode_writes_textured_glb_and_obj_with_mtl() {
    let dir = temp("decode");
    let seq = pmcodec_mesh::samples::textured_cloth(16, 10, 4, 16);
    let bytes = pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap();
    let pmc = dir.join("cloth.pmc");
    std::fs::write(&pmc, bytes).unwrap();
    let glb = dir.join("cut.glb");
    run(&[
        "decode".as_ref(),
        pmc.as_os_str(),
        "--frame".as_ref(),
        "2".as_ref(),
        "--triangles".as_ref(),
        "50%".as_ref(),
        "-o".as_ref(),
        glb.as_os_str(),
    ]);
    let (doc, buffers, images) = gltf::import(&glb).expect("a GLB the gltf crate imports");
    assert_eq!(doc.materials().count(), 2);
    assert_eq!(images.len(), 1);
    assert_eq!((images[0].width, images[0].height), (16, 16));
    let mesh = doc.meshes().next().unwrap();
    assert_eq!(mesh.primitives().count(), 2, "one primitive per material");
    for p in mesh.primitives() {
        let r = p.reader(|b| Some(&buffers[b.index()]));
        let n = r.read_positions().unwrap().count();
        assert_eq!(r.read_tex_coords(0).unwrap().into_f32().count(), n);
        assert_eq!(r.read_normals().unwrap().count(), n);
        assert_eq!(r.read_colors(0).unwrap().into_rgba_f32().count(), n);
    }
    let blend = doc.materials().find(|m| m.alpha_mode() == gltf::material::AlphaMode::Blend).expect("the orange material");
    assert!(blend.double_sided());
    // OBJ + MTL + image, read back by our OBJ reader: level 0 is the input.
    let obj = dir.join("out").join("level0.obj");
    std::fs::create_dir_all(obj.parent().unwrap()).unwrap();
    run(&["decode".as_ref(), pmc.as_os_str(), "--level".as_ref(), "0".as_ref(), "-o".as_ref(), obj.as_os_str()]);
    assert!(dir.join("out/level0.mtl").is_file());
    let back = pmcodec_mesh::obj::load_obj_sequence(&obj, 30.0).expect("reads back");
    let a = back.appearance.expect("appearance");
    let want = seq.appearance.as_ref().unwrap();
    assert_eq!(a.materials.len(), 2);
    assert_eq!(a.images.len(), 1);
    assert_eq!(a.images[0].bytes, want.images[0].bytes);
    assert_eq!(a.triangle_material, want.triangle_material);
    assert_eq!(back.triangles.len(), seq.triangles.len());
    // Positions and attributes are indexed apart: a seam does not split a vertex, so level 0
    // holds exactly the input's vertices, within a quantization step.
    assert_eq!(back.frames[0].len(), seq.frames[0].len(), "the OBJ's v lines are the input's vertices");
    let lo = seq.frames[0].iter().copied().reduce(|a, b| a.min(b)).unwrap();
    let hi = seq.frames[0].iter().copied().reduce(|a, b| a.max(b)).unwrap();
    let tol = (hi - lo).length() * 1e-3;
    for (a, b) in back.frames[0].iter().zip(&seq.frames[0]) {
        assert!(a.distance(*b) <= tol, "{a} vs {b}");
    }
}
