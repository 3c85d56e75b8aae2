//! Skinned streams (issue 17): for each skinned glTF, the `.pmc` at 12-bit quantization with
//! skinning prediction beside the same file without it and the source GLB; bits per vertex per
//! frame; the share of a full client's bytes that clients at 10% and 25% of the triangles read;
//! and the encode time. With `all`, every animation of the file is played back to back.
//! `cargo run --release -p pmcodec-container --example skinned -- ../shared/data/gltf/Fox.glb [all] [centroid]`
//! (`PMC_DERIVED`: below)
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{Decoder, EncodeOptions, PaletteCoding, QuantizationChoice, Reader, SkinPlacement, encode, summary};
use pmcodec_mesh::gltf_input::{GltfOptions, RiggedMesh, load_gltf};
use std::path::Path;

/// Every animation of `path`, sampled at 30 frames per second and played back to back.
fn all_animations(path: &Path) -> pmcodec_mesh::Sequence {
    let mut rig = RiggedMesh::from_path(path).expect("load");
    rig.weld();
    let mut out: Option<pmcodec_mesh::Sequence> = None;
    for a in 0..rig.animations.len() {
        let seq = rig.to_sequence(Some(a), 30.0).expect("sample");
        match out.as_mut() {
            None => out = Some(seq),
            Some(o) => {
                o.frames.extend(seq.frames);
                o.frame_names.extend(seq.frame_names);
                if let (Some(a), Some(b)) = (o.skin.as_mut(), seq.skin) {
                    a.matrices.extend(b.matrices);
                }
            }
        }
    }
    out.expect("the file has animations")
}

/// Bytes a client at `level` reads over the whole file (every chunk it needs).
fn bytes_at(bytes: &[u8], level: usize) -> u64 {
    let r = Reader::open(bytes).expect("open");
    r.index().chunks.iter().filter(|e| r.reads(e, level)).map(|e| e.stored_len as u64).sum::<u64>() + r.data_start()
}

/// `PMC_DERIVED=never|always|when-cheaper`: which bands derive their faces (default: the encoder's).
fn derived_topology() -> pmcodec_container::DerivedTopology {
    match std::env::var("PMC_DERIVED").as_deref() {
        Ok("never") => pmcodec_container::DerivedTopology::Never,
        Ok("when-cheaper") => pmcodec_container::DerivedTopology::WhenCheaper,
        _ => EncodeOptions::default().derived_topology,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = Path::new(&args[1]);
    let all = args.iter().any(|a| a == "all");
    let placement = if args.iter().any(|a| a == "centroid") { SkinPlacement::Centroid } else { SkinPlacement::BackPropagated };
    let seq = if all { all_animations(path) } else { load_gltf(path, &GltfOptions::default()).expect("load") };
    let glb = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let (n, frames) = (seq.vertex_count(), seq.frame_count());
    println!(
        "{}: {n} vertices, {} triangles, {frames} frames, palette {}; GLB {glb} bytes",
        path.display(),
        seq.triangles.len(),
        seq.skin.as_ref().map_or(0, |s| s.palette_len)
    );
    // Without skin; skinned with the palettes in Palette chunks (as before the Joints chunk);
    // skinned as today's encoder writes it (Joints chunks).
    // Joints chunks in the plain coding only (as before the linked coding), then as today.
    for (skin, palette_coding) in [
        (None, PaletteCoding::Joints),
        (Some(placement), PaletteCoding::Palette),
        (Some(placement), PaletteCoding::JointsPlain),
        (Some(placement), PaletteCoding::Joints),
    ] {
        let opts = EncodeOptions {
            quantization: QuantizationChoice::Bits(12),
            skin,
            palette_coding,
            derived_topology: derived_topology(),
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let secs = t.elapsed().as_secs_f64();
        let r = Reader::open(bytes.as_slice()).expect("open");
        let s = summary(&r);
        // Stored bytes and chunk count per kind, and what the preamble, header and index take.
        let mut kinds: std::collections::BTreeMap<&str, (u64, u64)> = Default::default();
        for e in &r.index().chunks {
            let k = kinds.entry(e.kind.name()).or_default();
            k.0 += e.stored_len as u64;
            k.1 += 1;
        }
        let table: Vec<String> = kinds.iter().map(|(k, (b, c))| format!("{k} {b} B in {c}")).collect();
        println!("    preamble, header and index {} B; {}", r.data_start(), table.join(", "));
        println!("    positions per band (band 0 first): {:?} B", s.positions_bytes);
        // PMC_OUT=dir: the skinned file, and every frame's quantized node positions as the Rust
        // decoder stores them at levels 0 and 1 (i32 little-endian, frame after frame), for
        // comparing other decoders with.
        if let (Some(dir), Some(_), PaletteCoding::Joints) = (std::env::var_os("PMC_OUT"), skin, palette_coding) {
            std::fs::write(Path::new(&dir).join("skinned.pmc"), &bytes).expect("write");
            for level in [0, 1] {
                let mut d = Decoder::new(r.borrowed(), level).expect("decoder");
                let mut out = Vec::new();
                for f in 0..r.header().frame_count {
                    d.seek(f).expect("frame");
                    out.extend(d.quantized().iter().flatten().flat_map(|v| v.to_le_bytes()));
                }
                std::fs::write(Path::new(&dir).join(format!("skinned-level{level}.q")), out).expect("write");
            }
        }
        let full = bytes_at(&bytes, 0) as f64;
        // The levels the default anchors put at 25% and 10% of the input.
        let sizes = &s.header.level_sizes;
        let tris = |l: usize| {
            let mut d = Decoder::new(r.borrowed(), l).expect("decoder");
            d.seek(0).expect("frame 0");
            d.mesh(pmcodec_container::CutTarget::Level(l)).expect("mesh").triangles.len() as f64 / seq.triangles.len() as f64
        };
        let level_of = |share: f64| (0..sizes.len()).rev().find(|&l| tris(l) >= share * 0.999).unwrap_or(0);
        let (l25, l10) = (level_of(0.25), level_of(0.10));
        println!(
            "  {:<24} {:>9} bytes ({:.2}x the GLB), {:.3} bits/vertex/frame (positions {:.3}, pose {:.0} B/frame, bind {} B); \
             a client at 25% (level {l25}, {:.1}% of triangles) reads {:.1}%, at 10% (level {l10}, {:.1}%) {:.1}%; encoded in {secs:.1} s",
            match skin {
                None => "without skin".to_string(),
                Some(p) => format!("skinned {p:?} {palette_coding:?}"),
            },
            bytes.len(),
            bytes.len() as f64 / glb.max(1) as f64,
            bytes.len() as f64 * 8.0 / (n * frames) as f64,
            s.positions_bits_per_vertex_frame,
            s.pose_bytes as f64 / frames as f64,
            s.bind_bytes.iter().sum::<u64>(),
            100.0 * tris(l25),
            100.0 * bytes_at(&bytes, l25) as f64 / full,
            100.0 * tris(l10),
            100.0 * bytes_at(&bytes, l10) as f64 / full,
        );
    }
}
