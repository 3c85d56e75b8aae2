//! Tests of the Charts and Attributes chunk payloads (`payload`, `chart_runs`, `entries`).
#![allow(clippy::unwrap_used, clippy::expect_used)]
use super::*;
use crate::appearance::charts::Charts;

pub(crate) fn info() -> AppearanceInfo {
    AppearanceInfo {
        charts: 3,
        groups: 3,
        materials: 2,
        images: 0,
        uv_sets: 1,
        uv_min: [0.0; 2],
        uv_step: [1.0; 2],
        colors: false,
        normals: false,
    }
}

#[test]
fn tables_and_charts_round_trip() {
    let t = QuantizedTable { entries: vec![(0, 0), (0, 2), (3, 1), (7, 0)], values: vec![5, 6, 7, 8, -1, 4000, 12, 0] };
    let table = read_table(&write_table(&t, 2), "t", 8, &info(), 100).unwrap();
    assert_eq!(table.get(0, 2, 2), Some(&[7, 8][..]));
    assert_eq!(table.get(7, 0, 2), Some(&[12, 0][..]));
    assert_eq!(table.get(3, 0, 2), None);
    assert!(read_table(&write_table(&t, 2), "t", 7, &info(), 100).is_err(), "node 7 of 7");
    // Chart-wise differences read back the same values; a derived coding is band 0's only.
    let chartwise = write_table_chartwise(&t, 2, false);
    assert_eq!(&chartwise[..2], &[0, 2]);
    let back = read_table(&chartwise, "t", 8, &info(), 100).unwrap();
    assert_eq!((back.values, back.charts), (table.values.clone(), table.charts.clone()));
    assert!(read_table(&chartwise[..chartwise.len() - 1], "t", 8, &info(), 100).is_err());
    let mut derived = chartwise.clone();
    derived[1] = 1;
    assert!(read_table(&derived, "t", 8, &info(), 100).is_err());
    // From the band above: nodes 0, 3, 7 under parents 1, 0, 1 of a table with entries
    // (0, 1) and (1, 0), (1, 2): some predicted from above, the rest chart-wise.
    let above = QuantizedTable { entries: vec![(0, 1), (1, 0), (1, 2)], values: vec![100, 200, 7, 9, 30, 31] }.to_table();
    let parent = [1, 1, 1, 0, 1, 1, 1, 1];
    let coded = write_table_from_above(&t, 2, &parent, &above, false);
    assert_eq!(&coded[..2], &[0, 3]);
    let back = read_table_above(&coded, "t", 8, &info(), 100, Some((&parent, &above))).unwrap();
    assert_eq!(back.values, table.values);
    assert!(needs_above(&coded) && !needs_above(&chartwise));
    // Without the band above (at the top, say), or cut short: errors, not panics.
    assert!(read_table(&coded, "t", 8, &info(), 100).is_err());
    assert!(read_table_above(&coded[..coded.len() - 1], "t", 8, &info(), 100, Some((&parent, &above))).is_err());
    // A parent list too short for the nodes falls back on chart-wise prediction, no panic.
    assert!(read_table_above(&coded, "t", 8, &info(), 100, Some((&parent[..2], &above))).is_ok());
    let charts = Charts { triangle_chart: vec![0, 0, 1, 2, 2, 0], chart_material: vec![0, 1, 1], triangle_group: vec![0, 0, 0, 0, 1, 2] };
    assert_eq!(read_charts(&write_charts(&charts), &info(), 6).unwrap(), charts);
    // New-chart runs: charts 0, 1, 2 open as "next", chart 0 again by id.
    let coded = write_charts_new_runs(&charts);
    assert_eq!(&coded[..2], &[0, 1]);
    assert_eq!(read_charts(&coded, &info(), 6).unwrap(), charts);
    assert!(read_charts(&coded[..coded.len() - 1], &info(), 6).is_err());
    let mut odd = coded.clone();
    odd[1] = 4;
    assert!(read_charts(&odd, &info(), 6).is_err(), "unknown charts coding");
    // A "next" chart beyond the count is an error, not a panic.
    let many = Charts { triangle_chart: vec![0, 1, 2], chart_material: vec![0, 0, 0], triangle_group: vec![0, 0, 0] };
    let info2 = AppearanceInfo { charts: 2, ..info() };
    assert!(read_charts(&write_charts_new_runs(&many), &info2, 3).is_err());
    assert!(read_charts(&write_charts(&charts), &info(), 7).is_err(), "runs cover 6 of 7");
    // Recent-chart runs: on many charts whose runs go back and forth, cut short or damaged.
    let mut seed = 0x1234_5679u32;
    let mut rnd = move |m: u32| {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed % m
    };
    let mut triangle_chart = Vec::new();
    let mut seen = 0u32;
    while triangle_chart.len() < 900 {
        // A new chart now and then, else one of the last few (repeated and distinct runs).
        let chart = if seen == 0 || rnd(6) == 0 { seen } else { seen - 1 - rnd(seen.min(4)) };
        seen = seen.max(chart + 1);
        triangle_chart.extend(std::iter::repeat_n(chart, 1 + rnd(5) as usize));
    }
    let n = triangle_chart.len() as u32;
    let many =
        Charts { chart_material: (0..seen).map(|c| c % 2).collect(), triangle_group: (0..n).map(|t| t / 100).collect(), triangle_chart };
    let info3 = AppearanceInfo { charts: seen, groups: 10, ..info() };
    let coded = write_charts_recent(&many).unwrap();
    assert_eq!(&coded[..2], &[0, 2]);
    assert_eq!(read_charts(&coded, &info3, n).unwrap(), many);
    assert!(coded.len() < write_charts_new_runs(&many).len(), "{} vs {}", coded.len(), write_charts_new_runs(&many).len());
    for cut in [2, 3, coded.len() / 2, coded.len() - 1] {
        assert!(read_charts(&coded[..cut], &info3, n).is_err(), "cut {cut}");
    }
    for at in 2..coded.len() {
        let mut bad = coded.clone();
        bad[at] ^= 0x5A;
        let _ = read_charts(&bad, &info3, n);
    }
    assert!(read_charts(&coded, &AppearanceInfo { charts: seen - 1, ..info3.clone() }, n).is_err());
    // A run opening a chart other than the next: the coding does not apply.
    let odd = Charts { triangle_chart: vec![1, 0], chart_material: vec![0, 0], triangle_group: vec![0, 0] };
    assert!(write_charts_recent(&odd).is_none());
}

