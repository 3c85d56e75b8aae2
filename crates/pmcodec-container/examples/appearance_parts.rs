//! Where a container's appearance bytes go (issue 16's size bar): the Charts chunk split into
//! its chart materials, chart runs and smoothing-group runs, and each band's Attributes chunk
//! into its (node, chart) entries and its values, every part zstd-compressed on its own (level
//! 19, as the encoder) so the parts are comparable with the chunks' stored bytes.
//!
//! Per band: its coding mode (1 derived entries, 2 chart-wise, 3 from the band above; | 8
//! rANS-coded residuals, | 16 represented values, | 32 entries from the band above, | 4 with 1
//! texture coordinates from bind positions, | 64
//! values across the band's faces), its
//! entries and how many of them are representatives (no residual), and what its entries would
//! take listed. `DUMP_CHARTS=FILE` writes each triangle's chart, one a line, for experiments.
//!
//! `cargo build --release -p pmcodec && target/release/pmcodec encode -q IN.glb -o /tmp/a.pmc &&
//!  cargo run --release -p pmcodec-container --example appearance_parts -- /tmp/a.pmc`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::appearance::across::{band_faces, write_table_across};
use pmcodec_container::appearance::payload::{
    QuantizedTable, Table, needs_above, read_band_bind, read_charts_with, read_table_across, representatives,
};
use pmcodec_container::payload::{put, zigzag};
use pmcodec_container::payload::{read_key, read_triangles};
use pmcodec_container::{ChunkKind, FileSource, Reader};

fn z(raw: &[u8]) -> usize {
    if raw.is_empty() { 0 } else { zstd::encode_all(raw, 19).unwrap().len().min(raw.len()) }
}

fn runs(values: &[u32]) -> Vec<(u32, u32)> {
    let mut r: Vec<(u32, u32)> = Vec::new();
    for &v in values {
        match r.last_mut() {
            Some((x, n)) if *x == v => *n += 1,
            _ => r.push((v, 1)),
        }
    }
    r
}

/// A skinned file's bind positions of the level-0 nodes (band 0 may predict from them).
fn bind0(path: &str) -> Option<Vec<[i64; 3]>> {
    let mut d = pmcodec_container::Decoder::new(Reader::open(FileSource::open(std::path::Path::new(path)).ok()?).ok()?, 0).ok()?;
    d.seek(0).ok()?;
    let n = d.reader().header().level_sizes[0] as usize;
    d.skin().map(|(nodes, _)| nodes[..n].iter().map(|s| s.bind).collect())
}

