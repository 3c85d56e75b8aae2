//! Container sizes beside the references of the issue: raw float positions, every frame
//! compressed on its own with zstd, and the paper's per-frame figures.
//! `cargo run --release -p pmcodec-container --example sizes -- ../shared/data/horse-gallop [bits] [coarse grid k|none]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{EncodeOptions, QuantizationChoice, Reader, encode, summary};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let bits: u8 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(12);
    let mut opts = EncodeOptions { quantization: QuantizationChoice::Bits(bits), ..Default::default() };
    // The coarse grid: the encoder's default unless given (`none`, or k).
    match args.get(3).map(String::as_str) {
        Some("none") => opts.coarse_grid = None,
        Some(k) => opts.coarse_grid = Some(k.parse().expect("coarse grid: a number or none")),
        None => {}
    }
    // PMCODEC_MOTION=mean|affine: band 0's motion (default: keyframe affine);
    // PMCODEC_ORDER=input: band 0 decoded in input order (default: breadth first).
    match std::env::var("PMCODEC_MOTION").as_deref() {
        Ok("mean") => opts.motion = pmcodec_container::Motion::Mean,
        Ok("affine") => opts.motion = pmcodec_container::Motion::Affine,
        _ => {}
    }
    if std::env::var("PMCODEC_ORDER").as_deref() == Ok("input") {
        opts.order = pmcodec_container::VertexOrder::Input;
    }
    // Experiments: PMCODEC_BRANCHING=b, or PMCODEC_LEVELS=n1,n2,... (sizes below |M0|).
    if let Some(b) = std::env::var("PMCODEC_BRANCHING").ok().and_then(|s| s.parse().ok()) {
        opts.build.branching = b;
    }
    if let Ok(l) = std::env::var("PMCODEC_LEVELS") {
        opts.build.level_sizes = Some(l.split(',').filter_map(|x| x.parse().ok()).collect());
    }
    // PMC_BANDS=1: the banded index (the default), which coarse clients read in part;
    // PMC_BANDS=0 the frame-by-frame one (`pmcodec encode --frame-index`).
    match std::env::var("PMC_BANDS").as_deref() {
        Ok("1") => opts.chunk_flags |= pmcodec_container::format::FLAG_BANDS,
        Ok("0") => opts.chunk_flags &= !pmcodec_container::format::FLAG_BANDS,
        _ => {}
    }
    let t = std::time::Instant::now();
    let bytes = encode(&seq, &opts, |_| {}).expect("encode");
    let secs = t.elapsed().as_secs_f64();
    let reader = Reader::open(bytes.as_slice()).expect("open");
    let s = summary(&reader);
    let (v, f) = (seq.vertex_count() as f64, seq.frame_count() as f64);
    println!("{}: {} vertices, {} frames, levels {:?}; encoded in {secs:.2} s", args[1], v, f, s.header.level_sizes);
    println!("total .pmc: {} bytes ({:.1} KB/frame)", s.file_bytes, s.file_bytes as f64 / f / 1024.0);
    println!("positions ({bits}-bit): {:.2} bits/vertex/frame (all bands)", s.positions_bits_per_vertex_frame);
    println!(
        "positions by band (bits per input vertex per frame): {:?}",
        s.positions_bytes.iter().map(|&b| format!("{:.2}", b as f64 * 8.0 / (v * f))).collect::<Vec<_>>()
    );
    let (mut key, mut inter, mut key0, mut inter0) = (0u64, 0u64, 0u64, 0u64);
    for e in reader.index().chunks.iter().filter(|e| e.kind == pmcodec_container::ChunkKind::Positions) {
        let (all, band0) = if s.header.is_keyframe(e.frame) { (&mut key, &mut key0) } else { (&mut inter, &mut inter0) };
        *all += e.stored_len as u64;
        if e.band == 0 {
            *band0 += e.stored_len as u64;
        }
    }
    let nk = (0..s.header.frame_count).filter(|&x| s.header.is_keyframe(x)).count() as f64;
    println!(
        "positions on keyframes {:.2}, other frames {:.2} bits/vertex/frame",
        key as f64 * 8.0 / (v * nk),
        inter as f64 * 8.0 / (v * (f - nk))
    );
    println!(
        "band 0 alone (the input vertices) on keyframes {:.2}, other frames {:.2} bits/vertex/frame",
        key0 as f64 * 8.0 / (v * nk),
        inter0 as f64 * 8.0 / (v * (f - nk))
    );
    println!(
        "topology deltas (swaps, what a full-resolution client reads): {:.0} B/frame compressed, {:.0} B/frame raw; by band {:?} B/frame",
        s.delta_bytes_per_frame,
        s.delta_raw_bytes_per_frame,
        s.delta_bytes.iter().map(|&b| (b as f64 / f).round()).collect::<Vec<_>>()
    );
    // What the deltas hold, per band: entries per frame of each kind.
    let levels = s.header.levels();
    let (mut mv, mut co) = (vec![0usize; levels], vec![0usize; levels]);
    let h = &s.header;
    for e in &reader.index().chunks {
        let b = e.band as usize;
        match e.kind {
            pmcodec_container::ChunkKind::Delta => {
                let raw = reader.read_chunk(e).expect("chunk");
                mv[b] += pmcodec_container::payload::read_delta(&raw, "d", &h.level_sizes, b).expect("delta").len();
            }
            pmcodec_container::ChunkKind::Corners => {
                let raw = reader.read_chunk(e).expect("chunk");
                // The count leads the chunk in every version.
                co[b] += pmcodec_container::payload::Cursor::new(&raw, "corners").get().expect("corners") as usize;
            }
            _ => {}
        }
    }
    let per = |x: &Vec<usize>| x.iter().map(|&c| (c as f64 / f).round()).collect::<Vec<_>>();
    println!("delta entries per frame by band: moves {:?}, corner updates {:?}", per(&mv), per(&co));
    println!(
        "corner updates (read only by a client stopping at that band): {:?} B/frame; keyframe faces {:?} B in all",
        s.corners_bytes.iter().map(|&b| (b as f64 / f).round()).collect::<Vec<_>>(),
        s.faces_bytes
    );
    println!("keyframes: {:?} B per band in all", s.key_bytes);
    println!(
        "bytes per frame for a client stopping at level L: {:?}",
        s.bytes_per_frame_to_level.iter().map(|x| x.round()).collect::<Vec<_>>()
    );
    // A reader at 10% of the triangles: the coarsest finest-level whose budget cut reaches
    // (98% of, as clients choose levels) that many triangles, and its share of the stream's chunk bytes (keys included).
    let budget = s.header.triangle_count / 10;
    let mid = s.header.frame_count / 2;
    let all: u64 = reader.index().chunks.iter().map(|e| e.stored_len as u64).sum();
    for l in (0..s.header.levels()).rev() {
        let mut d = pmcodec_container::Decoder::new(reader.borrowed(), l).expect("decoder");
        d.seek(mid).expect("seek");
        let shown = d.mesh(pmcodec_container::CutTarget::Triangles(budget)).expect("mesh").triangles.len();
        if shown as f64 >= 0.98 * budget as f64 {
            let part: u64 = reader.index().chunks.iter().filter(|e| reader.reads(e, l)).map(|e| e.stored_len as u64).sum();
            let full: u64 = reader.index().chunks.iter().filter(|e| reader.reads(e, 0)).map(|e| e.stored_len as u64).sum();
            // What that client is sent (`/stream?level=l`, `pmcodec_container::streams`):
            // its head (of a banded index only its groups) and its chunks, beside level 0's.
            let streamed = |l: usize| {
                let head: u64 = pmcodec_container::streams::head_ranges(&bytes, l).expect("head").iter().map(|r| r.end - r.start).sum();
                let ranges = pmcodec_container::streams::frame_ranges(&reader.index().chunks, reader.header(), reader.data_start(), l, 0);
                head + ranges.iter().flatten().map(|r| r.end - r.start).sum::<u64>()
            };
            let quarter = s.header.triangle_count / 4;
            let l25 = (0..s.header.levels())
                .rev()
                .find(|&l| {
                    let mut d = pmcodec_container::Decoder::new(reader.borrowed(), l).expect("decoder");
                    d.seek(mid).expect("seek");
                    d.mesh(pmcodec_container::CutTarget::Triangles(quarter)).expect("mesh").triangles.len() as f64 >= 0.98 * quarter as f64
                })
                .unwrap_or(0);
            println!(
                "streamed (head and chunks, index {}): a 10% client (level {l}) reads {:.1}%, a 25% client (level {l25}) {:.1}% of a full client's {} B",
                if pmcodec_container::streams::is_banded(&pmcodec_container::format::Preamble::parse(&bytes[..32]).expect("preamble")) {
                    "banded"
                } else {
                    "plain"
                },
                streamed(l) as f64 * 100.0 / streamed(0) as f64,
                streamed(l25) as f64 * 100.0 / streamed(0) as f64,
                streamed(0)
            );
            println!(
                "10% of the triangles ({budget}, frame {mid}) needs levels >= {l} ({shown} shown): reads {:.1}% of what a full-resolution reader reads ({:.1}% of all chunk bytes)",
                part as f64 * 100.0 / full as f64,
                part as f64 * 100.0 / all as f64
            );
            break;
        }
    }
    // Speed: full-resolution playback of every frame, best of 5, and random seeks.
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = std::time::Instant::now();
        let mut d = pmcodec_container::Decoder::new(reader.borrowed(), 0).expect("decoder");
        for fr in 0..s.header.frame_count {
            d.seek(fr).expect("frame");
        }
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!("decode, full resolution: {:.3} ms/frame = {:.0} frames/s (one core)", best * 1e3 / f, f / best);
    let mut worst = 0f64;
    let mut total = 0f64;
    let n = 50u32;
    for i in 0..n {
        let fr = (i.wrapping_mul(2654435761) >> 7) % s.header.frame_count;
        let t = std::time::Instant::now();
        let mut d = pmcodec_container::Decoder::new(reader.borrowed(), 0).expect("decoder");
        d.seek(fr).expect("seek");
        let e = t.elapsed().as_secs_f64();
        worst = worst.max(e);
        total += e;
    }
    println!("seek to a random frame from a fresh decoder: mean {:.2} ms, worst {:.2} ms", total * 1e3 / n as f64, worst * 1e3);
    // An open decoder (triangles read) jumping to random frames, as a player scrubbing does.
    let mut d = pmcodec_container::Decoder::new(reader.borrowed(), 0).expect("decoder");
    d.seek(0).expect("seek");
    let (mut worst, mut total, mut key_total, mut keys) = (0f64, 0f64, 0f64, 0u32);
    for i in 0..n {
        let fr = (i.wrapping_mul(2246822519).wrapping_add(12345) >> 9) % s.header.frame_count;
        let t = std::time::Instant::now();
        d.seek(fr).expect("seek");
        let e = t.elapsed().as_secs_f64();
        worst = worst.max(e);
        total += e;
        if s.header.is_keyframe(fr) {
            key_total += e;
            keys += 1;
        }
    }
    println!(
        "seek to a random frame with an open decoder: mean {:.2} ms, worst {:.2} ms (to keyframes: mean {:.2} ms)",
        total * 1e3 / n as f64,
        worst * 1e3,
        key_total * 1e3 / keys.max(1) as f64
    );
    // References.
    println!("raw f32 positions: 96 bits/vertex/frame ({:.0} KB/frame)", v * 12.0 / 1024.0);
    let mut zsum = 0usize;
    for frame in &seq.frames {
        let raw: Vec<u8> = frame.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes).collect();
        zsum += zstd::bulk::compress(&raw, 19).expect("zstd").len();
    }
    println!("each frame's f32 positions zstd -19 on its own: {:.2} bits/vertex/frame", zsum as f64 * 8.0 / (v * f));
    // meshoptimizer's vertex codec on each frame quantized as this file is (the same step over
    // the bounding box, 16 bits per axis and 16 of padding, as its 4-byte stride wants), the
    // vertices in the order its fetch optimizer gives the triangles (the order it is built
    // for), at its strongest level, then zstd -19 as glTF's meshopt compression suggests.
    let step = s.header.quantization.step;
    let lo = glam::Vec3::from_array(s.header.bbox_min);
    let indices: Vec<u32> = seq.triangles.iter().flatten().copied().collect();
    let indices = meshopt::optimize_vertex_cache(&indices, seq.vertex_count());
    let remap = meshopt::optimize_vertex_fetch_remap(&indices, seq.vertex_count());
    let (mut mo, mut moz) = (0usize, 0usize);
    let mut quantized = vec![[0u16; 4]; seq.vertex_count()];
    for frame in &seq.frames {
        for (i, p) in frame.iter().enumerate() {
            let q = ((*p - lo) / step).round();
            quantized[remap[i] as usize] = [q.x as u16, q.y as u16, q.z as u16, 0];
        }
        let coded = meshopt::encode_vertex_buffer_level(&quantized, 3, Some(1)).expect("meshopt");
        mo += coded.len();
        moz += zstd::bulk::compress(&coded, 19).expect("zstd").len();
    }
    println!(
        "meshoptimizer's vertex codec, each frame quantized the same on its own: {:.2} bits/vertex/frame ({:.2} with zstd -19)",
        mo as f64 * 8.0 / (v * f),
        moz as f64 * 8.0 / (v * f)
    );
    println!("paper (horse, uncompressed): swaps 2.2 KB/frame, swaps + degenerate sets 18.5 KB/frame, full hierarchy 103.4 KB/frame");
}
