//! Tests of the values across a band's faces (`across`).
#![allow(clippy::unwrap_used, clippy::expect_used)]
use super::*;
use crate::appearance::format::AppearanceInfo;
use crate::appearance::payload::{band0_entries, read_band, read_table_across, write_table_chartwise};

/// A grid of `w` x `h` vertices split into `k` charts by columns (seams: a vertex on a chart
/// border has an entry in both), its parents two levels up (2 x 2 cells each), and a band-1
/// table of every (level-1 node, chart) pair its triangles make, valued by `uv(x, y, chart)`,
/// with the band-2 table above it (its represented entries valued as their representatives).
struct Grid {
    triangles: Vec<[u32; 3]>,
    chart_of: Vec<u32>,
    p0: Vec<u32>,
    p1: Vec<u32>,
    band1: QuantizedTable,
    above: Table,
}

/// Texture coordinates of a level-1 node at (x, y) in a chart.
type Uv<'a> = &'a dyn Fn(u32, u32, u32) -> [i32; 2];

fn grid(w: u32, h: u32, k: u32, uv: Uv<'_>) -> Grid {
    let id = |x: u32, y: u32| y * w + x;
    let mut triangles = Vec::new();
    let mut chart_of = Vec::new();
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let chart = x * k / (w - 1);
            triangles.push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
            triangles.push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
            chart_of.extend([chart, chart]);
        }
    }
    let (w1, w2) = (w.div_ceil(2), w.div_ceil(4));
    let p0: Vec<u32> = (0..w * h).map(|v| (v / w / 2) * w1 + (v % w) / 2).collect();
    let p1: Vec<u32> = (0..w1 * h.div_ceil(2)).map(|n| (n / w1 / 2) * w2 + (n % w1) / 2).collect();
    let mut entries: Vec<(u32, u32)> = triangles.iter().zip(&chart_of).flat_map(|(t, &c)| t.map(|v| (p0[v as usize], c))).collect();
    entries.sort_unstable();
    entries.dedup();
    let values = entries.iter().flat_map(|&(n, c)| uv(n % w1, n / w1, c)).collect();
    let band1 = QuantizedTable { entries, values };
    let above = above_of(&band1, &p1);
    Grid { triangles, chart_of, p0, p1, band1, above }
}

/// The table above `t` under `parent`: every (parent, chart) of its entries, valued as its
/// representative (2 channels), as the reference encoder values a coarse entry.
fn above_of(t: &QuantizedTable, parent: &[u32]) -> Table {
    let mut up: Vec<(u32, u32)> = t.entries.iter().map(|&(n, c)| (parent[n as usize], c)).collect();
    up.sort_unstable();
    up.dedup();
    let mut above = QuantizedTable { values: vec![0; up.len() * 2], entries: up }.to_table();
    let nodes = t.entries.last().map_or(0, |e| e.0 + 1);
    for (e, r) in representatives(&Table::index(&t.entries, nodes), parent, &above).into_iter().enumerate() {
        if let Some(a) = r {
            above.values[a as usize * 2..a as usize * 2 + 2].copy_from_slice(&t.values[e * 2..e * 2 + 2]);
        }
    }
    above
}

#[test]
fn band0_values_across_the_triangles_round_trip_and_fail_cleanly() {
    // A seamed grid (4 charts) with a degenerate triangle, whose corner (vertex 5, chart 3) no
    // other triangle reaches: the traversal's leftovers.
    let g = grid(21, 15, 4, &|x, y, c| [(c * 1000 + x * 50) as i32, (y * 61) as i32]);
    let mut triangles = g.triangles.clone();
    let mut chart_of = g.chart_of.clone();
    triangles.push([5, 5, 6]);
    chart_of.push(3);
    let entries = band0_entries(&triangles, &chart_of);
    let values = entries.iter().flat_map(|&(v, c)| [(c * 1000 + (v % 21) * 25 + (v * 7) % 5) as i32, (v / 21 * 30) as i32]).collect();
    let t = QuantizedTable { entries, values };
    let above = above_of(&t, &g.p0);
    let info = info(4);
    let (n, tc) = (21 * 15, triangles.len() as u32);
    let band0 = Some((&triangles[..], &chart_of[..]));
    for rans in [false, true] {
        let raw = write_table_derived_across(&t, 2, &triangles, &chart_of, &g.p0, &above, rans).unwrap();
        assert_eq!(raw[..2], [0, 1 | 16 | 64 | if rans { 8 } else { 0 }]);
        let back = read_band(&raw, "t", n, &info, tc, band0, Some((&g.p0, &above))).unwrap();
        assert_eq!(back.values, t.values, "rans {rans}");
        assert!(read_band(&raw, "t", n, &info, tc, band0, None).is_err(), "without the band above");
        for cut in [2, raw.len() / 2, raw.len() - 1] {
            assert!(read_band(&raw[..cut], "t", n, &info, tc, band0, Some((&g.p0, &above))).is_err(), "cut {cut}");
        }
        for at in 1..raw.len() {
            let mut bad = raw.clone();
            bad[at] ^= 0x5A;
            let _ = read_band(&bad, "t", n, &info, tc, band0, Some((&g.p0, &above)));
        }
        // Across the triangles without represented values is no coding.
        let mut odd = raw.clone();
        odd[1] &= !16;
        assert!(read_band(&odd, "t", n, &info, tc, band0, Some((&g.p0, &above))).is_err());
    }
}

