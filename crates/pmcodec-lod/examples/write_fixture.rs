//! Writes the built-in test rig ([`pmcodec_lod::fixture`]) as a GLB, the input of the glTF
//! validator run in `tests/run-all.sh` on machines without the shared models.
//!
//! `cargo run -p pmcodec-lod --example write_fixture -- OUT.glb`

fn main() -> anyhow::Result<()> {
    let out = std::env::args().nth(1).ok_or_else(|| anyhow::anyhow!("usage: write_fixture OUT.glb"))?;
    let chain = pmcodec_lod::LodChain::single(pmcodec_lod::fixture::bending_tube_and_face(24, 16))?;
    let bytes = pmcodec_lod::gltf_out::chain_glb(&chain, "none")?;
    pmcodec_mesh::write::write_atomic(std::path::Path::new(&out), &bytes)?;
    println!("wrote {out} ({} triangles)", chain.levels[0].rig.triangles.len());
    Ok(())
}