/// A seamed strip over `n` vertices in `charts` charts (every chart boundary a seam: its
/// vertices get one entry per chart), values from `value(entry, channel)`.
fn seamed(n: u32, charts: u32, value: &mut dyn FnMut(usize, usize) -> i32) -> (Vec<[u32; 3]>, Vec<u32>, QuantizedTable) {
    let triangles: Vec<[u32; 3]> = (0..n - 2).map(|i| if i % 2 == 0 { [i, i + 1, i + 2] } else { [i + 1, i, i + 2] }).collect();
    let chart_of: Vec<u32> = (0..n - 2).map(|i| (i * charts) / (n - 2)).collect();
    let entries = band0_entries(&triangles, &chart_of);
    let values = (0..entries.len() * 2).map(|i| value(i / 2, i % 2)).collect();
    (triangles, chart_of, QuantizedTable { entries, values })
}

#[test]
fn rans_coded_residuals_round_trip_every_coding_and_fail_cleanly() {
    let mut seed = 0x9E37_79B9u32;
    let mut rnd = move |m: u32| {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed % m
    };
    let info = AppearanceInfo { charts: 5, ..info() };
    // Repeated values (a palette of 6 texture coordinates), all distinct (a counter, so
    // no two entries agree), and extremes whose residuals escape (beyond 30 bits).
    let palette = [[0, 0], [4095, 17], [1024, 2048], [3, 3000], [700, 701], [2222, 11]];
    let mut p = |e: usize, k: usize| palette[(e * 7 + e / 3) % palette.len()][k];
    let mut distinct = |e: usize, k: usize| (e as i32) * 9 + k as i32 * 40_000;
    let mut wild = |e: usize, k: usize| if (e + k).is_multiple_of(5) { i32::MIN + rnd(7) as i32 } else { rnd(4096) as i32 };
    let values: [&mut dyn FnMut(usize, usize) -> i32; 3] = [&mut p, &mut distinct, &mut wild];
    for (case, value) in values.into_iter().enumerate() {
        let (triangles, chart_of, t) = seamed(300, 5, value);
        let table = read_table(&write_table(&t, 2), "t", 300, &info, 298).unwrap();
        // Listed, chart-wise and derived with rANS-coded residuals: the same table.
        let listed = write_table_rans(&t, 2);
        let chartwise = write_table_chartwise(&t, 2, true);
        let derived = write_table_derived(&t, 2, &triangles, &chart_of, true);
        assert_eq!((listed[1], chartwise[1], derived[1]), (8, 10, 9), "case {case}");
        for raw in [&listed, &chartwise] {
            let back = read_table(raw, "t", 300, &info, 298).unwrap();
            assert_eq!((&back.values, &back.charts, &back.first), (&table.values, &table.charts, &table.first), "case {case}");
        }
        let back = read_table_with(&derived, "t", 300, &info, 298, Some((&triangles, &chart_of))).unwrap();
        assert_eq!(back.values, table.values, "case {case}");
        // From the band above: every third vertex under parent v / 3, the parent's table
        // holding (parent, chart) for some.
        let parent: Vec<u32> = (0..300).map(|v| v / 3).collect();
        let above =
            QuantizedTable { entries: (0..100).map(|p| (p, p * 5 / 100)).collect(), values: (0..200).map(|i| i * 37 % 4096).collect() }
                .to_table();
        let coded = write_table_from_above(&t, 2, &parent, &above, true);
        assert_eq!(coded[1], 11);
        assert!(needs_above(&coded));
        assert_eq!(read_table_above(&coded, "t", 300, &info, 298, Some((&parent, &above))).unwrap().values, table.values);
        // Cut short anywhere, or a byte changed: an error or (a changed mantissa bit) other
        // values, never a panic; cut short is always an error.
        for raw in [&listed, &chartwise, &coded] {
            // (One byte, 0, is a valid empty listed table.)
            for cut in [2, 3, raw.len() / 2, raw.len() - 1] {
                assert!(read_table_above(&raw[..cut], "t", 300, &info, 298, Some((&parent, &above))).is_err(), "case {case} cut {cut}");
            }
            for at in 2..raw.len() {
                let mut bad = raw.clone();
                bad[at] ^= 0x5A;
                let _ = read_table_above(&bad, "t", 300, &info, 298, Some((&parent, &above)));
            }
        }
        for cut in [2, derived.len() / 2, derived.len() - 1] {
            assert!(read_table_with(&derived[..cut], "t", 300, &info, 298, Some((&triangles, &chart_of))).is_err());
        }
        for at in 2..derived.len() {
            let mut bad = derived.clone();
            bad[at] ^= 0x5A;
            let _ = read_table_with(&bad, "t", 300, &info, 298, Some((&triangles, &chart_of)));
        }
    }
    // Repeated values take fewer bytes entropy-coded than as varints.
    let (triangles, chart_of, t) = seamed(300, 5, &mut |e, k| palette[e % 2][k]);
    let varints = write_table_derived(&t, 2, &triangles, &chart_of, false);
    let coded = write_table_derived(&t, 2, &triangles, &chart_of, true);
    assert!(coded.len() < varints.len(), "{} vs {}", coded.len(), varints.len());
    // "0, 0" is no coding: mode 0 only with the rANS flag.
    assert!(read_table(&[0, 0, 0], "t", 300, &info, 298).is_err());
}

