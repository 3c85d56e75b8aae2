//! Charts mode 4, *grown charts* (proto/container.md, "Charts"): each chart grown over the
//! triangles' edges from a seed, one yes-or-no answer per triangle the region reaches, as
//! Draco and Edgebreaker mark attribute seams along their traversal rather than naming each
//! triangle's chart (Rossignac, "Edgebreaker: connectivity compression for triangle meshes",
//! 1999; Isenburg & Snoeyink, "Compressing texture coordinates with selective linear
//! predictions", 2003). Why: a chart is a connected patch, so inside it every answer is yes
//! and the noes sit on its seams; coded as the lengths of the runs of yes (adaptive Rice or
//! rANS, `codes`), Fox's 576 triangles in 24 charts take about 60 B where naming each
//! triangle's chart in input order took about 190.

use super::codes::{put_codes, read_codes};
use crate::ContainerError;
use crate::payload::{Cursor, put};

/// Each triangle's edge neighbours, flattened: triangle t's are `list[start[t]..start[t + 1]]`,
/// for its edges v0v1, v1v2, v2v0 in turn the other triangles with that edge (either
/// direction) in increasing index.
struct Neighbours {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Neighbours {
    fn new(triangles: &[[u32; 3]]) -> Neighbours {
        let key = |a: u32, b: u32| ((a.min(b) as u64) << 32) | a.max(b) as u64;
        let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for i in 0..3 {
                edges.push((key(tri[i], tri[(i + 1) % 3]), t as u32));
            }
        }
        edges.sort_unstable();
        let mut start = Vec::with_capacity(triangles.len() + 1);
        let mut list = Vec::new();
        start.push(0);
        for (t, tri) in triangles.iter().enumerate() {
            for i in 0..3 {
                let k = key(tri[i], tri[(i + 1) % 3]);
                let from = edges.partition_point(|e| e.0 < k);
                for &(ek, u) in &edges[from..] {
                    if ek != k {
                        break;
                    }
                    if u as usize != t {
                        list.push(u);
                    }
                }
            }
            start.push(list.len() as u32);
        }
        Neighbours { start, list }
    }

    fn of(&self, t: u32) -> &[u32] {
        &self.list[self.start[t as usize] as usize..self.start[t as usize + 1] as usize]
    }
}

/// Grows the charts of `n` triangles: the lowest triangle without a chart is a seed and takes
/// `seed(t)`'s chart; its region then grows breadth first (a FIFO queue from the seed), each
/// triangle taken in turn visiting its [`Neighbours`] in order; a neighbour without a chart
/// that this region has not asked before is asked `same(u, chart)`: yes, it joins (and is
/// queued), no, it is left for a later seed. Returns each triangle's chart.
fn grow(
    triangles: &[[u32; 3]],
    mut seed: impl FnMut(u32) -> Result<u32, ContainerError>,
    mut same: impl FnMut(u32, u32) -> Result<bool, ContainerError>,
) -> Result<Vec<u32>, ContainerError> {
    const NONE: u32 = u32::MAX;
    let nb = Neighbours::new(triangles);
    let mut chart_of = vec![NONE; triangles.len()];
    // The region that last asked a triangle (regions numbered from 1), so no region asks twice.
    let mut asked = vec![0u32; triangles.len()];
    let mut queue: Vec<u32> = Vec::new();
    let mut region = 0u32;
    for s in 0..triangles.len() as u32 {
        if chart_of[s as usize] != NONE {
            continue;
        }
        region += 1;
        let chart = seed(s)?;
        chart_of[s as usize] = chart;
        queue.clear();
        queue.push(s);
        let mut at = 0;
        while let Some(&t) = queue.get(at) {
            at += 1;
            for &u in nb.of(t) {
                if chart_of[u as usize] != NONE || asked[u as usize] == region {
                    continue;
                }
                asked[u as usize] = region;
                if same(u, chart)? {
                    chart_of[u as usize] = chart;
                    queue.push(u);
                }
            }
        }
    }
    Ok(chart_of)
}

