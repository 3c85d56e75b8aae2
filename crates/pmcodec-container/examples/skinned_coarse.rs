//! Coarse nodes of skinned bands at their skinned positions (issues 17 and 19): one sequence
//! encoded at 12-bit quantization with coarse nodes stored near their per-frame quadric-optimal
//! points (`skinned_coarse: None`, as before) and at their skinned positions where their
//! cluster's error allows (the default), without and with the skinned positions' tolerance;
//! bytes, position bits per vertex per frame and the share of zero residuals per band. An OBJ
//! folder is given the skin `pmcodec encode --fit-skin` fits (Le and Deng's SSDR); a glTF keeps
//! its own. With PMC_OUT=dir both files are written there (`before.pmc`, `after.pmc`) for
//! `pmcodec eval --pmc`.
//! `cargo run --release -p pmcodec-container --example skinned_coarse -- ../shared/data/horse-gallop`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{EncodeOptions, QuantizationChoice, Reader, SkinnedCoarse, encode_with_report, payload, summary};
use pmcodec_mesh::skin_fit::{FitOptions, fit_skin};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = Path::new(&args[1]);
    let mut seq = if path.is_dir() {
        pmcodec_mesh::obj::load_obj_sequence(path, 30.0).expect("load")
    } else {
        pmcodec_mesh::gltf_input::load_gltf(path, &Default::default()).expect("load")
    };
    if path.is_dir() {
        let (skin, _) = fit_skin(&seq, &FitOptions::default()).expect("fit");
        seq.skin = Some(skin);
    }
    let (n, frames) = (seq.vertex_count(), seq.frame_count());
    println!("{}: {n} vertices, {frames} frames", path.display());
    // SKINNED_COARSE=error,cells,reach[,joints]: the tolerance of "after" (else the default).
    let after = match std::env::var("SKINNED_COARSE")
        .ok()
        .map(|s| s.split(',').map(|x| x.parse::<f64>().expect("number")).collect::<Vec<_>>())
    {
        Some(t) => {
            SkinnedCoarse { error: t[0], cells: t[1], reach: t[2], joints: t.get(3).copied().unwrap_or(SkinnedCoarse::default().joints) }
        }
        None => SkinnedCoarse::default(),
    };
    let tolerances: Vec<(&str, Option<SkinnedCoarse>)> = vec![("before", None), ("after", Some(after))];
    for (name, skinned_coarse) in tolerances {
        let opts = EncodeOptions { quantization: QuantizationChoice::Bits(12), skinned_coarse, ..Default::default() };
        let (bytes, report) = encode_with_report(&seq, &opts, |_| std::ops::ControlFlow::Continue(())).expect("encode");
        let r = Reader::open(bytes.as_slice()).expect("open");
        let s = summary(&r);
        // Zero residuals per band, over every frame.
        let levels = r.header().levels();
        let mut zeros = vec![(0u64, 0u64); levels];
        for e in r.index().chunks.iter().filter(|e| e.kind == pmcodec_container::ChunkKind::Positions) {
            let raw = r.read_chunk(e).expect("chunk");
            let count = r.header().level_sizes[e.band as usize];
            let (_, res) = payload::read_positions(&raw, "positions", count).expect("positions");
            let z = &mut zeros[e.band as usize];
            z.0 += res.iter().filter(|x| **x == [0; 3]).count() as u64;
            z.1 += res.len() as u64;
        }
        let shares: Vec<String> = zeros.iter().map(|(z, t)| format!("{:.0}%", 100.0 * *z as f64 / (*t).max(1) as f64)).collect();
        println!(
            "  {name:<7} {:>9} bytes, {:.3} bits/vertex/frame, positions {:.3}; skinned bands {} of {}; per band (band 0 first) {:?} B, zero residuals {}",
            bytes.len(),
            bytes.len() as f64 * 8.0 / (n * frames) as f64,
            s.positions_bits_per_vertex_frame,
            report.skinned_bands,
            report.bands,
            s.positions_bytes,
            shares.join(" "),
        );
        if let (Some(dir), "before" | "after") = (std::env::var_os("PMC_OUT"), name) {
            std::fs::write(Path::new(&dir).join(format!("{name}.pmc")), &bytes).expect("write");
        }
    }
}
