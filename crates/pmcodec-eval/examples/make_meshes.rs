//! Writes the test meshes of issue 15 that the project has no file of, as OBJ sequences (one
//! folder each) under OUT_DIR; deterministic, never committed:
//! - `horse-sub4`: horse-gallop Loop-subdivided twice (about 135,000 vertices), every frame
//!   from that frame's positions;
//! - `samba-open`, `cat-open`: faces within 3% of the bounding-box diagonal of the frame-0
//!   extreme vertices (+Y, -X, +X, -Z, +Z: head, hands, feet or paws) deleted;
//! - `horse-half`, `samba-half`: the faces whose frame-0 centroid lies below the median x
//!   (horse) or z (samba: its back) deleted: one long boundary across the surface, as on a
//!   face mask or a garment;
//! - `waving-cloth`: the built-in sample (pmcodec_mesh::samples), open on four sides.
//!
//! `cargo run --release -p pmcodec-eval --example make_meshes -- OUT_DIR [DATA_DIR]`
//! (DATA_DIR defaults to ../shared/data).

use pmcodec_eval::made::{boundary_loops, extreme_vertices, loop_subdivide, open_half, open_regions};
use pmcodec_mesh::{Sequence, TriMesh};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

fn load(data: &Path, name: &str) -> Result<Sequence, String> {
    let dir = data.join(name);
    pmcodec_mesh::obj::load_obj_sequence(&dir, 30.0).map_err(|e| format!("{}: {e} (is ../shared/data there?)", dir.display()))
}

fn write(out: &Path, name: &str, seq: &Sequence) -> Result<(), String> {
    let dir = out.join(name);
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for (f, frame) in seq.frames.iter().enumerate() {
        let path = dir.join(format!("{name}-{:03}.obj", f + 1));
        let mesh = TriMesh { positions: frame.clone(), triangles: seq.triangles.clone() };
        pmcodec_mesh::write::write_mesh_file(&path, &mesh).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    let (edges, loops) = boundary_loops(seq.vertex_count(), &seq.triangles);
    println!(
        "{name}: {} frames, {} vertices, {} triangles, {edges} boundary edges in {loops} loops",
        seq.frame_count(),
        seq.vertex_count(),
        seq.triangles.len()
    );
    Ok(())
}

fn opened(seq: &Sequence) -> Sequence {
    let first = seq.frames.first().map(Vec::as_slice).unwrap_or(&[]);
    let diagonal = pmcodec_mesh::bounds_of(first).map_or(0.0, |(lo, hi)| (hi - lo).length());
    open_regions(seq, &extreme_vertices(first), 0.03 * diagonal)
}

fn run(out: &Path, data: &Path) -> Result<(), String> {
    let horse = load(data, "horse-gallop")?;
    write(out, "horse-sub4", &loop_subdivide(&loop_subdivide(&horse)))?;
    write(out, "horse-half", &open_half(&horse, 0))?;
    let samba = load(data, "samba-60")?;
    write(out, "samba-open", &opened(&samba))?;
    write(out, "samba-half", &open_half(&samba, 2))?;
    write(out, "cat-open", &opened(&load(data, "cat-poses")?))?;
    let cloth = pmcodec_mesh::samples::by_name("waving-cloth").ok_or("no built-in waving-cloth sample")?;
    write(out, "waving-cloth", &cloth)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(out) = args.first() else {
        eprintln!("usage: make_meshes OUT_DIR [DATA_DIR]");
        return ExitCode::from(2);
    };
    let data = args.get(1).map_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data")), PathBuf::from);
    match run(Path::new(out), &data) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("make_meshes: {e}");
            ExitCode::from(3)
        }
    }
}
