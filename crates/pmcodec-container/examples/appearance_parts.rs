//! Where a container's appearance bytes go (issue 16's size bar): the Charts chunk split into
//! its chart materials, chart runs and smoothing-group runs, and each band's Attributes chunk
//! into its (node, chart) entries and its values, every part zstd-compressed on its own (level
//! 19, as the encoder) so the parts are comparable with the chunks' stored bytes.
//!
//! `cargo build --release -p pmcodec && target/release/pmcodec encode -q IN.glb -o /tmp/a.pmc &&
//!  cargo run --release -p pmcodec-container --example appearance_parts -- /tmp/a.pmc`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::appearance::payload::{needs_above, read_charts, read_table, read_table_with};
use pmcodec_container::payload::read_triangles;
use pmcodec_container::payload::{put, zigzag};
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
        let charts = read_charts(&raw, &info, h.triangle_count).unwrap();
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
        for j in (0..h.levels() as u32).rev() {
            let Some((e, s)) = stored(ChunkKind::Attributes, j) else {
                println!("  band {j}: no attributes chunk");
                continue;
            };
            total += s;
            let raw = reader.read_chunk(e).unwrap();
            // The coding mode after a first byte 0; bit 8: value residuals rANS-coded.
            let rans = raw.len() > 1 && raw[0] == 0 && raw[1] & 8 != 0;
            let coded = if rans { "rANS-coded" } else { "varints" };
            if raw.len() > 1 && raw[0] == 0 && raw[1] & 7 == 1 {
                // Band 0 with derived entries: only predicted values are stored.
                let te = reader.index().chunks.iter().find(|e| e.kind == ChunkKind::Triangles).unwrap();
                let tris =
                    read_triangles(&reader.read_chunk(te).unwrap(), "t", h.triangle_count, h.vertex_count, reader.version()).unwrap();
                let t =
                    read_table_with(&raw, "t", h.level_sizes[j as usize], &info, h.triangle_count, Some((&tris, &charts.triangle_chart)))
                        .unwrap();
                println!(
                    "  band {j}: {s} B stored ({} raw), {} entries of {} nodes derived from the triangles: predicted values only ({coded})",
                    raw.len(),
                    t.len(),
                    h.level_sizes[j as usize]
                );
                continue;
            }
            if needs_above(&raw) {
                println!("  band {j}: {s} B stored ({} raw, values from the band above, {coded})", raw.len());
                continue;
            }
            let t = read_table(&raw, "t", h.level_sizes[j as usize], &info, h.triangle_count).unwrap();
            let ch = info.channels();
            let (mut ent, mut val) = (Vec::new(), Vec::new());
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
            for k in 0..ch {
                let mut last = 0i32;
                for e in 0..t.len() {
                    let q = t.values[e * ch + k];
                    put(&mut val, zigzag(q.wrapping_sub(last)));
                    last = q;
                }
            }
            if std::env::var("EXPERIMENT").is_ok() {
                // Values as differences from the previous entry of the same chart.
                let mut alt = Vec::new();
                for k in 0..ch {
                    let mut last = vec![0i32; info.charts as usize];
                    for e in 0..t.len() {
                        let c = t.charts[e] as usize;
                        let q = t.values[e * ch + k];
                        put(&mut alt, zigzag(q.wrapping_sub(last[c])));
                        last[c] = q;
                    }
                }
                println!("  EXP band {j}: values same-chart delta {} B", z(&alt));
            }
            println!(
                "  band {j}: {s} B stored ({} raw, {}), {} entries of {} nodes: entries {} B, values {} B (parts zstd alone, as listed)",
                raw.len(),
                match (raw.len() > 1 && raw[0] == 0, raw.get(1).map_or(0, |m| m & 7)) {
                    (true, 2) => format!("chart-wise values, {coded}"),
                    _ => format!("listed, {coded}"),
                },
                t.len(),
                h.level_sizes[j as usize],
                z(&ent),
                z(&val)
            );
        }
        println!("  appearance total (charts + attributes, stored): {total} B");
    }
}
