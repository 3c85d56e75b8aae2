//! `encode --fit-skin` tells whether the fitted skin pays from a trial before the encode
//! (`--skin-choice estimate`, the default: one encode) and keeps or drops it as the exhaustive
//! choice (`--skin-choice exhaustive`: the file encoded with and without it) does, on rigid
//! parts (kept) and a waving cloth (dropped).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn frames(name: &str, seq: &pmcodec_mesh::Sequence) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pmcodec-skin-choice-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for (f, positions) in seq.frames.iter().enumerate() {
        let mesh = pmcodec_mesh::TriMesh { positions: positions.clone(), triangles: seq.triangles.clone() };
        let file = std::fs::File::create(d.join(format!("f{f:03}.obj"))).unwrap();
        pmcodec_mesh::write::write_obj(std::io::BufWriter::new(file), &mesh).unwrap();
    }
    d
}

fn encode(dir: &Path, choice: &str) -> (serde_json::Value, u64) {
    let out = dir.join(format!("{choice}.pmc"));
    let o = Command::new(env!("CARGO_BIN_EXE_pmcodec"))
        .args(["encode", "-q", "--keyframe-interval", "8", "--quant-bits", "12", "--fit-skin", "--json", "--skin-choice", choice])
        .arg(dir)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (serde_json::from_slice(&o.stdout).unwrap(), std::fs::metadata(&out).unwrap().len())
}

#[test]
fn the_trial_keeps_or_drops_the_fitted_skin_as_the_exhaustive_choice_does() {
    for (name, seq, kept) in
        [("parts", pmcodec_mesh::samples::rigid_parts(4, 16), true), ("cloth", pmcodec_mesh::samples::waving_cloth(24, 16, 16), false)]
    {
        let dir = frames(name, &seq);
        let (estimate, bytes) = encode(&dir, "estimate");
        let (exhaustive, exhaustive_bytes) = encode(&dir, "exhaustive");
        let (e, x) = (&estimate["fitted_skin"], &exhaustive["fitted_skin"]);
        assert_eq!(e["used"], kept, "{name}: {e}");
        assert_eq!(x["used"], kept, "{name}: {x}");
        // The trial ran (and was reported) only where it was asked for.
        assert!(e["trial"]["frames_coded"].as_u64().unwrap() > 0, "{name}: {e}");
        assert!(x["trial"].is_null(), "{name}: {x}");
        // Dropped, both wrote the plain file; kept, the exhaustive choice may have kept the
        // file with every joint at every level, never a larger one.
        if kept {
            assert!(exhaustive_bytes <= bytes, "{name}: {exhaustive_bytes} > {bytes}");
        } else {
            assert_eq!(bytes, exhaustive_bytes, "{name}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
