//! Writes a generated skinned character (`pmcodec_mesh::samples::skinned_character`) as a GLB:
//! by default issue 17's shape, 59 parts of 578 vertices (34,102) on one skeleton of 57 joints,
//! animated for 35 s. Deterministic.
//!
//! `cargo run -p pmcodec-mesh --example make_character -- OUT.glb [--parts N] [--limbs N]
//! [--chain N] [--segments N] [--rings N] [--seconds S] [--seed N]`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_mesh::samples::{CharacterOptions, skinned_character};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args.first().expect("usage: make_character OUT.glb [--parts N] ...");
    let mut opts = CharacterOptions::default();
    let mut i = 1;
    while i + 1 < args.len() {
        let (flag, value) = (&args[i], &args[i + 1]);
        let int = || value.parse::<u32>().expect("a whole number");
        match flag.as_str() {
            "--parts" => opts.parts = int(),
            "--limbs" => opts.limbs = int(),
            "--chain" => opts.chain = int(),
            "--segments" => opts.segments = int(),
            "--rings" => opts.rings = int(),
            "--seconds" => opts.seconds = value.parse().expect("seconds"),
            "--seed" => opts.seed = value.parse().expect("a seed"),
            other => panic!("unknown option {other}"),
        }
        i += 2;
    }
    let glb = skinned_character(&opts).expect("generate");
    std::fs::write(out, &glb).expect("write");
    let vertices = opts.parts as u64 * (opts.segments as u64 * opts.rings as u64 + 2);
    eprintln!(
        "{out}: {} bytes, {} parts, {vertices} vertices, {} joints, {} s",
        glb.len(),
        opts.parts,
        1 + opts.limbs * opts.chain,
        opts.seconds
    );
}