#[test]
fn represented_values_round_trip_and_fail_cleanly() {
    let mut seed = 0x51ED_270Bu32;
    let mut rnd = move |m: u32| {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed % m
    };
    let info = AppearanceInfo { charts: 5, ..info() };
    let palette = [[0, 0], [4095, 17], [1024, 2048], [3, 3000]];
    let mut p = |e: usize, k: usize| palette[(e * 5 + e / 7) % palette.len()][k];
    let mut distinct = |e: usize, k: usize| (e as i32) * 13 + k as i32 * 50_000;
    let mut wild = |e: usize, k: usize| if (e + k).is_multiple_of(4) { i32::MAX - rnd(5) as i32 } else { rnd(4096) as i32 };
    let values: [&mut dyn FnMut(usize, usize) -> i32; 3] = [&mut p, &mut distinct, &mut wild];
    for (case, value) in values.into_iter().enumerate() {
        let (triangles, chart_of, t) = seamed(300, 5, value);
        // The band above: nodes v / 3, its value of (v / 3, chart) the representative's
        // (the first of the chart's entries under it), as the encoder's tables make it.
        let parent: Vec<u32> = (0..300).map(|v| v / 3).collect();
        let mut above_entries: Vec<(u32, u32)> = t.entries.iter().map(|&(n, k)| (n / 3, k)).collect();
        above_entries.sort_unstable();
        above_entries.dedup();
        let mut above = QuantizedTable { entries: above_entries.clone(), values: Vec::new() }.to_table();
        above.values = vec![0; above.len() * 2];
        let below = QuantizedTable { entries: t.entries.clone(), values: Vec::new() }.to_table();
        let reps = representatives(&below, &parent, &above);
        assert_eq!(reps.iter().filter(|r| r.is_some()).count(), above.len(), "case {case}: every entry above represented once");
        for (e, r) in reps.iter().enumerate() {
            if let Some(a) = r {
                let a = *a as usize;
                above.values[2 * a..2 * a + 2].copy_from_slice(&t.values[2 * e..2 * e + 2]);
            }
        }
        let ab = Some((&parent[..], &above));
        for rans in [false, true] {
            let listed = write_table_represented(&t, 2, &parent, &above, rans).unwrap();
            let derived = write_table_derived_represented(&t, 2, &triangles, &chart_of, &parent, &above, rans).unwrap();
            let flag = if rans { 8 } else { 0 };
            assert_eq!((listed[1], derived[1]), (19 | flag, 17 | flag), "case {case}");
            assert!(needs_above(&listed) && needs_above(&derived));
            let back = read_band(&listed, "t", 300, &info, 298, None, ab).unwrap();
            assert_eq!((&back.values, &back.charts), (&t.values, &below.charts), "case {case} rans {rans}");
            let back = read_band(&derived, "t", 300, &info, 298, Some((&triangles, &chart_of)), ab).unwrap();
            assert_eq!(back.values, t.values, "case {case} rans {rans}");
            // Fewer residuals than the plain codings: a representative costs nothing.
            let plain = write_table_derived(&t, 2, &triangles, &chart_of, rans);
            assert!(derived.len() < plain.len(), "case {case}: {} vs {}", derived.len(), plain.len());
            // Without the band above, cut short, or damaged: errors (or other values), no panic.
            assert!(read_band(&listed, "t", 300, &info, 298, None, None).is_err());
            assert!(read_band(&derived, "t", 300, &info, 298, Some((&triangles, &chart_of)), None).is_err());
            for raw in [&listed, &derived] {
                for cut in [2, raw.len() / 2, raw.len() - 1] {
                    assert!(read_band(&raw[..cut], "t", 300, &info, 298, Some((&triangles, &chart_of)), ab).is_err(), "cut {cut}");
                }
                for at in 1..raw.len() {
                    let mut bad = raw.clone();
                    bad[at] ^= 0x5A;
                    let _ = read_band(&bad, "t", 300, &info, 298, Some((&triangles, &chart_of)), ab);
                }
            }
            // A band above short of values, or parents for fewer nodes: no panic.
            let _ = read_band(&derived, "t", 300, &info, 298, Some((&triangles, &chart_of)), Some((&parent[..40], &above)));
            let short = Table { values: above.values[..10].to_vec(), ..above.clone() };
            let _ = read_band(&listed, "t", 300, &info, 298, None, Some((&parent[..], &short)));
            let _ = read_band(&derived, "t", 300, &info, 298, Some((&triangles, &chart_of)), Some((&parent[..], &short)));
        }
        // Entries from the band above (mode | 32): a bit per parent chart, the rest listed;
        // with a band above missing every fourth entry, some of this band's are listed.
        let mut sparse = QuantizedTable { entries: Vec::new(), values: Vec::new() };
        for (i, &(n, k)) in above_entries.iter().enumerate().filter(|(i, _)| i % 4 != 1) {
            sparse.entries.push((n, k));
            sparse.values.extend_from_slice(&above.values[2 * i..2 * i + 2]);
        }
        let sparse = sparse.to_table();
        for (up, represented) in [(&above, true), (&above, false), (&sparse, false)] {
            let ab = Some((&parent[..], up));
            let coded = write_table_entries_above(&t, 2, &parent, up, true, represented).unwrap();
            assert_eq!(coded[1], 3 | 32 | 8 | if represented { 16 } else { 0 });
            assert!(needs_above(&coded));
            let back = read_band(&coded, "t", 300, &info, 298, None, ab).unwrap();
            assert_eq!((&back.values, &back.charts, &back.first), (&t.values, &below.charts, &below.first), "case {case}");
            let listed = write_table_represented(&t, 2, &parent, &above, true).unwrap();
            if represented {
                assert!(coded.len() < listed.len(), "case {case}: {} vs {} listed", coded.len(), listed.len());
            }
            assert!(read_band(&coded, "t", 300, &info, 298, None, None).is_err());
            for cut in [2, 3, coded.len() / 2, coded.len() - 1] {
                assert!(read_band(&coded[..cut], "t", 300, &info, 298, None, ab).is_err(), "cut {cut}");
            }
            for at in 2..coded.len() {
                let mut bad = coded.clone();
                bad[at] ^= 0x5A;
                let _ = read_band(&bad, "t", 300, &info, 298, None, ab);
            }
        }
        // A representative whose value is not its parent entry's: the coding does not apply.
        let mut odd = t.clone();
        let first = reps.iter().position(Option::is_some).unwrap();
        odd.values[2 * first] ^= 1;
        assert!(write_table_represented(&odd, 2, &parent, &above, true).is_none());
        assert!(write_table_derived_represented(&odd, 2, &triangles, &chart_of, &parent, &above, true).is_none());
    }
    // Mode 16 alone, or with chart-wise differences; 32 but with mode 3: no coding.
    for mode in [16, 18, 32, 34, 40, 33] {
        assert!(read_band(&[0, mode, 0], "t", 300, &info, 298, None, None).is_err(), "mode {mode}");
    }
}

