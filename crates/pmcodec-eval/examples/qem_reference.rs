//! Plain QEM on frame 0, the reference of issue 15's "frame 0 alone" bar: meshoptimizer's
//! simplifier (edge collapse by quadric error, boundary vertices kept on the boundary, no
//! flipped triangle; Kapoulkine's meshoptimizer, after Garland & Heckbert 1997) taking frame 0
//! to each vertex count, measured by the same sampled distance as `pmcodec eval`. The target
//! index count is bisected until the vertex count is within 1% of the one asked for.
//!
//! `cargo run --release -p pmcodec-eval --example qem_reference -- INPUT N [N...]`
//! prints one JSON object a line: `{"vertices": asked, "got": vertices, "rms": %, "max": %}`.

use pmcodec_eval::{SampleOptions, symmetric_relative};
use std::path::Path;
use std::process::ExitCode;

#[path = "common/qem.rs"]
mod qem;
use qem::reference;

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
