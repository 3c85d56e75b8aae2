//! Skinned streams (issue 17): for each skinned glTF, the `.pmc` at 12-bit quantization with
//! skinning prediction beside the same file without it and the source GLB; bits per vertex per
//! frame; the share of a full client's bytes that clients at 10% and 25% of the triangles read
//! (with and without the texture images, which the server also serves at their own URLs), what
//! a 10% client reads by chunk kind, and per band the palette entries its Joints chunks carry;
//! and the encode time. With `all`, every animation of the file is played back to back. Rows:
//! skinned with every joint at every level (`joints 0`), then with the skeleton's level of
//! detail at each threshold of `PMC_JOINTS` (comma-separated; default today's encoder's, 0.25);
//! `codings` adds the older Palette and plain Joints codings. A folder of OBJ frames is given
//! the skin `pmcodec encode --fit-skin` fits.
//! `cargo run --release -p pmcodec-container --example skinned -- ../shared/data/gltf/Fox.glb [all] [centroid] [codings]`
//! (`PMC_DERIVED`, `PMC_BANDS`: below)
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{
    ChunkKind, Decoder, EncodeOptions, PaletteCoding, QuantizationChoice, Reader, SkinPlacement, SkinnedCoarse, encode, summary,
};
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

/// Bytes a client at `level` reads over the whole file (every chunk it needs), and of them the
/// texture images'.
/// It is what the server's `/stream?level=L` sends (`pmcodec_container::streams`): the head
/// (of a banded index, only its level's groups) and the chunks of its level.
fn bytes_at(bytes: &[u8], level: usize) -> (u64, u64) {
    let r = Reader::open_at(bytes, level).expect("open");
    let len = |r: &std::ops::Range<u64>| r.end - r.start;
    let head: u64 = pmcodec_container::streams::head_ranges(bytes, level).expect("head").iter().map(len).sum();
    let chunks = pmcodec_container::streams::chunks_for(&r.index().chunks, r.header(), level, 0);
    let (mut all, mut images) = (head, 0);
    for (_, e) in chunks {
        all += e.stored_len as u64;
        if e.kind == ChunkKind::Image {
            images += e.stored_len as u64;
        }
    }
    (all, images)
}

/// What a client at `level` reads, by chunk kind (and band for Bind and Joints chunks), largest
/// first, beside the preamble, header and index.
fn read_by_kind(r: &Reader<&[u8]>, level: usize) -> String {
    let r = &Reader::open_at(*r.source(), level).expect("open");
    let mut kinds: std::collections::BTreeMap<String, u64> = Default::default();
    for e in r.index().chunks.iter().filter(|e| r.reads(e, level)) {
        let name = match e.kind {
            ChunkKind::Bind | ChunkKind::Joints => format!("{} band {}", e.kind.name(), e.band),
            k => k.name().to_string(),
        };
        *kinds.entry(name).or_default() += e.stored_len as u64;
    }
    let mut rows: Vec<(String, u64)> = kinds.into_iter().collect();
    rows.push(("preamble, header and index".into(), r.bytes_read()));
    rows.sort_by_key(|r| std::cmp::Reverse(r.1));
    rows.iter().map(|(k, b)| format!("{k} {b}")).collect::<Vec<_>>().join(", ")
}

/// Per band (band 0 first): nodes, the palette entries its nodes use, the entries its Joints
/// chunks carry (used by it and by no coarser band), and its Joints chunks' bytes.
fn bands(r: &Reader<&[u8]>) -> String {
    let h = r.header();
    let mut d = Decoder::new(r.borrowed(), 0).expect("decoder");
    d.seek(0).expect("frame 0");
    let Some((nodes, _)) = d.skin() else { return String::new() };
    let mut taken = std::collections::BTreeSet::new();
    let mut out = vec![String::new(); h.levels()];
    let mut from = h.level_sizes.iter().sum::<u32>() as usize;
    for j in (0..h.levels()).rev() {
        let to = from;
        from -= h.level_sizes[j] as usize;
        let used: std::collections::BTreeSet<u32> =
            nodes[from..to].iter().flat_map(|n| n.joints.iter().zip(&n.weights).filter(|p| *p.1 > 0).map(|p| *p.0)).collect();
        let carried = used.iter().filter(|e| !taken.contains(*e)).count();
        taken.extend(used.iter().copied());
        let joints: u64 =
            r.index().chunks.iter().filter(|e| e.kind == ChunkKind::Joints && e.band as usize == j).map(|e| e.stored_len as u64).sum();
        out[j] = format!("band {j}: {} nodes, uses {} entries, carries {carried}, joints {joints} B", h.level_sizes[j], used.len());
    }
    out.join("; ")
}

/// `PMC_DERIVED=never|always|when-cheaper|per-band`: which bands derive their faces (default: the encoder's).
fn derived_topology() -> pmcodec_container::DerivedTopology {
    match std::env::var("PMC_DERIVED").as_deref() {
        Ok("never") => pmcodec_container::DerivedTopology::Never,
        Ok("when-cheaper") => pmcodec_container::DerivedTopology::WhenCheaper,
        Ok("always") => pmcodec_container::DerivedTopology::Always,
        Ok("per-band") => pmcodec_container::DerivedTopology::PerBand,
        _ => EncodeOptions::default().derived_topology,
    }
}

