//! Plain QEM on frame 0, the reference of issue 15's "frame 0 alone" bar: meshoptimizer's
//! simplifier (edge collapse by quadric error, boundary vertices kept on the boundary, no
//! flipped triangle; Kapoulkine's meshoptimizer, after Garland & Heckbert 1997) taking frame 0
//! to each vertex count, measured by the same sampled distance as `pmcodec eval`. The target
//! index count is bisected until the vertex count is within 1% of the one asked for.
//!
//! `cargo run --release -p pmcodec-eval --example qem_reference -- INPUT N [N...]`
//! prints one JSON object a line: `{"vertices": asked, "got": vertices, "rms": %, "max": %}`.

use pmcodec_eval::{SampleOptions, symmetric_relative};
use pmcodec_mesh::{Sequence, TriMesh};
use std::path::Path;
use std::process::ExitCode;

/// The simplified mesh with its unused vertices dropped.
fn simplify(seq: &Sequence, index_target: usize) -> Result<TriMesh, String> {
    let frame = &seq.frames[0];
    let flat: Vec<f32> = frame.iter().flat_map(|p| p.to_array()).collect();
    let bytes: Vec<u8> = flat.iter().flat_map(|x| x.to_le_bytes()).collect();
    let adapter = meshopt::VertexDataAdapter::new(&bytes, 12, 0).map_err(|e| format!("{e:?}"))?;
    let indices: Vec<u32> = seq.triangles.iter().flatten().copied().collect();
    let out = meshopt::simplify(&indices, &adapter, index_target, f32::MAX, meshopt::SimplifyOptions::empty(), None);
    let mut index = vec![u32::MAX; frame.len()];
    let mut mesh = TriMesh::default();
    for t in out.chunks_exact(3) {
        let tri = [t[0], t[1], t[2]].map(|v| {
            if index[v as usize] == u32::MAX {
                index[v as usize] = mesh.positions.len() as u32;
                mesh.positions.push(frame[v as usize]);
            }
            index[v as usize]
        });
        mesh.triangles.push(tri);
    }
    Ok(mesh)
}

fn reference(seq: &Sequence, vertices: usize) -> Result<TriMesh, String> {
    let (mut lo, mut hi) = (3usize, seq.triangles.len() * 3);
    let mut best: Option<TriMesh> = None;
    for _ in 0..24 {
        let mid = (lo + hi) / 2 / 3 * 3;
        let m = simplify(seq, mid)?;
        let got = m.positions.len();
        let better = best.as_ref().is_none_or(|b| got.abs_diff(vertices) < b.positions.len().abs_diff(vertices));
        if got > vertices {
            hi = mid;
        } else {
            lo = mid + 3;
        }
        if better {
            best = Some(m);
        }
        if got.abs_diff(vertices) * 100 <= vertices || hi <= lo {
            break;
        }
    }
    best.ok_or_else(|| "no simplification".to_string())
}

fn run(args: &[String]) -> Result<(), String> {
    let input = args.first().ok_or("usage: qem_reference INPUT N [N...]")?;
    let seq = pmcodec_mesh::obj::load_obj_sequence(Path::new(input), 30.0).map_err(|e| format!("{input}: {e}"))?;
    let original = seq.frame_mesh(0).ok_or("no frames")?;
    for n in &args[1..] {
        let n: usize = n.parse().map_err(|_| format!("{n:?} is not a vertex count"))?;
        let m = reference(&seq, n)?;
        let d = symmetric_relative(&original, &m, &SampleOptions::default()).map_err(|e| e.to_string())?;
        println!("{{\"vertices\": {n}, \"got\": {}, \"rms\": {}, \"max\": {}}}", m.positions.len(), d.rms, d.max);
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("qem_reference: {e}");
            ExitCode::from(3)
        }
    }
}
