//! The Charts chunk payload (proto/container.md, "Charts"): each triangle's chart as runs in
//! input order (plain, new-chart or recent-chart runs), each chart's material, and the
//! smoothing groups' runs.

use super::charts::Charts;
use super::codes::{put_codes, read_codes};
use super::format::AppearanceInfo;
use crate::ContainerError;
use crate::payload::{Cursor, put, unzigzag, zigzag};

/// Runs of equal values: (value, length).
fn runs(values: &[u32]) -> Vec<(u32, u32)> {
    let mut runs: Vec<(u32, u32)> = Vec::new();
    for &v in values {
        match runs.last_mut() {
            Some((last, n)) if *last == v => *n += 1,
            _ => runs.push((v, 1)),
        }
    }
    runs
}

/// CHARTS: `C`, then per chart its material; then runs of equal chart ids over the triangles
/// in input order: `R`, then per run the chart and its length; then runs of equal smoothing
/// groups likewise, each group as the zigzag-coded difference from the previous run's (from
/// 0): a flat-shaded input's groups climb by one per triangle.
pub fn write_charts(c: &Charts) -> Vec<u8> {
    write_charts_coded(c, false)
}

/// CHARTS with *new-chart runs*: `0`, `1`, then the layout of [`write_charts`] but each run's
/// chart coded as 0 when it is the next chart not yet seen (`next`, from 0, then one more),
/// else as `chart + 1`: charts are numbered in order of their first triangle, so a run that
/// opens a chart is always the next one (on Parrot's 220 UV islands, 30% fewer bytes).
pub fn write_charts_new_runs(c: &Charts) -> Vec<u8> {
    write_charts_coded(c, true)
}

/// The mode of [`write_charts_new_runs`], after a first byte 0 (a count of charts is at least 1).
const NEW_CHART_RUNS: u32 = 1;
/// The mode of [`write_charts_recent`].
const RECENT_CHART_RUNS: u32 = 2;

/// CHARTS with *recent-chart runs*: `0`, `2`, `C` and the charts' materials as [`write_charts`];
/// then `R` and a RESIDUALS section ([`put_codes`], rANS) of 2 R codes: channel 0, per run its
/// chart as 0 when it is the next chart not yet seen, else as its position in the list of the
/// charts seen, most recently used first (move to front: the run's chart then moves to the
/// front, a new chart enters there; position 0, the previous run's chart, never occurs);
/// channel 1, per run its length minus 1; then the group runs as [`write_charts`]. Why: the
/// input's triangle order goes back and forth between a few neighbouring charts (Fox's 264
/// runs over 24 charts, Parrot's 422 over 220), which a short list of recent charts names in a
/// few bits (Bentley, Sleator, Tarjan & Wei, "A locally adaptive data compression scheme",
/// 1986), where varints under zstd took a byte or two per run. `None` when a run opens a chart
/// other than the next one (charts are numbered in order of their first triangle).
pub fn write_charts_recent(c: &Charts) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, RECENT_CHART_RUNS);
    put(&mut out, c.count() as u32);
    for &m in &c.chart_material {
        put(&mut out, m);
    }
    let charts = runs(&c.triangle_chart);
    let mut recent: Vec<u32> = Vec::new();
    let mut next = 0u32;
    let mut codes = vec![0u32; 2 * charts.len()];
    for (i, &(ch, n)) in charts.iter().enumerate() {
        if ch == next {
            next += 1;
        } else {
            let at = recent.iter().position(|&x| x == ch)?;
            codes[i] = at as u32;
            recent.remove(at);
        }
        recent.insert(0, ch);
        codes[charts.len() + i] = n - 1;
    }
    put(&mut out, charts.len() as u32);
    put_codes(&mut out, &codes, charts.len(), 2, true);
    put_group_runs(&mut out, c);
    Some(out)
}

/// The mode of [`write_charts_neighbours`].
const NEIGHBOUR_CHARTS: u32 = 3;

/// Per triangle of `triangles`, in order, its *candidates*: the chart of the triangle before
/// (`recent[0]`), then the charts of its earlier edge neighbours (edges v0v1, v1v2, v2v0, each
/// the first earlier triangle with that edge), each once. `chart_of` holds the charts of the
/// triangles before.
fn candidates(tri: &[u32; 3], edges: &std::collections::HashMap<(u32, u32), u32>, chart_of: &[u32], recent: &[u32], out: &mut Vec<u32>) {
    out.clear();
    out.extend(recent.first());
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        if let Some(&u) = edges.get(&(a.min(b), a.max(b)))
            && let Some(&k) = chart_of.get(u as usize)
            && !out.contains(&k)
        {
            out.push(k);
        }
    }
}