/// `PMC_BANDS=1`: the banded index (the default), which coarse clients read in part;
/// `PMC_BANDS=0` the frame-by-frame one (`pmcodec encode --frame-index`); unset: the encoder's
/// flags.
fn chunk_flags() -> u16 {
    let flags = EncodeOptions::default().chunk_flags;
    match std::env::var("PMC_BANDS").as_deref() {
        Ok("1") => flags | pmcodec_container::format::FLAG_BANDS,
        Ok("0") => flags & !pmcodec_container::format::FLAG_BANDS,
        _ => flags,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = Path::new(&args[1]);
    let all = args.iter().any(|a| a == "all");
    let placement = if args.iter().any(|a| a == "centroid") { SkinPlacement::Centroid } else { SkinPlacement::BackPropagated };
    let seq = if path.is_dir() {
        let mut seq = pmcodec_mesh::obj::load_obj_sequence(path, 30.0).expect("load");
        let fit = pmcodec_mesh::skin_fit::FitOptions { quant_bits: 12, ..Default::default() };
        seq.skin = Some(pmcodec_mesh::skin_fit::fit_skin(&seq, &fit).expect("fit").0);
        seq
    } else if all {
        all_animations(path)
    } else {
        load_gltf(path, &GltfOptions::default()).expect("load")
    };
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
    let thresholds: Vec<f64> = std::env::var("PMC_JOINTS")
        .map(|s| s.split(',').map(|x| x.parse().expect("a number")).collect())
        .unwrap_or_else(|_| vec![SkinnedCoarse::default().joints]);
    let mut rows = vec![(None, PaletteCoding::Joints, 0.0)];
    if args.iter().any(|a| a == "codings") {
        rows.extend([(Some(placement), PaletteCoding::Palette, 0.0), (Some(placement), PaletteCoding::JointsPlain, 0.0)]);
    }
    rows.push((Some(placement), PaletteCoding::Joints, 0.0));
    rows.extend(thresholds.iter().filter(|&&t| t > 0.0).map(|&t| (Some(placement), PaletteCoding::Joints, t)));
    for (skin, palette_coding, joints) in rows {
        let skinned_coarse = Some(SkinnedCoarse { joints, ..Default::default() });
        let opts = EncodeOptions {
            quantization: QuantizationChoice::Bits(12),
            skin,
            palette_coding,
            skinned_coarse,
            derived_topology: derived_topology(),
            chunk_flags: chunk_flags(),
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
        println!("    preamble, header and index {} B (flags {}); {}", r.data_start(), r.flags(), table.join(", "));
        println!("    positions per band (band 0 first): {:?} B", s.positions_bytes);
        // PMC_OUT=dir: each skinned file in the Joints coding (`skinned-joints{threshold}.pmc`,
        // for `pmcodec eval --pmc`), and every frame's quantized node positions as the Rust
        // decoder stores them at levels 0 and 1 (i32 little-endian, frame after frame; the last
        // such row's), for comparing other decoders with.
        if let (Some(dir), Some(_), PaletteCoding::Joints) = (std::env::var_os("PMC_OUT"), skin, palette_coding) {
            std::fs::write(Path::new(&dir).join(format!("skinned-joints{joints}.pmc")), &bytes).expect("write");
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
        let full = bytes_at(&bytes, 0);
        // The levels the default anchors put at 25% and 10% of the input.
        let sizes = &s.header.level_sizes;
        let tris = |l: usize| {
            let mut d = Decoder::new(r.borrowed(), l).expect("decoder");
            d.seek(0).expect("frame 0");
            d.mesh(pmcodec_container::CutTarget::Level(l)).expect("mesh").triangles.len() as f64 / seq.triangles.len() as f64
        };
        let level_of = |share: f64| (0..sizes.len()).rev().find(|&l| tris(l) >= share * 0.999).unwrap_or(0);
        let (l25, l10) = (level_of(0.25), level_of(0.10));
        // Shares of a full client's bytes, with the texture images and without (they are
        // served at their own URLs too, and a client may already hold them).
        let share = |l: usize| {
            let (b, i) = bytes_at(&bytes, l);
            (100.0 * b as f64 / full.0 as f64, 100.0 * (b - i) as f64 / (full.0 - full.1).max(1) as f64)
        };
        if skin.is_some() {
            println!("    {}", bands(&r));
            println!("    a 10% client reads: {}", read_by_kind(&r, l10));
            let top = sizes.len() - 1;
            println!("    every client (the coarsest, level {top}) reads: {} of {} B", read_by_kind(&r, top), full.0);
        }
        println!(
            "  {:<24} {:>9} bytes ({:.2}x the GLB), {:.3} bits/vertex/frame (positions {:.3}, pose {:.0} B/frame, bind {} B); \
             a client at 25% (level {l25}, {:.1}% of triangles) reads {:.1}% ({:.1}% without images), at 10% (level {l10}, {:.1}%) {:.1}% ({:.1}%); encoded in {secs:.1} s",
            match skin {
                None => "without skin".to_string(),
                Some(p) => format!("skinned {p:?} {palette_coding:?} joints {joints}"),
            },
            bytes.len(),
            bytes.len() as f64 / glb.max(1) as f64,
            bytes.len() as f64 * 8.0 / (n * frames) as f64,
            s.positions_bits_per_vertex_frame,
            s.pose_bytes as f64 / frames as f64,
            s.bind_bytes.iter().sum::<u64>(),
            100.0 * tris(l25),
            share(l25).0,
            share(l25).1,
            100.0 * tris(l10),
            share(l10).0,
            share(l10).1,
        );
    }
}
