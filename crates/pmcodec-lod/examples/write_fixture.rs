//! Writes a built-in test rig ([`pmcodec_lod::fixture`]) as a GLB, an input of the glTF
//! validator and three.js runs in `tests/run-all.sh`: the bending tube and face, or with
//! `--character SEED` a generated multi-part character (many small parts, several meshes on one
//! 18-joint skeleton, touching parts; issue 13).
//!
//! `cargo run -p pmcodec-lod --example write_fixture -- [--character SEED] OUT.glb`

use pmcodec_lod::fixture::{CharacterSpec, bending_tube_and_face, multi_part_character};

fn main() -> anyhow::Result<()> {
    let usage = || anyhow::anyhow!("usage: write_fixture [--character SEED] OUT.glb");
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (rig, out) = match args.as_slice() {
        [out] => (bending_tube_and_face(24, 16), out),
        [flag, seed, out] if flag == "--character" => {
            let seed = seed.parse().map_err(|_| anyhow::anyhow!("--character {seed:?}: not a number"))?;
            // Welded parts, some touching (pinches and fins): every budget of the run-all chain
            // stays reachable, so three.js sees fewer triangles at every level.
            let spec = CharacterSpec { seed, parts: 120, meshes: 8, unwelded: false, touching: true, morph: true };
            (multi_part_character(&spec), out)
        }
        _ => return Err(usage()),
    };
    let chain = pmcodec_lod::LodChain::single(rig)?;
    let bytes = pmcodec_lod::gltf_out::chain_glb(&chain, "none")?;
    pmcodec_mesh::write::write_atomic(std::path::Path::new(out), &bytes)?;
    println!("wrote {out} ({} triangles, {} meshes)", chain.levels[0].rig.triangles.len(), chain.levels[0].rig.instances.len());
    Ok(())
}