/// Records triangle `t`'s edges where no earlier triangle has them.
fn add_edges(tri: &[u32; 3], t: u32, edges: &mut std::collections::HashMap<(u32, u32), u32>) {
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        edges.entry((a.min(b), a.max(b))).or_insert(t);
    }
}

/// The code of a chart not among the candidates: 4 for the next chart not yet seen, else
/// `5 + its position in the recent list`.
const NEXT_CHART: u32 = 4;

/// CHARTS with *neighbour charts*: `0`, `3`, `C` and the charts' materials as [`write_charts`];
/// then a RESIDUALS section ([`put_codes`], rANS, one channel) of one code per triangle in input
/// order: its chart's position among its [`candidates`] (0 the previous triangle's chart, 1..3
/// an earlier edge neighbour's), else 4 when it is the next chart not yet seen, else 5 + its
/// position in the list of charts seen, most recently used first (each triangle's chart then
/// moves to its front); then the group runs as [`write_charts`]. It needs the Triangles chunk.
/// Why: a chart is edge-connected, so a triangle that leaves the previous one's chart almost
/// always joins an earlier neighbour's (Fox: 150 of its 264 chart changes are the first such
/// neighbour's), which a run coding cannot see. `None` when a triangle opens a chart other than
/// the next one, or the triangles and charts disagree in number.
pub fn write_charts_neighbours(c: &Charts, triangles: &[[u32; 3]]) -> Option<Vec<u8>> {
    if triangles.len() != c.triangle_chart.len() {
        return None;
    }
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, NEIGHBOUR_CHARTS);
    put(&mut out, c.count() as u32);
    for &m in &c.chart_material {
        put(&mut out, m);
    }
    let mut edges = std::collections::HashMap::new();
    let mut recent: Vec<u32> = Vec::new();
    let mut cands = Vec::new();
    let mut next = 0u32;
    let mut codes = Vec::with_capacity(triangles.len());
    for (t, (tri, &chart)) in triangles.iter().zip(&c.triangle_chart).enumerate() {
        candidates(tri, &edges, &c.triangle_chart[..t], &recent, &mut cands);
        let at = recent.iter().position(|&x| x == chart);
        codes.push(match cands.iter().position(|&x| x == chart) {
            Some(i) => i as u32,
            None if chart == next => NEXT_CHART,
            None => NEXT_CHART + 1 + at? as u32,
        });
        if chart == next {
            next += 1;
        }
        if let Some(at) = at {
            recent.remove(at);
        }
        recent.insert(0, chart);
        add_edges(tri, t as u32, &mut edges);
    }
    put_codes(&mut out, &codes, codes.len(), 1, true);
    put_group_runs(&mut out, c);
    Some(out)
}

/// The mode of [`write_charts_grown`].
const GROWN_CHARTS: u32 = 4;

/// CHARTS with *grown charts*: `0`, `4`, `C` and the charts' materials as [`write_charts`];
/// then each chart grown from seeds over the triangles' edges ([`super::grown_charts`]); then
/// the group runs as [`write_charts`]. It needs the Triangles chunk. `None` without triangles
/// or when the triangles and charts disagree in number.
pub fn write_charts_grown(c: &Charts, triangles: &[[u32; 3]]) -> Option<Vec<u8>> {
    if triangles.is_empty() {
        return None;
    }
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, GROWN_CHARTS);
    put(&mut out, c.count() as u32);
    for &m in &c.chart_material {
        put(&mut out, m);
    }
    super::grown_charts::put_grown(&mut out, &c.triangle_chart, triangles)?;
    put_group_runs(&mut out, c);
    Some(out)
}

/// Whether a Charts payload needs the triangles (mode 3, [`write_charts_neighbours`], and mode
/// 4, [`write_charts_grown`]).
pub fn charts_need_triangles(bytes: &[u8]) -> bool {
    bytes.len() > 1 && bytes[0] == 0 && (bytes[1] == NEIGHBOUR_CHARTS as u8 || bytes[1] == GROWN_CHARTS as u8)
}

