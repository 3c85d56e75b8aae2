//! Writes a built-in test rig ([`pmcodec_lod::fixture`]) as a GLB, an input of the glTF
//! validator and three.js runs in `tests/run-all.sh`: the bending tube and face, or with
//! `--character SEED` a generated multi-part character (many small parts, several meshes on one
//! 18-joint skeleton, touching parts; issue 13).
//!
//! `--parts N --meshes M --seconds S` make the character larger and its walk longer (the walk
//! cycle repeated): issue 17's encode-cost character is
//! `--character 17 --parts 3000 --meshes 59 --seconds 35` (about 34,000 vertices in 59 meshes
//! on one skeleton, 35 s of animation).
//!
//! `cargo run -p pmcodec-lod --example write_fixture -- [--character SEED [--parts N]
//! [--meshes M] [--seconds S]] OUT.glb`

use pmcodec_lod::fixture::{CharacterSpec, bending_tube_and_face, multi_part_character};
use pmcodec_mesh::gltf_input::Animation;

/// The animation played `cycles` times back to back (each channel's keys repeated, shifted by
/// the animation's duration).
fn repeat(a: &mut Animation, cycles: u32) {
    let d = a.duration;
    for ch in &mut a.channels {
        let (times, values) = (ch.times.clone(), ch.values.clone());
        for c in 1..cycles {
            // The first key of each repeat falls on the last of the one before: skip it.
            ch.times.extend(times.iter().skip(1).map(|t| t + c as f32 * d));
            let per_key = values.len() / times.len().max(1);
            ch.values.extend(values.iter().skip(per_key).copied());
        }
    }
    a.duration = d * cycles as f32;
}

fn main() -> anyhow::Result<()> {
    let usage = || anyhow::anyhow!("usage: write_fixture [--character SEED [--parts N] [--meshes M] [--seconds S]] OUT.glb");
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((out, flags)) = args.split_last() else { return Err(usage()) };
    let value = |name: &str| -> anyhow::Result<Option<f64>> {
        match flags.iter().position(|a| a == name) {
            None => Ok(None),
            Some(i) => {
                let v = flags.get(i + 1).ok_or_else(usage)?;
                Ok(Some(v.parse().map_err(|_| anyhow::anyhow!("{name} {v:?}: not a number"))?))
            }
        }
    };
    let rig = match value("--character")? {
        None if flags.is_empty() => bending_tube_and_face(24, 16),
        None => return Err(usage()),
        Some(seed) => {
            // Welded parts, some touching (pinches and fins): every budget of the run-all chain
            // stays reachable, so three.js sees fewer triangles at every level.
            let parts = value("--parts")?.unwrap_or(120.0) as usize;
            let meshes = value("--meshes")?.unwrap_or(8.0) as usize;
            let spec = CharacterSpec { seed: seed as u64, parts, meshes, unwelded: false, touching: true, morph: true };
            let mut rig = multi_part_character(&spec);
            if let Some(seconds) = value("--seconds")? {
                for a in &mut rig.animations {
                    let cycles = (seconds / a.duration.max(1e-3) as f64).round().max(1.0) as u32;
                    repeat(a, cycles);
                }
            }
            rig
        }
    };
    let chain = pmcodec_lod::LodChain::single(rig)?;
    let bytes = pmcodec_lod::gltf_out::chain_glb(&chain, "none")?;
    pmcodec_mesh::write::write_atomic(std::path::Path::new(out), &bytes)?;
    let rig = &chain.levels[0].rig;
    println!("wrote {out} ({} vertices, {} triangles, {} meshes)", rig.positions.len(), rig.triangles.len(), rig.instances.len());
    Ok(())
}
