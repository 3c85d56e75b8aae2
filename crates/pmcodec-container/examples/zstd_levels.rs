//! What zstd's level buys and costs per chunk kind of a written file: each chunk's payload
//! compressed again at several levels, stored as the encoder stores it (the zstd frame, or
//! the payload itself where the frame is no shorter, `FLAG_STORED`), with the bytes and the
//! compression time of each level, per kind and band class (band 0, bands >= 1; Positions by
//! band, 3 for bands 3 and up, and coding).
//! `cargo run --release -p pmcodec-container --example zstd_levels -- FILE.pmc [LEVEL...]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::{ChunkKind, Reader};
use std::collections::BTreeMap;
use std::time::Instant;

/// Per class: chunks, raw bytes, and per level (stored bytes, seconds compressing).
type Row = (usize, usize, Vec<(usize, f64)>);

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().expect("usage: zstd_levels FILE.pmc [LEVEL...]");
    let mut levels: Vec<i32> = args[1..].iter().map(|l| l.parse().expect("level")).collect();
    if levels.is_empty() {
        levels = vec![19, 15, 12, 9, 6, 3, 1];
    }
    let bytes = std::fs::read(path).expect("read");
    let r = Reader::open(bytes.as_slice()).expect("open");
    let mut by: BTreeMap<(String, bool), Row> = BTreeMap::new();
    let entries = r.index().chunks.clone();
    for e in &entries {
        let raw = r.read_chunk(e).expect("chunk");
        // Positions by band and coding (the first byte: shift + 32 * coding, 0 rANS, 1
        // varints, 2 sparse), other kinds by band 0 or not.
        let key = match e.kind {
            ChunkKind::Positions => (format!("Positions b{} c{}", e.band.min(3), raw.first().map_or(0, |b| b / 32)), true),
            _ => (format!("{:?}", e.kind), e.band == 0 || e.kind == ChunkKind::Triangles),
        };
        let row = by.entry(key).or_insert_with(|| (0, 0, vec![(0, 0.0); levels.len()]));
        row.0 += 1;
        row.1 += raw.len();
        for (i, &l) in levels.iter().enumerate() {
            let t = Instant::now();
            let z = zstd::bulk::compress(&raw, l).expect("zstd");
            row.2[i].1 += t.elapsed().as_secs_f64();
            row.2[i].0 += z.len().min(raw.len());
        }
    }
    println!("{path}: {} chunks, {} bytes", entries.len(), r.file_len());
    let head: Vec<String> = levels.iter().map(|l| format!("{:>16}", format!("z{l} B / ms"))).collect();
    println!("{:<22} {:>6} {:>9} {}", "kind (band 0?)", "chunks", "raw B", head.join(""));
    let mut totals = vec![(0usize, 0.0f64); levels.len()];
    for ((kind, b0), (n, raw, per)) in &by {
        let cells: Vec<String> = per.iter().map(|(b, s)| format!("{:>16}", format!("{b} / {:.1}", s * 1e3))).collect();
        println!("{:<22} {n:>6} {raw:>9} {}", format!("{kind} ({b0})"), cells.join(""));
        for (t, p) in totals.iter_mut().zip(per) {
            t.0 += p.0;
            t.1 += p.1;
        }
    }
    let cells: Vec<String> = totals.iter().map(|(b, s)| format!("{:>16}", format!("{b} / {:.1}", s * 1e3))).collect();
    println!("{:<22} {:>6} {:>9} {}", "total", "", "", cells.join(""));
}