/// The charts of [`write_charts_neighbours`] (after the materials), appended to `chart_of`.
fn read_neighbour_charts(
    c: &mut Cursor<'_>,
    info: &AppearanceInfo,
    triangles: &[[u32; 3]],
    chart_of: &mut Vec<u32>,
) -> Result<(), ContainerError> {
    let bad = |detail: String| ContainerError::Corrupt { what: "charts chunk".into(), detail };
    let codes = read_codes(c, triangles.len(), 1, true)?;
    let mut edges = std::collections::HashMap::new();
    let mut recent: Vec<u32> = Vec::new();
    let mut cands = Vec::new();
    let mut next = 0u32;
    for (t, (tri, &code)) in triangles.iter().zip(&codes).enumerate() {
        candidates(tri, &edges, chart_of, &recent, &mut cands);
        let chart = match code {
            i if i < NEXT_CHART => {
                *cands.get(i as usize).ok_or_else(|| bad(format!("candidate {i} of {} at triangle {t}", cands.len())))?
            }
            NEXT_CHART => next,
            p => *recent.get((p - NEXT_CHART - 1) as usize).ok_or_else(|| bad(format!("recent chart {p} at triangle {t}")))?,
        };
        if chart >= info.charts {
            return Err(bad(format!("chart {chart} out of range (< {}) at triangle {t}", info.charts)));
        }
        if chart == next {
            next += 1;
        }
        if let Some(at) = recent.iter().position(|&x| x == chart) {
            recent.remove(at);
        }
        recent.insert(0, chart);
        chart_of.push(chart);
        add_edges(tri, t as u32, &mut edges);
    }
    Ok(())
}

/// The group runs of [`write_charts`]: `G`, then per run the zigzag-coded difference of its
/// group from the previous run's (from 0) and its length.
fn put_group_runs(out: &mut Vec<u8>, c: &Charts) {
    let groups = runs(&c.triangle_group);
    put(out, groups.len() as u32);
    let mut last = 0u32;
    for (g, n) in groups {
        put(out, zigzag(g.wrapping_sub(last) as i32));
        put(out, n);
        last = g;
    }
}

fn write_charts_coded(c: &Charts, new_runs: bool) -> Vec<u8> {
    let mut out = Vec::new();
    if new_runs {
        put(&mut out, 0);
        put(&mut out, NEW_CHART_RUNS);
    }
    put(&mut out, c.count() as u32);
    for &m in &c.chart_material {
        put(&mut out, m);
    }
    let charts = runs(&c.triangle_chart);
    put(&mut out, charts.len() as u32);
    let mut next = 0u32;
    for (ch, n) in charts {
        if !new_runs {
            put(&mut out, ch);
        } else if ch == next {
            put(&mut out, 0);
            next += 1;
        } else {
            put(&mut out, ch + 1);
        }
        put(&mut out, n);
    }
    put_group_runs(&mut out, c);
    out
}

/// Reads a Charts chunk of `triangles` triangles (proto/container.md, "Charts"): each
/// triangle's chart and smoothing group, either coding; errors name the chunk and what is wrong.
pub fn read_charts(bytes: &[u8], info: &AppearanceInfo, triangles: u32) -> Result<Charts, ContainerError> {
    read_charts_with(bytes, info, triangles, None)
}