#[test]
fn derived_band0_tables_round_trip_and_fail_cleanly() {
    // Random triangles over 40 vertices in 3 charts, some degenerate, values anywhere in
    // 32 bits (the predictions wrap).
    let mut seed = 0x2545_F491u32;
    let mut rnd = |m: u32| {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed % m
    };
    let triangles: Vec<[u32; 3]> = (0..90).map(|_| [rnd(40), rnd(40), rnd(40)]).collect();
    let chart_of: Vec<u32> = (0..90).map(|_| rnd(3)).collect();
    let entries = band0_entries(&triangles, &chart_of);
    let t = QuantizedTable {
        values: (0..entries.len() * 2).map(|k| if k % 7 == 0 { i32::MIN + rnd(9) as i32 } else { rnd(4096) as i32 }).collect(),
        entries,
    };
    let raw = write_table_derived(&t, 2, &triangles, &chart_of, false);
    assert_eq!(&raw[..2], &[0, 1]);
    let table = read_table_with(&raw, "t", 40, &info(), 90, Some((&triangles, &chart_of))).unwrap();
    for (e, &(n, k)) in t.entries.iter().enumerate() {
        assert_eq!(table.get(n, k, 2), Some(&t.values[2 * e..2 * e + 2]), "entry ({n}, {k})");
    }
    // Listed tables still read through the same function.
    let listed = read_table_with(&write_table(&t, 2), "t", 40, &info(), 90, None).unwrap();
    assert_eq!(listed.values, table.values);
    // Without band 0's triangles, cut short, or a vertex beyond the nodes: errors.
    assert!(read_table_with(&raw, "t", 40, &info(), 90, None).is_err());
    assert!(read_table_with(&raw[..raw.len() - 1], "t", 40, &info(), 90, Some((&triangles, &chart_of))).is_err());
    assert!(read_table_with(&raw, "t", 39, &info(), 90, Some((&triangles, &chart_of))).is_err());
    let mut odd = raw.clone();
    odd[1] = 2;
    assert!(read_table_with(&odd, "t", 40, &info(), 90, Some((&triangles, &chart_of))).is_err());
}