/// The charts part of a mode-4 CHARTS payload: `S` and a RESIDUALS section ([`put_codes`], one
/// channel) of the S seeds' codes (0 when the seed's chart is the next one not yet seen, else
/// chart + 1); `R` and a RESIDUALS section of R codes: the lengths of the runs of yes answers
/// of [`grow`], each run ended by a no (the last by the end). `None` when the charts and
/// triangles disagree in number.
pub(super) fn put_grown(out: &mut Vec<u8>, triangle_chart: &[u32], triangles: &[[u32; 3]]) -> Option<()> {
    if triangles.len() != triangle_chart.len() {
        return None;
    }
    let mut seeds = Vec::new();
    let mut runs = vec![0u32];
    let mut next = 0u32;
    let grown = grow(
        triangles,
        |s| {
            let chart = triangle_chart[s as usize];
            seeds.push(if chart == next { 0 } else { chart + 1 });
            next = next.max(chart + 1);
            Ok(chart)
        },
        |u, chart| {
            let yes = triangle_chart[u as usize] == chart;
            match runs.last_mut() {
                Some(r) if yes => *r += 1,
                _ => runs.push(0),
            }
            Ok(yes)
        },
    )
    .ok()?;
    debug_assert_eq!(grown, triangle_chart);
    put(out, seeds.len() as u32);
    put_codes(out, &seeds, seeds.len(), 1, true);
    put(out, runs.len() as u32);
    put_codes(out, &runs, runs.len(), 1, true);
    Some(())
}

/// Reads the charts part [`put_grown`] wrote, for `charts` charts over `triangles`.
pub(super) fn read_grown(c: &mut Cursor<'_>, charts: u32, triangles: &[[u32; 3]]) -> Result<Vec<u32>, ContainerError> {
    let bad = |detail: String| ContainerError::Corrupt { what: "charts chunk".into(), detail };
    let n = triangles.len() as u64;
    let s = c.count(n, "chart seeds")?;
    let seeds = read_codes(c, s, 1, true)?;
    // Every answer but the last run's end is a triangle's: at most n runs beside the first.
    let r = c.count(n + 1, "chart runs")?;
    let runs = read_codes(c, r, 1, true)?;
    let (mut next_seed, mut next_run, mut left) = (0usize, 0usize, None::<u32>);
    let mut next_chart = 0u32;
    let chart_of = grow(
        triangles,
        |t| {
            let code = *seeds.get(next_seed).ok_or_else(|| bad(format!("more than {s} seeds at triangle {t}")))?;
            next_seed += 1;
            let chart = if code == 0 { next_chart } else { code - 1 };
            if chart >= charts {
                return Err(bad(format!("chart {chart} out of range (< {charts}) at triangle {t}")));
            }
            next_chart = next_chart.max(chart + 1);
            Ok(chart)
        },
        |u, _| {
            let l = match left {
                Some(l) => l,
                None => {
                    let l = *runs.first().ok_or_else(|| bad("no chart runs".into()))?;
                    next_run = 1;
                    l
                }
            };
            if l > 0 {
                left = Some(l - 1);
                return Ok(true);
            }
            let l = *runs.get(next_run).ok_or_else(|| bad(format!("more than {r} chart runs at triangle {u}")))?;
            next_run += 1;
            left = Some(l);
            Ok(false)
        },
    )?;
    let ended = match left {
        None => r == 1 && runs[0] == 0,
        Some(l) => l == 0 && next_run == r,
    };
    if next_seed != s || !ended {
        return Err(bad(format!("{s} seeds and {r} runs where the charts take {next_seed} and {next_run}")));
    }
    Ok(chart_of)
}

#[cfg(test)]
mod tests {
    use super::super::charts::Charts;
    use super::super::format::AppearanceInfo;
    use super::super::payload::{charts_need_triangles, read_charts, read_charts_with, write_charts_grown, write_charts_neighbours};
    use crate::testing::Rng;