/// [`read_charts`] with the triangles (the Triangles chunk), which a Charts chunk with
/// neighbour charts needs ([`charts_need_triangles`] says whether).
pub fn read_charts_with(bytes: &[u8], info: &AppearanceInfo, triangles: u32, tris: Option<&[[u32; 3]]>) -> Result<Charts, ContainerError> {
    let what = "charts chunk";
    let bad = |detail: String| ContainerError::Corrupt { what: what.into(), detail };
    let mut c = Cursor::new(bytes, what);
    let coded = bytes.first() == Some(&0);
    let mut recent_runs = false;
    let mut neighbours = None;
    let mut grown = false;
    if coded {
        c.get()?;
        let mode = c.get()?;
        recent_runs = mode == RECENT_CHART_RUNS;
        grown = mode == GROWN_CHARTS;
        if mode == NEIGHBOUR_CHARTS || grown {
            let t = tris.ok_or_else(|| bad("neighbour charts without the triangles".into()))?;
            if t.len() != triangles as usize {
                return Err(bad(format!("{} triangles where the header says {triangles}", t.len())));
            }
            neighbours = Some(t);
        } else if mode != NEW_CHART_RUNS && !recent_runs {
            return Err(bad(format!("charts coding {mode} unknown")));
        }
    }
    let new_runs = coded && !recent_runs && neighbours.is_none();
    let count = c.count_within(info.charts as u64, 1, "charts")?;
    if count != info.charts as usize {
        return Err(bad(format!("{count} charts where the header says {}", info.charts)));
    }
    let mut charts = Charts { triangle_chart: Vec::with_capacity(triangles as usize), ..Default::default() };
    for _ in 0..count {
        charts.chart_material.push(c.id(info.materials.max(1), "material")?);
    }
    if recent_runs {
        read_recent_runs(&mut c, info, triangles, &mut charts.triangle_chart)?;
    }
    match neighbours {
        Some(t) if grown => charts.triangle_chart = super::grown_charts::read_grown(&mut c, info.charts, t)?,
        Some(t) => read_neighbour_charts(&mut c, info, t, &mut charts.triangle_chart)?,
        None => {}
    }
    let n = if recent_runs || neighbours.is_some() { 0 } else { c.count_within(triangles as u64, 2, "chart runs")? };
    let mut next = 0u32;
    for _ in 0..n {
        let chart = if !new_runs {
            c.id(info.charts, "chart")?
        } else {
            match c.get()? {
                0 => {
                    next += 1;
                    next - 1
                }
                x => x - 1,
            }
        };
        if chart >= info.charts {
            return Err(bad(format!("chart {chart} out of range (< {})", info.charts)));
        }
        let len = c.get()?;
        if len == 0 || charts.triangle_chart.len() as u64 + len as u64 > triangles as u64 {
            return Err(bad(format!("a run of {len} triangles after {} of {triangles}", charts.triangle_chart.len())));
        }
        charts.triangle_chart.extend(std::iter::repeat_n(chart, len as usize));
    }
    if charts.triangle_chart.len() != triangles as usize {
        return Err(bad(format!("chart runs cover {} of {triangles} triangles", charts.triangle_chart.len())));
    }
    charts.triangle_group.reserve(triangles as usize);
    let n = c.count_within(triangles as u64, 2, "group runs")?;
    let mut last = 0u32;
    for _ in 0..n {
        let group = last.wrapping_add(unzigzag(c.get()?) as u32);
        if group >= info.groups {
            return Err(bad(format!("smoothing group {group} out of range (< {})", info.groups)));
        }
        last = group;
        let len = c.get()?;
        if len == 0 || charts.triangle_group.len() as u64 + len as u64 > triangles as u64 {
            return Err(bad(format!("a run of {len} triangles after {} of {triangles}", charts.triangle_group.len())));
        }
        charts.triangle_group.extend(std::iter::repeat_n(group, len as usize));
    }
    if charts.triangle_group.len() != triangles as usize {
        return Err(bad(format!("group runs cover {} of {triangles} triangles", charts.triangle_group.len())));
    }
    c.finish()?;
    Ok(charts)
}

/// The chart runs of [`write_charts_recent`] (after the materials), appended to `chart_of`.
fn read_recent_runs(c: &mut Cursor<'_>, info: &AppearanceInfo, triangles: u32, chart_of: &mut Vec<u32>) -> Result<(), ContainerError> {
    let bad = |detail: String| ContainerError::Corrupt { what: "charts chunk".into(), detail };
    let n = c.count(triangles as u64, "chart runs")?;
    let codes = read_codes(c, n, 2, true)?;
    let mut recent: Vec<u32> = Vec::new();
    let mut next = 0u32;
    for i in 0..n {
        let chart = match codes[i] as usize {
            0 => {
                next += 1;
                next - 1
            }
            at if at < recent.len() => recent.remove(at),
            at => return Err(bad(format!("recent chart {at} of {}", recent.len()))),
        };
        if chart >= info.charts {
            return Err(bad(format!("chart {chart} out of range (< {})", info.charts)));
        }
        recent.insert(0, chart);
        let len = codes[n + i] as u64 + 1;
        if chart_of.len() as u64 + len > triangles as u64 {
            return Err(bad(format!("a run of {len} triangles after {} of {triangles}", chart_of.len())));
        }
        chart_of.extend(std::iter::repeat_n(chart, len as usize));
    }
    Ok(())
}