#[test]
fn neighbour_charts_round_trip_with_the_triangles_and_fail_cleanly() {
    // A grid of 30 x 20 quads in row order, its charts patches of 7 x 5 quads (so a row goes
    // back and forth between patches and a patch's first row follows the one above), numbered
    // in order of first use, the groups by rows.
    let (w, h) = (30u32, 20u32);
    let id = |x: u32, y: u32| y * (w + 1) + x;
    let mut triangles = Vec::new();
    let mut patch = Vec::new();
    for y in 0..h {
        for x in 0..w {
            triangles.push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
            triangles.push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
            patch.extend([x / 7 + 10 * (y / 5); 2]);
        }
    }
    let mut order: Vec<u32> = Vec::new();
    let triangle_chart: Vec<u32> = patch
        .iter()
        .map(|p| match order.iter().position(|q| q == p) {
            Some(i) => i as u32,
            None => {
                order.push(*p);
                order.len() as u32 - 1
            }
        })
        .collect();
    let n = triangles.len() as u32;
    let charts = Charts {
        chart_material: (0..order.len() as u32).map(|c| c % 2).collect(),
        triangle_group: (0..n).map(|t| t / (2 * w)).collect(),
        triangle_chart,
    };
    let info = AppearanceInfo { charts: order.len() as u32, groups: h, ..info() };
    let coded = write_charts_neighbours(&charts, &triangles).unwrap();
    assert_eq!(&coded[..2], &[0, 3]);
    assert!(charts_need_triangles(&coded) && !charts_need_triangles(&write_charts_recent(&charts).unwrap()));
    assert_eq!(read_charts_with(&coded, &info, n, Some(&triangles)).unwrap(), charts);
    // Without the triangles, with too few, cut short, with too few charts: errors; damaged: an
    // error or other charts, never a panic.
    assert!(read_charts(&coded, &info, n).is_err());
    assert!(read_charts_with(&coded, &info, n, Some(&triangles[1..])).is_err());
    for cut in [2, 3, coded.len() / 2, coded.len() - 1] {
        assert!(read_charts_with(&coded[..cut], &info, n, Some(&triangles)).is_err(), "cut {cut}");
    }
    for at in 2..coded.len() {
        let mut bad = coded.clone();
        bad[at] ^= 0x5A;
        let _ = read_charts_with(&bad, &info, n, Some(&triangles));
    }
    let fewer = AppearanceInfo { charts: info.charts - 1, ..info.clone() };
    assert!(read_charts_with(&coded, &fewer, n, Some(&triangles)).is_err());
    // Charts not numbered in order of first use, or triangles and charts apart: no coding.
    let odd = Charts { triangle_chart: vec![1, 0], chart_material: vec![0, 0], triangle_group: vec![0, 0] };
    assert!(write_charts_neighbours(&odd, &triangles[..2]).is_none());
    assert!(write_charts_neighbours(&charts, &triangles[1..]).is_none());
}

