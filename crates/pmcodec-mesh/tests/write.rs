//! Writers: OBJ and GLB round trips, and no half files on failure.

use glam::Vec3;
use pmcodec_mesh::write::{glb_bytes, write_mesh_file, write_obj};
use pmcodec_mesh::TriMesh;

fn tetra() -> TriMesh {
    TriMesh {
        positions: vec![Vec3::ZERO, Vec3::new(1.5, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.1, 0.2, -2.25)],
        triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
    }
}

#[test]
fn obj_round_trips_exactly() {
    let m = tetra();
    let mut buf = Vec::new();
    write_obj(&mut buf, &m).unwrap();
    let back = pmcodec_mesh::obj::parse_obj(std::str::from_utf8(&buf).unwrap(), std::path::Path::new("x.obj")).unwrap();
    assert_eq!(back.positions, m.positions);
    assert_eq!(back.triangles, m.triangles);
}

#[test]
fn glb_parses_back_with_gltf() {
    let m = tetra();
    let bytes = glb_bytes(&m);
    assert_eq!(bytes.len() % 4, 0);
    let g = gltf::Gltf::from_slice(&bytes).expect("valid GLB");
    let blob = g.blob.clone().expect("BIN chunk");
    let mesh = g.meshes().next().expect("one mesh");
    let prim = mesh.primitives().next().expect("one primitive");
    let reader = prim.reader(|_| Some(&blob[..]));
    let pos: Vec<Vec3> = reader.read_positions().expect("positions").map(Vec3::from_array).collect();
    assert_eq!(pos, m.positions);
    let idx: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    assert_eq!(idx, m.triangles.iter().flatten().copied().collect::<Vec<_>>());
    let bb = prim.bounding_box();
    assert_eq!(bb.min, [0.0, 0.0, -2.25]);
    assert_eq!(bb.max, [1.5, 1.0, 0.0]);
    assert_eq!(reader.read_normals().expect("normals").count(), 4);
}

#[test]
fn empty_mesh_is_still_a_valid_glb() {
    let bytes = glb_bytes(&TriMesh::default());
    let g = gltf::Gltf::from_slice(&bytes).expect("valid GLB");
    assert_eq!(g.meshes().count(), 0);
}

#[test]
fn files_are_written_whole_or_not_at_all() {
    let dir = std::env::temp_dir().join(format!("pmcodec-write-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ok = dir.join("t.glb");
    write_mesh_file(&ok, &tetra()).unwrap();
    assert!(gltf::Gltf::from_slice(&std::fs::read(&ok).unwrap()).is_ok());
    let bad = dir.join("t.stl");
    assert!(write_mesh_file(&bad, &tetra()).unwrap_err().to_string().contains("unknown extension"));
    let missing = dir.join("no-such-dir").join("t.obj");
    assert!(write_mesh_file(&missing, &tetra()).is_err());
    let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().filter(|e| e.file_name().to_string_lossy().ends_with(".tmp")).collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    std::fs::remove_dir_all(&dir).ok();
}