fn main() {
    for path in std::env::args().skip(1) {
        let reader = Reader::open(FileSource::open(std::path::Path::new(&path)).unwrap()).unwrap();
        let h = reader.header().clone();
        let Some(info) = h.appearance.clone() else {
            println!("{path}: no appearance");
            continue;
        };
        let stored = |kind: ChunkKind, band: u32| {
            reader.index().chunks.iter().find(|e| e.kind == kind && e.band == band && e.frame == 0).map(|e| (e, e.stored_len as usize))
        };
        println!(
            "{path}: {} triangles, {} charts, {} groups, {} materials, {} channels, levels {:?}",
            h.triangle_count,
            info.charts,
            info.groups,
            info.materials,
            info.channels(),
            h.level_sizes
        );
        let Some((ce, cs)) = stored(ChunkKind::Charts, 0) else { continue };
        let raw = reader.read_chunk(ce).unwrap();
        let te = reader.index().chunks.iter().find(|e| e.kind == ChunkKind::Triangles).unwrap();
        let tris = read_triangles(&reader.read_chunk(te).unwrap(), "t", h.triangle_count, h.vertex_count, reader.version()).unwrap();
        let charts = read_charts_with(&raw, &info, h.triangle_count, Some(&tris)).unwrap();
        let mut mats = Vec::new();
        for &m in &charts.chart_material {
            put(&mut mats, m);
        }
        let mut chart_runs = Vec::new();
        let cr = runs(&charts.triangle_chart);
        for &(c, n) in &cr {
            put(&mut chart_runs, c);
            put(&mut chart_runs, n);
        }
        let mut group_runs = Vec::new();
        let gr = runs(&charts.triangle_group);
        let mut last = 0u32;
        for &(g, n) in &gr {
            put(&mut group_runs, zigzag(g.wrapping_sub(last) as i32));
            put(&mut group_runs, n);
            last = g;
        }
        if let Ok(dump) = std::env::var("DUMP_CHARTS") {
            // Each triangle's chart, one a line, for offline experiments.
            let lines: Vec<String> = charts.triangle_chart.iter().map(u32::to_string).collect();
            std::fs::write(&dump, lines.join("\n")).unwrap();
        }
        if std::env::var("EXPERIMENT").is_ok() {
            // Alternative chart-run codings: 0 = the next new chart, else chart + 1.
            let mut alt = Vec::new();
            let mut next = 0u32;
            for &(c, n) in &cr {
                if c == next {
                    put(&mut alt, 0);
                    next += 1;
                } else {
                    put(&mut alt, c + 1);
                }
                put(&mut alt, n);
            }
            let mut alt2 = Vec::new();
            let mut lastc = 0u32;
            for &(c, n) in &cr {
                put(&mut alt2, zigzag(c.wrapping_sub(lastc) as i32));
                put(&mut alt2, n);
                lastc = c;
            }
            println!("  EXP chart runs: new-or-id {} B, delta {} B", z(&alt), z(&alt2));
        }
        if std::env::var("EXPERIMENT").is_ok() {
            let n = pmcodec_container::appearance::payload::write_charts_neighbours(&charts, &tris).map_or(0, |w| z(&w));
            println!("  EXP charts with neighbour charts (mode 3): {n} B");
        }
        println!(
            "  charts chunk: {cs} B stored ({} raw); chart materials {} B ({} raw), chart runs {} B ({} runs, {} raw), group runs {} B ({} runs, {} raw) (parts zstd alone)",
            raw.len(),
            z(&mats),
            mats.len(),
            z(&chart_runs),
            cr.len(),
            chart_runs.len(),
            z(&group_runs),
            gr.len(),
            group_runs.len()
        );
        let mut total = cs;
        let mut above: Option<Table> = None;
        for j in (0..h.levels() as u32).rev() {
            let Some((e, s)) = stored(ChunkKind::Attributes, j) else {
                println!("  band {j}: no attributes chunk");
                continue;
            };
            total += s;
            let raw = reader.read_chunk(e).unwrap();
            // The coding mode after a first byte 0: 1 derived entries, 2 chart-wise, 3 from the
            // band above; | 8 value residuals rANS-coded; | 16 represented values; | 32 entries
            // coded from the band above's; with 1, | 4 texture coordinates from bind positions.
            let mode = if raw.len() > 1 && raw[0] == 0 { raw[1] } else { 0 };
            let coded = if mode & 8 != 0 { "rANS-coded" } else { "varints" };
            let kind = match (mode & 3, mode & 32 != 0) {
                (1, _) if mode & 4 != 0 => "entries derived from the triangles, texture coordinates from bind positions",
                (1, _) => "entries derived from the triangles",
                (2, _) => "listed, chart-wise values",
                (3, false) if mode & 64 != 0 => "listed, values across the band's faces",
                (3, true) if mode & 64 != 0 => "entries from the band above, values across the band's faces",
                (3, false) => "listed, values from the band above",
                (3, true) => "entries and values from the band above",
                _ => "listed",
            };
            let parent = needs_above(&raw).then(|| {
                let ke = reader.find(ChunkKind::Key, 0, j).unwrap();
                read_key(&reader.read_chunk(ke).unwrap(), "k", &h.level_sizes, j as usize, reader.version()).unwrap()
            });
            let band0 = (j == 0).then(|| (&tris[..], &charts.triangle_chart[..]));
            let above_of = parent.as_ref().and_then(|p| above.as_ref().map(|t| (&p[..], t)));
            // Frame 0's parents of levels 0..j and band j's faces (values across them, mode | 64).
            let parents: Vec<Vec<u32>> = (0..j)
                .map(|i| {
                    let ke = reader.find(ChunkKind::Key, 0, i).unwrap();
                    read_key(&reader.read_chunk(ke).unwrap(), "k", &h.level_sizes, i as usize, reader.version()).unwrap()
                })
                .collect();
            let refs: Vec<&[u32]> = parents.iter().map(Vec::as_slice).collect();
            let (faces, fc) = band_faces(&tris, &charts.triangle_chart, &refs).unwrap();
            let t = if j > 0 {
                read_table_across(&raw, "t", h.level_sizes[j as usize], &info, h.triangle_count, above_of, Some((&faces, &fc))).unwrap()
            } else {
                read_band_bind(&raw, "t", h.level_sizes[j as usize], &info, (h.triangle_count, band0), above_of, bind0(&path).as_deref())
                    .unwrap()
            };
            // The entries as a listed table writes them, zstd alone.
            let mut ent = Vec::new();
            let mut prev: Option<(u32, u32)> = None;
            for n in 0..h.level_sizes[j as usize] {
                for x in t.first[n as usize]..t.first[n as usize + 1] {
                    let c = t.charts[x as usize];
                    match prev {
                        Some((pn, pc)) if pn == n => {
                            put(&mut ent, 0);
                            put(&mut ent, c - pc - 1)
                        }
                        Some((pn, _)) => {
                            put(&mut ent, n - pn);
                            put(&mut ent, c)
                        }
                        None => {
                            put(&mut ent, n);
                            put(&mut ent, c)
                        }
                    }
                    prev = Some((n, c));
                }
            }
            let reps = match (&parent, &above) {
                (Some(p), Some(a)) if mode & 16 != 0 => representatives(&t, p, a).iter().filter(|r| r.is_some()).count(),
                _ => 0,
            };
            println!(
                "  band {j}: {s} B stored ({} raw; mode {mode}: {kind}, {coded}), {} entries of {} nodes, {reps} represented (no residual); entries as listed {} B{}",
                raw.len(),
                t.len(),
                h.level_sizes[j as usize],
                z(&ent),
                if mode & 7 == 1 { " (not stored)" } else { "" }
            );
            if let (Ok(_), Some(p), Some(a)) = (std::env::var("EXPERIMENT"), &parent, &above) {
                // Bit lengths of the non-representatives' residuals against their parent entries.
                let ch = info.channels();
                let reps = representatives(&t, p, a);
                let mut hist = [0usize; 33];
                let mut orphans = 0;
                for (n, &pn) in p.iter().enumerate().take(t.first.len() - 1) {
                    for e in t.first[n] as usize..t.first[n + 1] as usize {
                        if reps[e].is_some() {
                            continue;
                        }
                        match a.get(pn, t.charts[e], ch) {
                            Some(v) => (0..ch)
                                .for_each(|k| hist[32 - zigzag(t.values[e * ch + k].wrapping_sub(v[k])).leading_zeros() as usize] += 1),
                            None => orphans += 1,
                        }
                    }
                }
                println!("  EXP band {j}: residual bit lengths vs parent {:?}, {orphans} entries without a parent entry", &hist[..16]);
            }
            if let (Ok(_), Some(p), Some(a)) = (std::env::var("EXPERIMENT"), &parent, &above) {
                // The values across band j's faces in frame 0, each variant zstd'd.
                let mut q = QuantizedTable::default();
                for n in 0..h.level_sizes[j as usize] {
                    for x in t.first[n as usize]..t.first[n as usize + 1] {
                        q.entries.push((n, t.charts[x as usize]));
                    }
                }
                q.values = t.values.clone();
                let mut sizes = Vec::new();
                for bits in 0..8 {
                    let w = write_table_across(&q, info.channels(), p, a, (&faces, &fc), bits & 1 != 0, bits & 2 != 0, bits & 4 != 0);
                    sizes.push(w.map_or(0, |w| z(&w)));
                }
                if j == 0 {
                    let d: Vec<usize> = [false, true]
                        .map(|r| {
                            pmcodec_container::appearance::across::write_table_derived_across(
                                &q,
                                info.channels(),
                                &tris,
                                &charts.triangle_chart,
                                p,
                                a,
                                r,
                            )
                            .map_or(0, |w| z(&w))
                        })
                        .to_vec();
                    println!("  EXP band 0 derived across (varints, rans): {d:?}");
                }
                println!("  EXP band {j}: {} faces; across the faces (rans, represented, entries above bits) {sizes:?}", faces.len());
            }
            above = Some(t);
        }
        println!("  appearance total (charts + attributes, stored): {total} B");
    }
}