#[test]
fn band0_with_bind_positions_round_trips_and_fails_cleanly() {
    // A bent grid of 16 x 12 quads (a 3D surface: a quarter cylinder), unwrapped without
    // distortion (u along the arc, v along the axis) in two charts, left and right halves,
    // quads' diagonals alternating; a third chart of scattered triangles with random values
    // anywhere in 32 bits and positions up to and beyond the 2^28 limit (the projection falls
    // back there), some corners repeated (degenerate).
    let (w, h) = (16u32, 12u32);
    let id = |x: u32, y: u32| y * (w + 1) + x;
    let mut bind: Vec<[i64; 3]> = Vec::new();
    for y in 0..=h {
        for x in 0..=w {
            let a = std::f64::consts::FRAC_PI_2 * x as f64 / w as f64;
            bind.push([(4000.0 * a.cos()).round() as i64, (4000.0 * a.sin()).round() as i64, 400 * y as i64]);
        }
    }
    let mut triangles = Vec::new();
    let mut chart_of = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let q = if (x + y) % 2 == 0 {
                [[id(x, y), id(x + 1, y), id(x + 1, y + 1)], [id(x, y), id(x + 1, y + 1), id(x, y + 1)]]
            } else {
                [[id(x, y), id(x + 1, y), id(x, y + 1)], [id(x + 1, y), id(x + 1, y + 1), id(x, y + 1)]]
            };
            triangles.extend(q);
            chart_of.extend([u32::from(x >= w / 2); 2]);
        }
    }
    let grid = bind.len() as u32;
    let mut seed = 0x9E37_79B9u32;
    let mut rnd = |m: u32| {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed % m
    };
    for i in 0..40u32 {
        bind.push([0, 1, 2].map(|_| rnd(1 << 30) as i64 - (1 << 29)));
        let t = [grid + i, grid + rnd(40), if i % 5 == 0 { grid + i } else { grid + rnd(40) }];
        triangles.push(t);
        chart_of.push(2);
    }
    let entries = band0_entries(&triangles, &chart_of);
    let values = entries
        .iter()
        .flat_map(|&(n, _)| {
            if n < grid {
                // The arc's length is pi/2 * 4000 ~ 6283 bind quanta over 16 columns: 10 per
                // quantum in u (about 628 texels), v likewise 400 per row / 10.
                let (x, y) = (n % (w + 1), n / (w + 1));
                [(6283 * x / w) as i32 / 10, 40 * y as i32]
            } else {
                [rnd(u32::MAX) as i32, rnd(u32::MAX) as i32]
            }
        })
        .collect();
    let t = QuantizedTable { entries, values };
    let tris = (&triangles[..], &chart_of[..]);
    let nodes = bind.len() as u32;
    let raw = write_table_derived_bind(&t, 2, tris, None, &bind, true).unwrap();
    assert_eq!(&raw[..2], &[0, 1 | 4 | 8]);
    assert!(needs_bind(&raw));
    let band0 = (triangles.len() as u32, Some(tris));
    let table = read_band_bind(&raw, "t", nodes, &info(), band0, None, Some(&bind)).unwrap();
    for (e, &(n, k)) in t.entries.iter().enumerate() {
        assert_eq!(table.get(n, k, 2), Some(&t.values[2 * e..2 * e + 2]), "entry ({n}, {k})");
    }
    // The bind pose places the grid's coordinates: fewer bytes than the parallelogram rule.
    let plain = write_table_derived(&t, 2, &triangles, &chart_of, true);
    assert!(!needs_bind(&plain));
    assert!(raw.len() < plain.len(), "{} bytes with bind positions, {} without", raw.len(), plain.len());
    // Without the bind positions, with too few, cut short, without texture coordinates, or
    // beside values across the faces (mode 1 | 16 | 64): errors.
    assert!(read_band_bind(&raw, "t", nodes, &info(), band0, None, None).is_err());
    assert!(read_band_bind(&raw, "t", nodes, &info(), band0, None, Some(&bind[..10])).is_err());
    assert!(read_band_bind(&raw[..raw.len() - 1], "t", nodes, &info(), band0, None, Some(&bind)).is_err());
    let bare = AppearanceInfo { uv_sets: 0, colors: true, ..info() };
    assert!(read_band_bind(&raw, "t", nodes, &bare, band0, None, Some(&bind)).is_err());
    let mut odd = raw.clone();
    odd[1] |= 16 | 64;
    assert!(read_band_bind(&odd, "t", nodes, &info(), band0, None, Some(&bind)).is_err());
}
