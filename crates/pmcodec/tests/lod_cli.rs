//! `pmcodec lod` end to end on the built-in test rigs: a chain written, read back by the `gltf`
//! crate and by our reader, the report printed; a generated multi-part character with the
//! options that crashed on the Khronos one (issue 13); bad requests get exit code 3 and no
//! output.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pmcodec"))
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pmcodec-lod-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn fixture(dir: &std::path::Path) -> PathBuf {
    let chain = pmcodec_lod::LodChain::single(pmcodec_lod::fixture::bending_tube_and_face(16, 12)).unwrap();
    let path = dir.join("rig.glb");
    std::fs::write(&path, pmcodec_lod::gltf_out::chain_glb(&chain, "none").unwrap()).unwrap();
    path
}

#[test]
fn lod_writes_a_chain_and_reports() {
    let dir = temp("ok");
    let input = fixture(&dir);
    let out = dir.join("lod.glb");
    let run = bin()
        .args(["lod", "--triangles", "50%,20%", "--placement", "blended", "--weighting", "smooth", "--report"])
        .args(["--pose-weight", "rest=2,bend=1"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report = String::from_utf8_lossy(&run.stdout);
    assert!(report.contains("lod1") && report.contains("lod2"), "{report}");
    let bytes = std::fs::read(&out).unwrap();
    let g = gltf::Gltf::from_slice(&bytes).expect("gltf crate reads it");
    assert_eq!(g.scenes().count(), 3);
    assert_eq!(g.animations().count(), 1);
    assert!(g.skins().count() >= 1);
    let back = pmcodec_mesh::gltf_input::RiggedMesh::from_bytes(&bytes).expect("our reader reads it");
    assert_eq!(back.animations.len(), 1);
}

#[test]
fn lod_bad_requests_exit_3() {
    let dir = temp("bad");
    let input = fixture(&dir);
    let out = dir.join("never.glb");
    for triangles in ["0", "abc", "150%", "10,20", "100000"] {
        let run = bin().args(["-q", "lod", "--triangles", triangles]).arg(&input).arg("-o").arg(&out).output().unwrap();
        assert_eq!(run.status.code(), Some(3), "--triangles {triangles}: {}", String::from_utf8_lossy(&run.stderr));
        assert!(!out.exists());
    }
    let run = bin().args(["-q", "lod", "--triangles", "10", "--pose-weight", "nope=1"]).arg(&input).arg("-o").arg(&out).output().unwrap();
    assert_eq!(run.status.code(), Some(3));
    let junk = dir.join("junk.glb");
    std::fs::write(&junk, b"not a glb").unwrap();
    let run = bin().args(["-q", "lod", "--triangles", "10"]).arg(&junk).arg("-o").arg(&out).output().unwrap();
    assert_eq!(run.status.code(), Some(3));
    assert!(!String::from_utf8_lossy(&run.stderr).is_empty());
    assert!(!out.exists());
}

/// The commands of issue 13 that failed on a multi-part skinned character ("level 0 vertex N
/// merged into N, which level 1 does not use"), on a generated one: many small parts, some
/// touching, some split at seams, several meshes on one 18-joint skeleton.
#[test]
fn lod_multi_part_character() {
    use pmcodec_lod::fixture::{CharacterSpec, multi_part_character};
    let dir = temp("character");
    let spec = CharacterSpec { seed: 13, parts: 50, meshes: 6, unwelded: true, touching: true, morph: false };
    let chain = pmcodec_lod::LodChain::single(multi_part_character(&spec)).unwrap();
    let input = dir.join("character.glb");
    std::fs::write(&input, pmcodec_lod::gltf_out::chain_glb(&chain, "none").unwrap()).unwrap();
    for (triangles, placement) in [("25%,10%", "endpoint"), ("50%,25%,10%,5%", "endpoint"), ("25%,10%", "houle-poulin")] {
        let out = dir.join(format!("lod-{placement}-{}.glb", triangles.len()));
        let run = bin().args(["lod", "--triangles", triangles, "--placement", placement]).arg(&input).arg("-o").arg(&out).output().unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "--triangles {triangles} --placement {placement}: {stderr}");
        let bytes = std::fs::read(&out).unwrap();
        let g = gltf::Gltf::from_slice(&bytes).expect("gltf crate reads it");
        let levels = triangles.split(',').count() + 1;
        assert_eq!(g.scenes().count(), levels);
        // Every level above its target is named in a warning.
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
        let described = json["extras"]["pmcodec_lod"]["levels"].as_array().unwrap();
        for (k, level) in described.iter().enumerate() {
            let above = level["target"].as_u64().is_some_and(|t| level["triangles"].as_u64().unwrap() > t);
            assert_eq!(stderr.contains(&format!("warning: lod{k} has")), above, "level {k} {level}: {stderr}");
        }
    }
}

/// Bad appearance input (issue 16): a texture whose file is missing, an image that is neither
/// PNG nor JPEG. Exit code 3, a message naming the image, nothing written.
#[test]
fn lod_bad_textures_exit_3() {
    let fox = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/gltf/Fox.glb"));
    assert!(fox.is_file(), "{} is absent; this test reads the real models in ../shared/data", fox.display());
    let bytes = std::fs::read(&fox).unwrap();
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    let chunk = &bytes[20 + len + 8..];
    // The Fox's own binary chunk under an edited JSON chunk, by the workspace's GLB assembler.
    let glb = |doc: &serde_json::Value| pmcodec_mesh::glb::assemble(doc, chunk.to_vec()).unwrap();
    let dir = temp("textures");
    let out = dir.join("never.glb");
    let mut missing = doc.clone();
    missing["images"][0] = serde_json::json!({"uri": "fox_skin.png"});
    let mut gif = doc.clone();
    // Point the image at the first view of the buffer (vertex data), which is not an image.
    gif["images"][0] = serde_json::json!({"bufferView": 0, "mimeType": "image/png"});
    for (name, doc, says) in [("missing.glb", &missing, "fox_skin.png"), ("notpng.glb", &gif, "neither PNG nor JPEG")] {
        let input = dir.join(name);
        std::fs::write(&input, glb(doc)).unwrap();
        let run = bin().args(["-q", "lod", "--triangles", "50%"]).arg(&input).arg("-o").arg(&out).output().unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(3), "{name}: {stderr}");
        assert!(stderr.contains("image 0") && stderr.contains(says) && stderr.contains(name), "{name}: {stderr}");
        assert!(!out.exists(), "{name}: nothing is written");
    }
}