fn info(charts: u32) -> AppearanceInfo {
    AppearanceInfo {
        charts,
        groups: 1,
        materials: 1,
        images: 0,
        uv_sets: 1,
        uv_min: [0.0; 2],
        uv_step: [1.0; 2],
        colors: false,
        normals: false,
    }
}

#[test]
fn values_across_a_bands_faces_round_trip_every_flag_and_fail_cleanly() {
    let mut seed = 0x2545_F491u32;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        (seed % 4096) as i32
    };
    let noise: Vec<i32> = (0..4096).map(|_| rnd()).collect();
    // Smooth texture coordinates (each chart its own region of the texture), and noise.
    let smooth = |x: u32, y: u32, c: u32| [(c * 900 + x * 37) as i32, (y * 41 + x * 3) as i32];
    let wild = |x: u32, y: u32, c: u32| [noise[((x * 7 + y * 13 + c) % 4096) as usize], noise[((x * 11 + y * 5 + c * 3) % 4096) as usize]];
    let cases: [(&str, Uv<'_>); 2] = [("smooth", &smooth), ("noise", &wild)];
    for (name, uv) in cases {
        let g = grid(23, 17, 4, uv);
        let info = info(4);
        let (faces, face_chart) = band_faces(&g.triangles, &g.chart_of, &[&g.p0]).unwrap();
        assert!(faces.len() > 100 && faces.iter().all(|f| f[0] != f[1] && f[1] != f[2] && f[0] != f[2]), "{name}");
        let nodes = g.p1.len() as u32;
        for bits in 0..8 {
            let (rans, represented, entries_above) = (bits & 1 != 0, bits & 2 != 0, bits & 4 != 0);
            let raw = write_table_across(&g.band1, 2, &g.p1, &g.above, (&faces, &face_chart), rans, represented, entries_above).unwrap();
            let mode = 3 | 64 | if rans { 8 } else { 0 } | if represented { 16 } else { 0 } | if entries_above { 32 } else { 0 };
            assert_eq!(raw[..2], [0, mode], "{name} flags {bits}");
            assert!(needs_faces(&raw) && super::super::payload::needs_above(&raw));
            let f = Some((&faces[..], &face_chart[..]));
            let back = read_table_across(&raw, "t", nodes, &info, g.triangles.len() as u32, Some((&g.p1, &g.above)), f).unwrap();
            assert_eq!(back.values, g.band1.values, "{name} flags {bits}");
            // Without the faces, or cut short: an error; a changed byte: an error or other
            // values, never a panic.
            assert!(read_table_across(&raw, "t", nodes, &info, 9999, Some((&g.p1, &g.above)), None).is_err());
            for cut in [2, raw.len() / 2, raw.len() - 1] {
                assert!(
                    read_table_across(&raw[..cut], "t", nodes, &info, 9999, Some((&g.p1, &g.above)), f).is_err(),
                    "{name} {bits} cut {cut}"
                );
            }
            for at in 1..raw.len() {
                let mut bad = raw.clone();
                bad[at] ^= 0x5A;
                let _ = read_table_across(&bad, "t", nodes, &info, 9999, Some((&g.p1, &g.above)), f);
            }
            // Faces of another hierarchy name pairs the table may lack: an error or other
            // values, never a panic.
            let other: Vec<[u32; 3]> = faces.iter().map(|t| t.map(|v| (v * 7) % nodes)).collect();
            let _ = read_table_across(&raw, "t", nodes, &info, 9999, Some((&g.p1, &g.above)), Some((&other, &face_chart)));
        }
        // Smooth values: across the faces takes fewer bytes than each entry from the chart's
        // previous one (neighbours in a chart lie near in the texture; node order does not).
        let across = write_table_across(&g.band1, 2, &g.p1, &g.above, (&faces, &face_chart), true, true, true).unwrap();
        let chartwise = write_table_chartwise(&g.band1, 2, true);
        if name == "smooth" {
            assert!(across.len() < chartwise.len(), "{name}: {} B across, {} B chart-wise", across.len(), chartwise.len());
        }
    }
}

#[test]
fn band_faces_walk_corners_up_and_drop_collapsed_triangles() {
    let triangles = [[0, 1, 2], [1, 3, 2], [2, 3, 4]];
    let charts = [0, 1, 1];
    // 0 and 1 merge into node 0; 2 -> 1, 3 -> 2, 4 -> 2.
    let p0 = [0, 0, 1, 2, 2];
    let (faces, fc) = band_faces(&triangles, &charts, &[&p0]).unwrap();
    assert_eq!((faces, fc), (vec![[0, 2, 1]], vec![1]));
    // No parents: the triangles themselves; a parent map that misses a node: none.
    assert_eq!(band_faces(&triangles, &charts, &[]).unwrap().0, triangles.to_vec());
    assert!(band_faces(&triangles, &charts, &[&p0[..3]]).is_none());
}