    /// A grid of `w` x `h` quads (two triangles each) in shuffled order, its charts patches of
    /// 6 x 4 quads; one chart is two patches apart (so a seed names an old chart); then a
    /// triangle on an edge two others share (non-manifold), a degenerate one, a lone one.
    fn mesh(seed: u64) -> (Vec<[u32; 3]>, Charts, AppearanceInfo) {
        let (w, h) = (24u32, 16u32);
        let id = |x: u32, y: u32| y * (w + 1) + x;
        let mut tris = Vec::new();
        let mut patch = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let p = if (x / 6, y / 4) == (3, 3) { 0 } else { x / 6 + 10 * (y / 4) };
                tris.push(([id(x, y), id(x + 1, y), id(x + 1, y + 1)], p));
                tris.push(([id(x, y), id(x + 1, y + 1), id(x, y + 1)], p));
            }
        }
        let far = id(w, h) + 1;
        tris.push(([id(0, 0), id(1, 0), far], 99));
        tris.push(([far, far, id(2, 0)], 99));
        tris.push(([far + 1, far + 2, far + 3], 98));
        let mut rng = Rng::new(seed);
        for i in (1..tris.len()).rev() {
            tris.swap(i, rng.below(i + 1));
        }
        let mut order: Vec<u32> = Vec::new();
        for (_, p) in &tris {
            patch.push(match order.iter().position(|q| q == p) {
                Some(i) => i as u32,
                None => {
                    order.push(*p);
                    order.len() as u32 - 1
                }
            });
        }
        let n = tris.len() as u32;
        let charts = Charts {
            chart_material: (0..order.len() as u32).map(|c| c % 2).collect(),
            triangle_group: vec![0; n as usize],
            triangle_chart: patch,
        };
        let info = AppearanceInfo { charts: order.len() as u32, groups: 1, ..super::super::payload::tests::info() };
        (tris.into_iter().map(|(t, _)| t).collect(), charts, info)
    }

    #[test]
    fn grown_charts_round_trip_and_cost_a_fraction_of_naming_each_triangles_chart() {
        for seed in 0..4 {
            let (tris, charts, info) = mesh(seed);
            let n = tris.len() as u32;
            let coded = write_charts_grown(&charts, &tris).unwrap();
            assert_eq!(&coded[..2], &[0, 4]);
            assert!(charts_need_triangles(&coded));
            assert_eq!(read_charts_with(&coded, &info, n, Some(&tris)).unwrap(), charts, "seed {seed}");
            // The same charts in input order with neighbour candidates: the shuffled order
            // leaves that coding little to go on, the grown regions do not care.
            let neighbours = write_charts_neighbours(&charts, &tris).unwrap();
            assert!(coded.len() * 2 < neighbours.len(), "grown {} B, neighbours {} B", coded.len(), neighbours.len());
        }
        // Charts numbered in any order still round-trip (seeds then name them).
        let (tris, mut charts, info) = mesh(9);
        let last = info.charts - 1;
        for c in &mut charts.triangle_chart {
            *c = last - *c;
        }
        let coded = write_charts_grown(&charts, &tris).unwrap();
        assert_eq!(read_charts_with(&coded, &info, tris.len() as u32, Some(&tris)).unwrap(), charts);
        assert!(write_charts_grown(&charts, &tris[1..]).is_none());
        assert!(write_charts_grown(&Charts::default(), &[]).is_none());
    }

    #[test]
    fn damaged_grown_charts_are_errors_never_panics() {
        let (tris, charts, info) = mesh(3);
        let n = tris.len() as u32;
        let coded = write_charts_grown(&charts, &tris).unwrap();
        assert!(read_charts(&coded, &info, n).is_err(), "without the triangles");
        assert!(read_charts_with(&coded, &info, n, Some(&tris[1..])).is_err());
        for cut in 2..coded.len() {
            assert!(read_charts_with(&coded[..cut], &info, n, Some(&tris)).is_err(), "cut {cut}");
        }
        let fewer = AppearanceInfo { charts: info.charts - 1, ..info.clone() };
        assert!(read_charts_with(&coded, &fewer, n, Some(&tris)).is_err());
        // Other triangles (the same count): the answers no longer fit the regions, or fit other
        // charts; never a panic.
        let mut other = tris.clone();
        other.reverse();
        let _ = read_charts_with(&coded, &info, n, Some(&other));
        let mut rng = Rng::new(5);
        for _ in 0..3000 {
            let mut bad = coded.clone();
            let i = 2 + rng.below(bad.len() - 2);
            bad[i] ^= 1 << rng.below(8);
            let _ = read_charts_with(&bad, &info, n, Some(&tris));
        }
    }
}
