//! Issue 17, "overhead on small meshes": a file's bits per vertex per frame beyond its position
//! bits (tables, chunk framing, index), written as files were before the preamble flags (every
//! chunk a zstd frame, empty ones too) and as today's encoder writes them (`format::FLAGS`),
//! with the bytes of each chunk kind and of the preamble, header and index (and what the index
//! took in version 6).
//! Without arguments: a generated waving cloth of 54 x 54 = 2,916 vertices and 200 frames; with
//! a glTF path, its animations played back to back (as the `skinned` example); with a folder,
//! its OBJ frames (the horse, the cat).
//! `cargo run --release -p pmcodec-container --example overhead -- [file.glb | folder]`
//! (`PMC_K`, `PMC_SUBDIVIDE`, `PMC_FRAMES`, `PMC_DERIVED`: below).
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{ChunkKind, EncodeOptions, QuantizationChoice, Reader, encode, summary};
use pmcodec_mesh::gltf_input::RiggedMesh;
use std::collections::BTreeMap;

fn main() {
    let seq = match std::env::args().nth(1) {
        None => pmcodec_mesh::samples::waving_cloth(54, 54, 200),
        Some(path) if std::path::Path::new(&path).is_dir() => {
            pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&path), 30.0).expect("load")
        }
        Some(path) => {
            let mut rig = RiggedMesh::from_path(std::path::Path::new(&path)).expect("load");
            rig.weld();
            let mut out: Option<pmcodec_mesh::Sequence> = None;
            for a in 0..rig.animations.len() {
                let s = rig.to_sequence(Some(a), 30.0).expect("sample");
                match out.as_mut() {
                    None => out = Some(s),
                    Some(o) => {
                        o.frames.extend(s.frames);
                        o.frame_names.extend(s.frame_names);
                        if let (Some(a), Some(b)) = (o.skin.as_mut(), s.skin) {
                            a.matrices.extend(b.matrices);
                        }
                    }
                }
            }
            out.expect("animations")
        }
    };
    // `PMC_SUBDIVIDE=N`: the sequence Loop-subdivided N times, every frame from that frame's
    // positions (`pmcodec_eval::made`; the skin is dropped), so that a small model (Fox, 1,728
    // unindexed vertices) makes the ~3,000-vertex sequence issue 17's overhead bar asks for.
    // `PMC_FRAMES=N`: its first N frames, played again from the start when it has fewer.
    let mut seq = seq;
    for _ in 0..std::env::var("PMC_SUBDIVIDE").ok().and_then(|k| k.parse().ok()).unwrap_or(0u32) {
        seq = pmcodec_eval::made::loop_subdivide(&seq);
    }
    if let Some(n) = std::env::var("PMC_FRAMES").ok().and_then(|k| k.parse().ok()) {
        let had = seq.frames.len();
        if n > had {
            // The skin's per-frame matrices are not repeated: encoded as any other sequence.
            seq.skin = None;
        }
        seq.frames = (0..n).map(|f| seq.frames[f % had].clone()).collect();
        seq.frame_names = (0..n).map(|f| format!("frame-{f:04}")).collect();
    }
    let (n, frames) = (seq.vertex_count(), seq.frame_count());
    let per = |bytes: u64| bytes as f64 * 8.0 / (n * frames) as f64;
    println!("{n} vertices, {frames} frames, 12-bit quantization");
    // `PMC_K=32`: another keyframe interval (the encoder's default is 16).
    let k = std::env::var("PMC_K").ok().and_then(|k| k.parse().ok()).unwrap_or(EncodeOptions::default().keyframe_interval);
    for flags in [0, pmcodec_container::format::FLAGS] {
        // `PMC_DERIVED=never|when-cheaper`: bands that send their faces (default: the encoder's).
        let derived_topology = match std::env::var("PMC_DERIVED").as_deref() {
            Ok("never") => pmcodec_container::DerivedTopology::Never,
            Ok("when-cheaper") => pmcodec_container::DerivedTopology::WhenCheaper,
            _ => EncodeOptions::default().derived_topology,
        };
        let opts = EncodeOptions {
            quantization: QuantizationChoice::Bits(12),
            chunk_flags: flags,
            keyframe_interval: k,
            derived_topology,
            ..Default::default()
        };
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let r = Reader::open(bytes.as_slice()).expect("open");
        let s = summary(&r);
        let total = per(bytes.len() as u64);
        let stored = r.index().chunks.iter().filter(|e| e.stored_len == e.raw_len).count();
        println!(
            "  version {} flags {flags}: {} bytes, {total:.3} bits/vertex/frame, positions {:.3}, overhead {:.3}; \
             {} chunks ({stored} stored as is), preamble+header+index {} B; levels {:?}",
            r.version(),
            bytes.len(),
            s.positions_bits_per_vertex_frame,
            total - s.positions_bits_per_vertex_frame,
            r.index().chunks.len(),
            r.data_start(),
            r.header().level_sizes,
        );
        let pre = pmcodec_container::format::Preamble::parse(&bytes).expect("preamble");
        let (header_len, index_len) = (pre.header_len as u64, pre.index_len as u64);
        println!("    {:<12} {:>6} chunks {:>9} B {:>7.3} bits/v/f", "preamble", 1, 32, per(32));
        println!("    {:<12} {:>6}        {:>9} B {:>7.3} bits/v/f", "header", "", header_len, per(header_len));
        println!(
            "    {:<12} {:>6}        {:>9} B {:>7.3} bits/v/f ({:.1} B per entry)",
            "index",
            "",
            index_len,
            per(index_len),
            index_len as f64 / r.index().chunks.len().max(1) as f64
        );
        // The same entries as version 6 wrote them (postcard, every entry whole), for comparison.
        let v6 = r.index().to_bytes(6, r.header().frame_count).expect("index").len() as u64;
        println!("    {:<12} {:>6}        {:>9} B {:>7.3} bits/v/f (as version 6 wrote it)", "index v6", "", v6, per(v6));
        // Bytes, chunks and items (the count each payload starts with: moves, corner updates,
        // faces) per kind and band.
        let mut kinds: BTreeMap<(u32, u32), (usize, u64, u64, usize)> = BTreeMap::new();
        for e in &r.index().chunks {
            let k = kinds.entry((u32::from(e.kind), e.band)).or_default();
            k.0 += 1;
            k.1 += e.stored_len as u64;
            if matches!(e.kind, ChunkKind::Key | ChunkKind::Delta | ChunkKind::Corners | ChunkKind::Faces) {
                let raw = r.read_chunk(e).expect("chunk");
                // A coded payload (a 0, then its coding: proto/container.md, Faces and
                // Corners) holds its count in its bit stream: counted apart.
                if raw.len() >= 2 && raw[0] == 0 {
                    k.3 += 1;
                } else {
                    k.2 += pmcodec_container::payload::Cursor::new(&raw, "count").get().expect("count") as u64;
                }
            }
        }
        let mut by_kind: BTreeMap<u32, (usize, u64)> = BTreeMap::new();
        for (&(k, _), &(count, b, _, _)) in &kinds {
            let t = by_kind.entry(k).or_default();
            t.0 += count;
            t.1 += b;
        }
        for (k, (count, b)) in by_kind {
            let name = ChunkKind::try_from(k).map_or("?", |k| k.name());
            println!("    {name:<12} {count:>6} chunks {b:>9} B {:>7.3} bits/v/f", per(b));
            for (&(_, band), &(c, bb, items, coded)) in kinds.range((k, 0)..(k + 1, 0)) {
                if matches!(k, 1 | 2 | 4 | 5) {
                    println!(
                        "      band {band}: {c:>5} chunks {bb:>8} B, {coded} bit-coded, {items:>7} items in the others, {:.2} B per item",
                        bb as f64 / items.max(1) as f64
                    );
                }
            }
        }
        // The Triangles chunk as the varint coding alone would store it (before its coding 1).
        let varints = pmcodec_container::payload::write_triangles(&seq.triangles, r.version());
        let z = pmcodec_container::format::compress(&varints, pmcodec_container::format::ZSTD_LEVEL)
            .map_or(varints.len(), |z| z.len().min(varints.len()));
        println!("    triangles as varint differences alone: {z} B stored ({:.3} bits/v/f)", per(z as u64));
        // Keyframe parent maps against frame 0's (which every client reads) and against the
        // keyframe before: how many nodes changed their parent (proto/container.md, Key coding 3).
        let h = r.header();
        for j in 0..h.levels().saturating_sub(1) {
            let key = |f: u32, first: Option<&[u32]>| {
                let e = r.find(ChunkKind::Key, f, j as u32)?;
                pmcodec_container::payload::read_key_from(&r.read_chunk(e).ok()?, "k", &h.level_sizes, j, r.version(), first).ok()
            };
            let Some(first) = key(0, None) else { continue };
            let mut coded = 0;
            let (mut from0, mut fromprev, mut keys) = (0usize, 0usize, 0usize);
            let mut prev = first.clone();
            for f in (1..h.frame_count).filter(|&f| r.find(ChunkKind::Key, f, j as u32).is_some()) {
                let Some(p) = key(f, Some(&first)) else { continue };
                coded += r
                    .find(ChunkKind::Key, f, j as u32)
                    .and_then(|e| r.read_chunk(e).ok())
                    .is_some_and(|raw| pmcodec_container::payload::key_from_first(&raw)) as usize;
                from0 += p.iter().zip(&first).filter(|(a, b)| a != b).count();
                fromprev += p.iter().zip(&prev).filter(|(a, b)| a != b).count();
                keys += 1;
                prev = p;
            }
            println!(
                "      band {j}: {} nodes, {keys} keyframes after 0 ({coded} coding 3): {:.1}% of parents differ from frame 0's, {:.1}% from the keyframe before's",
                first.len(),
                100.0 * from0 as f64 / (keys * first.len()).max(1) as f64,
                100.0 * fromprev as f64 / (keys * first.len()).max(1) as f64
            );
        }
    }
}
