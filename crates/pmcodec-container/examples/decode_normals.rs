//! Decode speed at full resolution with normals computed (issue 16's bar: at least 1,000
//! frames per second on one core, horse), in CPU time of this process (the machine is shared):
//!
//! - bare: every frame decoded, cut at level 0 (the input mesh) and given area-weighted vertex
//!   normals, as the server's GLB and a player do;
//! - textured: the same sequence with a generated appearance (cylindrical texture coordinates
//!   with a seam where the cylinder is cut, two materials split by height, vertex colours), each
//!   frame drawn by `Decoder::textured_mesh` (per-vertex attributes of every (node, chart,
//!   smoothing group), normals split at seams: proto/container.md, "Drawing a cut's
//!   appearance").
//!
//! `cargo run --release -p pmcodec-container --example decode_normals -- DIR [passes]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use glam::Vec3;
use pmcodec_container::{CutTarget, Decoder, EncodeOptions, QuantizationChoice, Reader, encode};
use pmcodec_mesh::appearance::Material;
use pmcodec_mesh::{Appearance, Sequence, TriMesh};

/// CPU seconds (user + system) this process has used, from /proc (10 ms ticks).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = after.split_whitespace().map(|x| x.parse().unwrap_or(0.0)).collect();
    (f.get(11).copied().unwrap_or(0.0) + f.get(12).copied().unwrap_or(0.0)) / 100.0
}

/// A generated appearance for `seq`: texture coordinates from a cylinder around the longest
/// axis of frame 0's bounding box (a triangle that wraps around gets its own wedges, so the
/// seam is real), colours from the position, material 1 above the middle height.
fn cylinder_appearance(seq: &Sequence) -> Appearance {
    let f0 = &seq.frames[0];
    let (lo, hi) = f0.iter().fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(a, b), &p| (a.min(p), b.max(p)));
    let ext = hi - lo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let centre = (lo + hi) * 0.5;
    let uv_of = |p: Vec3| {
        let d = p - centre;
        let (a, b) = match axis {
            0 => (d.y, d.z),
            1 => (d.z, d.x),
            _ => (d.x, d.y),
        };
        let u = (b.atan2(a) / std::f32::consts::TAU) + 0.5;
        [u, (p[axis] - lo[axis]) / ext[axis].max(1e-9)]
    };
    let mut app = Appearance::default();
    let mut first_wedge: Vec<Option<u32>> = vec![None; f0.len()];
    for t in &seq.triangles {
        let uvs = t.map(|v| uv_of(f0[v as usize]));
        let wraps = uvs.iter().any(|a| uvs.iter().any(|b| (a[0] - b[0]).abs() > 0.5));
        let mut w = [0u32; 3];
        for i in 0..3 {
            let v = t[i] as usize;
            let reuse = if wraps { None } else { first_wedge[v] };
            w[i] = reuse.unwrap_or_else(|| {
                let id = app.wedge_vertex.len() as u32;
                let mut uv = uvs[i];
                if wraps && uv[0] < 0.5 {
                    uv[0] += 1.0;
                }
                app.wedge_vertex.push(v as u32);
                app.uv0.push(uv);
                let c = (f0[v] - lo) / ext.max(Vec3::splat(1e-9));
                app.colors.push([c.x, c.y, c.z, 1.0]);
                if !wraps {
                    first_wedge[v] = Some(id);
                }
                id
            });
        }
        app.corner_wedges.push(w);
        let h = t.iter().map(|&v| f0[v as usize][axis]).sum::<f32>() / 3.0;
        app.triangle_material.push(u32::from(h > centre[axis]));
    }
    app.materials =
        vec![Material { name: Some("low".into()), ..Default::default() }, Material { name: Some("high".into()), ..Default::default() }];
    app
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).expect("usage: decode_normals DIR [passes]");
    let passes: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20);
    let mut seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(dir), 30.0).expect("load");
    let opts = EncodeOptions { quantization: QuantizationChoice::Bits(12), ..Default::default() };
    let bare = encode(&seq, &opts, |_| {}).expect("encode");
    seq.appearance = Some(cylinder_appearance(&seq));
    let textured = encode(&seq, &opts, |_| {}).expect("encode textured");

    for (name, bytes) in [("bare", &bare), ("textured", &textured)] {
        let reader = Reader::open(bytes.as_slice()).expect("open");
        let n = reader.header().frame_count;
        let mut mesh = TriMesh::default();
        let (mut vertices, mut triangles, mut check) = (0usize, 0usize, 0.0f64);
        let (t, c) = (std::time::Instant::now(), cpu_seconds());
        for _ in 0..passes {
            let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
            for f in 0..n {
                d.seek(f).expect("frame");
                if name == "bare" {
                    d.mesh_into(CutTarget::Level(0), &mut mesh).expect("cut");
                    let normals = pmcodec_mesh::write::vertex_normals(&mesh);
                    check += normals[f as usize % normals.len()].x as f64;
                    (vertices, triangles) = (mesh.positions.len(), mesh.triangles.len());
                } else {
                    let (m, app) = d.textured_mesh(CutTarget::Level(0)).expect("textured cut");
                    check += app.normals[f as usize % app.normals.len()][0] as f64;
                    (vertices, triangles) = (m.positions.len(), m.triangles.len());
                }
            }
        }
        let frames = (passes as u32 * n) as f64;
        let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        println!(
            "decode with normals, {name}, full resolution ({vertices} vertices, {triangles} triangles): {:.3} ms/frame CPU ({:.0} frames/s), {:.3} ms/frame wall (checksum {check:.3})",
            cpu * 1e3 / frames,
            frames / cpu,
            wall * 1e3 / frames
        );
    }
}
