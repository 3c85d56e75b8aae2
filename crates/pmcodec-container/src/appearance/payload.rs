//! The Charts and Attributes chunk payloads (varints, as every payload; proto/container.md,
//! "Appearance").

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
    let what = "charts chunk";
    let bad = |detail: String| ContainerError::Corrupt { what: what.into(), detail };
    let mut c = Cursor::new(bytes, what);
    let coded = bytes.first() == Some(&0);
    let mut recent_runs = false;
    if coded {
        c.get()?;
        let mode = c.get()?;
        recent_runs = mode == RECENT_CHART_RUNS;
        if mode != NEW_CHART_RUNS && !recent_runs {
            return Err(bad(format!("charts coding {mode} unknown")));
        }
    }
    let new_runs = coded && !recent_runs;
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
    let n = if recent_runs { 0 } else { c.count_within(triangles as u64, 2, "chart runs")? };
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

/// One level's attribute table: entries ascending by (node, chart), each with `channels`
/// quantized values (texture coordinates in `uv_step` units from `uv_min`, colours 0..=255).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct QuantizedTable {
    /// The (node, chart) pairs, ascending.
    pub entries: Vec<(u32, u32)>,
    /// `entries.len() * channels` values, entry after entry.
    pub values: Vec<i32>,
}

/// ATTRIBUTES, band j: `m`, then m entries ascending by (node, chart): the node as its
/// difference from the previous entry's (from 0), the chart as is when the node differs and as
/// `chart - previous chart - 1` when it repeats; then, channel by channel, the m values as
/// zigzag-coded differences from the previous entry's value of that channel (from 0).
pub fn write_table(t: &QuantizedTable, channels: usize) -> Vec<u8> {
    let mut out = Vec::new();
    write_listed(&mut out, t, channels, false, None, false);
    out
}

/// ATTRIBUTES listed as [`write_table`], with *entropy-coded values*: `0`, `8`, then that
/// layout with the value residuals as a [`put_codes`] rANS section instead of varints.
pub fn write_table_rans(t: &QuantizedTable, channels: usize) -> Vec<u8> {
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, RANS_VALUES);
    write_listed(&mut out, t, channels, false, None, true);
    out
}

/// ATTRIBUTES with *chart-wise differences*: `0`, `2`, then the layout of [`write_table`] but
/// each value the difference from the previous entry's of the same chart (from 0): charts sit
/// in separate regions of the texture, and the previous entry in node order is often in
/// another (10% to 25% fewer value bytes in the bands above 0 of issue 16's inputs).
/// With `rans`, the mode is `2 | 8` and the residuals a [`put_codes`] rANS section.
pub fn write_table_chartwise(t: &QuantizedTable, channels: usize, rans: bool) -> Vec<u8> {
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, CHARTWISE | if rans { RANS_VALUES } else { 0 });
    write_listed(&mut out, t, channels, true, None, rans);
    out
}

/// ATTRIBUTES of a band j below the top with *values from the band above*: `0`, `3`, then the
/// layout of [`write_table`] but each value the difference from the prediction: the value of
/// (parent of the node in frame 0's hierarchy (the Key chunk of frame 0, band j), the same
/// chart) in band j+1's table when it has that entry, else the previous value of the same chart
/// in this table (from 0). A coarse value is the area-weighted mean of its children's, so a
/// child sits near it; the previous entry in node order may be anywhere in the chart.
/// `parent` maps this band's nodes to band j+1's, `above` is band j+1's table.
/// With `rans`, the mode is `3 | 8` and the residuals a [`put_codes`] rANS section.
pub fn write_table_from_above(t: &QuantizedTable, channels: usize, parent: &[u32], above: &Table, rans: bool) -> Vec<u8> {
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, FROM_ABOVE | if rans { RANS_VALUES } else { 0 });
    write_listed(&mut out, t, channels, true, Some((parent, above)), rans);
    out
}

/// ATTRIBUTES of a band j below the top with *represented values*: `0`, `3 | 16` (with `rans`,
/// `3 | 16 | 8`), then the layout of [`write_table_from_above`] but without a residual for an
/// entry that is its parent entry's *representative* ([`representatives`]): its value is that
/// parent entry's, which the encoder made so (each coarse value is one of its descendants'
/// input values, see `tables`), so every distinct value is sent once, coarse first. `None`
/// when a representative's value differs from its parent entry's (the coding would lose it).
pub fn write_table_represented(t: &QuantizedTable, channels: usize, parent: &[u32], above: &Table, rans: bool) -> Option<Vec<u8>> {
    let nodes = t.entries.last().map_or(0, |e| e.0 + 1);
    let reps = representatives(&Table::index(&t.entries, nodes), parent, above);
    if !represented_agree(&reps, &t.values, &above.values, channels) {
        return None;
    }
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, FROM_ABOVE | REPRESENTED | if rans { RANS_VALUES } else { 0 });
    write_listed_with(&mut out, t, channels, true, Some((parent, above)), rans, &reps);
    Some(out)
}

/// ATTRIBUTES of a band j below the top with *entries from the band above*: `0`, `3 | 32` (with
/// `represented`, `| 16`; with `rans`, `| 8`), then the layout of [`write_table_from_above`]
/// (or [`write_table_represented`]) but the entries as [`put_entries_above`] writes them: a
/// bit per chart of the node's parent entries, the rest listed. `None` where the represented
/// coding does not apply.
pub fn write_table_entries_above(
    t: &QuantizedTable,
    channels: usize,
    parent: &[u32],
    above: &Table,
    rans: bool,
    represented: bool,
) -> Option<Vec<u8>> {
    let nodes = t.entries.last().map_or(0, |e| e.0 + 1);
    let reps = if represented { representatives(&Table::index(&t.entries, nodes), parent, above) } else { Vec::new() };
    if !represented_agree(&reps, &t.values, &above.values, channels) {
        return None;
    }
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, FROM_ABOVE | ENTRIES_ABOVE | if represented { REPRESENTED } else { 0 } | if rans { RANS_VALUES } else { 0 });
    put_entries_above(&mut out, &t.entries, parent, above);
    write_values(&mut out, t, channels, true, Some((parent, above)), rans, &reps);
    Some(out)
}

/// ENTRIES FROM ABOVE: `n` (the entries' nodes are below it), then for each node c < n and each
/// entry (P[c], k) of the band above in its order, one bit: whether (c, k) is an entry (packed
/// from bit 0 of byte 0 upward, the bytes the bits need); then `x` and the x entries whose
/// chart the parent has no entry in, listed as [`write_table`] lists entries. A node's entries
/// mostly lie in its parent's charts (the parent's are their union in frame 0), so a bit each
/// replaces two varints (Fox's band 1: 159 B of listed entries).
fn put_entries_above(out: &mut Vec<u8>, entries: &[(u32, u32)], parent: &[u32], above: &Table) {
    let n = entries.last().map_or(0, |e| e.0 + 1);
    put(out, n);
    let mut bits: Vec<u8> = Vec::new();
    let mut at = 0usize;
    let mut extras = Vec::new();
    let mut e = 0;
    for node in 0..n {
        let start = e;
        while e < entries.len() && entries[e].0 == node {
            e += 1;
        }
        let mine = &entries[start..e];
        let theirs = candidates(parent, above, node);
        for &k in theirs {
            if at.is_multiple_of(8) {
                bits.push(0);
            }
            if mine.iter().any(|x| x.1 == k) {
                bits[at / 8] |= 1 << (at % 8);
            }
            at += 1;
        }
        extras.extend(mine.iter().filter(|x| !theirs.contains(&x.1)));
    }
    out.extend_from_slice(&bits);
    put_entries(out, &extras);
}

/// The charts of the band above's entries of `node`'s parent, ascending (none when the node
/// has no parent there).
fn candidates<'t>(parent: &[u32], above: &'t Table, node: u32) -> &'t [u32] {
    let Some(&p) = parent.get(node as usize) else { return &[] };
    match (above.first.get(p as usize), above.first.get(p as usize + 1)) {
        (Some(&lo), Some(&hi)) => above.charts.get(lo as usize..hi as usize).unwrap_or(&[]),
        _ => &[],
    }
}

/// Reads [`put_entries_above`]'s entries, ascending by (node, chart); at most `limit`.
fn read_entries_above(
    c: &mut Cursor<'_>,
    nodes: u32,
    charts: u32,
    limit: u64,
    parent: &[u32],
    above: &Table,
) -> Result<Vec<(u32, u32)>, ContainerError> {
    let corrupt = |detail: String| ContainerError::Corrupt { what: "attribute entries".into(), detail };
    let n = c.get()?;
    if n > nodes {
        return Err(corrupt(format!("entries of {n} nodes where the band has {nodes}")));
    }
    let total: u64 = (0..n).map(|node| candidates(parent, above, node).len() as u64).sum();
    let bits = c.take(total.div_ceil(8) as usize)?;
    let mut entries = Vec::new();
    let mut at = 0usize;
    for node in 0..n {
        for &k in candidates(parent, above, node) {
            if (bits[at / 8] >> (at % 8)) & 1 == 1 {
                entries.push((node, k));
            }
            at += 1;
        }
    }
    if !at.is_multiple_of(8) && bits.last().is_some_and(|&b| b >> (at % 8) != 0) {
        return Err(corrupt("bits set beyond the candidates".into()));
    }
    let x = c.count_within(limit, 2, "listed entries")?;
    let extras = read_entries(c, x, n, charts)?;
    if entries.len() as u64 + x as u64 > limit {
        return Err(corrupt(format!("{} entries, more than {limit}", entries.len() + x)));
    }
    entries.extend(extras);
    entries.sort_unstable();
    if entries.windows(2).any(|w| w[0] == w[1]) {
        return Err(corrupt("an entry both in its parent's charts and listed".into()));
    }
    Ok(entries)
}

/// Entries ascending by (node, chart) as listed tables list them: the node as its difference
/// from the previous entry's (the first as is), the chart as is when the node differs, else as
/// `chart - previous chart - 1`.
fn put_entries(out: &mut Vec<u8>, entries: &[(u32, u32)]) {
    put(out, entries.len() as u32);
    let mut prev: Option<(u32, u32)> = None;
    for &(node, chart) in entries {
        match prev {
            Some((pn, pc)) if pn == node => {
                put(out, 0);
                put(out, chart - pc - 1);
            }
            Some((pn, _)) => {
                put(out, node - pn);
                put(out, chart);
            }
            None => {
                put(out, node);
                put(out, chart);
            }
        }
        prev = Some((node, chart));
    }
}

/// Reads `m` entries as [`put_entries`] lists them (after their count), each node below `nodes`
/// and chart below `charts`.
fn read_entries(c: &mut Cursor<'_>, m: usize, nodes: u32, charts: u32) -> Result<Vec<(u32, u32)>, ContainerError> {
    let mut out = Vec::with_capacity(m);
    let mut prev: Option<(u32, u32)> = None;
    for _ in 0..m {
        let d = c.get()?;
        let raw_chart = c.get()?;
        let (node, chart) = match prev {
            Some((pn, pc)) if d == 0 => (pn as u64, pc as u64 + raw_chart as u64 + 1),
            Some((pn, _)) => (pn as u64 + d as u64, raw_chart as u64),
            None => (d as u64, raw_chart as u64),
        };
        if node >= nodes as u64 || chart >= charts as u64 {
            return Err(ContainerError::Corrupt {
                what: "attribute entries".into(),
                detail: format!("entry (node {node}, chart {chart}) out of range (< {nodes}, < {charts})"),
            });
        }
        prev = Some((node as u32, chart as u32));
        out.push((node as u32, chart as u32));
    }
    Ok(out)
}

/// Whether every represented entry's values equal its parent entry's.
fn represented_agree(reps: &[Option<u32>], values: &[i32], above: &[i32], channels: usize) -> bool {
    reps.iter().enumerate().all(|(e, r)| {
        r.is_none_or(|a| values.get(e * channels..(e + 1) * channels) == above.get(a as usize * channels..(a as usize + 1) * channels))
    })
}

/// Per entry of a band's table (ascending by (node, chart)), the entry of the band above it
/// copies, if it is a *representative*: the first entry, in table order, whose node's parent
/// (`parent`, frame 0's hierarchy) has an entry of the same chart in `above`, each entry above
/// represented once. So a coarse (node, chart) value is that of its smallest child node with
/// an entry in the chart, a rule the decoder follows from the entries alone (Hoppe,
/// "Progressive meshes", 1996, keeps a vertex's attributes through its collapses the same way:
/// a coarse vertex's wedge is one of its children's, not new data).
pub fn representatives(table: &Table, parent: &[u32], above: &Table) -> Vec<Option<u32>> {
    let mut claimed = vec![false; above.len()];
    let mut out = vec![None; table.len()];
    for node in 0..table.first.len().saturating_sub(1) {
        let Some(&p) = parent.get(node) else { break };
        let (lo, hi) = (table.first[node] as usize, table.first[node + 1] as usize);
        for (slot, &chart) in out[lo..hi].iter_mut().zip(&table.charts[lo..hi]) {
            if let Some(a) = above.find(p, chart).filter(|&a| !claimed[a]) {
                claimed[a] = true;
                *slot = Some(a as u32);
            }
        }
    }
    out
}

impl QuantizedTable {
    /// As a decoded [`Table`] (for predicting the band below it).
    pub fn to_table(&self) -> Table {
        let nodes = self.entries.last().map_or(0, |e| e.0 + 1);
        let mut t = Table::index(&self.entries, nodes);
        t.values = self.values.clone();
        t
    }
}

/// The prediction of entry (node, chart)'s channel k from the band above, if it has the entry.
fn from_above(above: Option<(&[u32], &Table)>, node: u32, chart: u32, channels: usize, k: usize) -> Option<i32> {
    let (parent, table) = above?;
    let p = *parent.get(node as usize)?;
    let e = table.find(p, chart)?;
    table.values.get(e * channels + k).copied()
}

fn write_listed(out: &mut Vec<u8>, t: &QuantizedTable, channels: usize, chartwise: bool, above: Option<(&[u32], &Table)>, rans: bool) {
    write_listed_with(out, t, channels, chartwise, above, rans, &[]);
}

/// [`write_listed`] without a residual for the entries `reps` names (their values are their
/// parent entries').
fn write_listed_with(
    out: &mut Vec<u8>,
    t: &QuantizedTable,
    channels: usize,
    chartwise: bool,
    above: Option<(&[u32], &Table)>,
    rans: bool,
    reps: &[Option<u32>],
) {
    put_entries(out, &t.entries);
    write_values(out, t, channels, chartwise, above, rans, reps);
}

/// A listed table's values, channel by channel, as residuals from their predictions.
fn write_values(
    out: &mut Vec<u8>,
    t: &QuantizedTable,
    channels: usize,
    chartwise: bool,
    above: Option<(&[u32], &Table)>,
    rans: bool,
    reps: &[Option<u32>],
) {
    let charts = t.entries.iter().map(|e| e.1 as usize + 1).max().unwrap_or(0);
    let mut codes = Vec::with_capacity(t.values.len());
    for k in 0..channels {
        // The previous value of the chart (chart-wise) or of any entry (slot 0).
        let mut last = vec![0i32; if chartwise { charts } else { 1 }];
        for (e, &(node, chart)) in t.entries.iter().enumerate() {
            let slot = if chartwise { chart as usize } else { 0 };
            let q = t.values[e * channels + k];
            if reps.get(e).is_none_or(Option::is_none) {
                let pred = from_above(above, node, chart, channels, k).unwrap_or(last[slot]);
                codes.push(zigzag(q.wrapping_sub(pred)));
            }
            last[slot] = q;
        }
    }
    let coded = t.entries.len() - reps.iter().filter(|r| r.is_some()).count();
    put_codes(out, &codes, coded, channels, rans);
}

/// Set in a table's mode (after its first byte 0): the value residuals are a rANS section
/// ([`put_codes`]) rather than varints. Files before it never set it.
const RANS_VALUES: u32 = 8;
/// Set in a table's mode with [`FROM_ABOVE`] or [`DERIVED_ENTRIES`]: representatives
/// ([`representatives`]) take their parent entry's values and have no residual. Files before
/// it never set it.
const REPRESENTED: u32 = 16;
/// A decoded attribute table, indexed by node: entries of node n are `first[n]..first[n+1]`.
#[derive(Clone, Debug, Default)]
pub struct Table {
    /// Per node and one past the last: where its entries start.
    pub first: Vec<u32>,
    /// Each entry's chart.
    pub charts: Vec<u32>,
    /// Each entry's quantized values, `channels` per entry.
    pub values: Vec<i32>,
}

impl Table {
    /// The quantized values of (node, chart), if the table has that entry.
    pub fn get(&self, node: u32, chart: u32, channels: usize) -> Option<&[i32]> {
        let e = self.find(node, chart)?;
        Some(&self.values[e * channels..(e + 1) * channels])
    }

    /// The index of entry (node, chart), if the table has it.
    pub fn find(&self, node: u32, chart: u32) -> Option<usize> {
        let lo = *self.first.get(node as usize)? as usize;
        let hi = *self.first.get(node as usize + 1)? as usize;
        Some(lo + self.charts.get(lo..hi)?.iter().position(|&c| c == chart)?)
    }

    /// The index of entries ascending by (node, chart), without values.
    pub(crate) fn index(entries: &[(u32, u32)], nodes: u32) -> Table {
        let mut first = vec![0u32; nodes as usize + 1];
        for &(n, _) in entries {
            first[n as usize + 1] += 1;
        }
        for n in 0..nodes as usize {
            first[n + 1] += first[n];
        }
        Table { first, charts: entries.iter().map(|e| e.1).collect(), values: Vec::new() }
    }

    /// Entries in the table.
    pub fn len(&self) -> usize {
        self.charts.len()
    }

    /// Whether the table has no entry.
    pub fn is_empty(&self) -> bool {
        self.charts.is_empty()
    }
}

/// Band 0's entries: the (vertex, chart) pair of every triangle corner, ascending (what a
/// client of level 0 derives from the Triangles and Charts chunks).
pub fn band0_entries(triangles: &[[u32; 3]], triangle_chart: &[u32]) -> Vec<(u32, u32)> {
    let mut pairs: Vec<(u32, u32)> =
        triangles.iter().zip(triangle_chart).flat_map(|(tri, &chart)| tri.iter().map(move |&v| (v, chart))).collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// The coding of a band-0 table with *derived entries*: after a first byte 0 (no entries
/// listed), this mode (proto/container.md, "Attributes, band j").
const DERIVED_ENTRIES: u32 = 1;
/// The coding of a listed table with chart-wise value differences ([`write_table_chartwise`]).
const CHARTWISE: u32 = 2;
/// The coding of a listed table with values predicted from the band above
/// ([`write_table_from_above`]).
const FROM_ABOVE: u32 = 3;
/// [`FROM_ABOVE`] with [`REPRESENTED`] ([`write_table_represented`]).
const REPRESENTED_ABOVE: u32 = FROM_ABOVE | REPRESENTED;
/// Set with [`FROM_ABOVE`]: the entries are coded from the band above's
/// ([`put_entries_above`]). Files before it never set it.
const ENTRIES_ABOVE: u32 = 32;

/// Band 0's traversal (proto/container.md, "Attributes, band 0 with derived entries"): the
/// triangles in input order, each one's corners in order; a corner whose entry is not yet
/// known is predicted, then `visit(prediction, its values)` makes it known (the encoder
/// records the residual, the decoder adds it). The prediction is the parallelogram rule
/// (Touma & Gotsman, "Triangle mesh compression", 1998, as Draco predicts texture coordinates
/// across an edge) when the triangle's two other corners are known and an earlier triangle
/// of the chart shares their edge: `a + b - o`, o that triangle's third corner; else the mean
/// of the two known corners, the one known corner, the last entry made known in the
/// triangle's chart, or the last entry made known (zeros at first). Arithmetic wraps in 32 bits, the mean is `(a + b) >> 1` (arithmetic shift).
/// Entries `known` at the start (the representatives of a represented table, their values in
/// `values`) are never visited; the others see them as known corners.
#[allow(clippy::too_many_arguments)]
fn traverse(
    table: &Table,
    triangles: &[[u32; 3]],
    triangle_chart: &[u32],
    channels: usize,
    values: &mut [i32],
    mut known: Vec<bool>,
    mut visit: impl FnMut(&[i32], &mut [i32]) -> Result<(), ContainerError>,
    what: &str,
) -> Result<(), ContainerError> {
    let c = channels;
    known.resize(table.len(), false);
    // Edge (entry a, entry b), a < b, of an earlier triangle -> that triangle's third entry.
    let mut opposite: std::collections::HashMap<u64, u32> = std::collections::HashMap::new();
    let key = |a: usize, b: usize| ((a.min(b) as u64) << 32) | a.max(b) as u64;
    let mut last = vec![0i32; c];
    // The last entry made known in each chart, if any.
    let charts = triangle_chart.iter().map(|&k| k as usize + 1).max().unwrap_or(0);
    let mut chart_last = vec![0i32; charts * c];
    let mut chart_seen = vec![false; charts];
    let mut pred = vec![0i32; c];
    for (t, tri) in triangles.iter().enumerate() {
        let chart = triangle_chart.get(t).copied().unwrap_or(u32::MAX);
        let mut e = [0usize; 3];
        for i in 0..3 {
            e[i] = table.find(tri[i], chart).ok_or_else(|| ContainerError::Corrupt {
                what: what.into(),
                detail: format!("no entry for vertex {}, chart {chart} of triangle {t}", tri[i]),
            })?;
        }
        for i in 0..3 {
            let x = e[i];
            if known[x] {
                continue;
            }
            let (a, b) = (e[(i + 1) % 3], e[(i + 2) % 3]);
            let (ka, kb) = (known[a], known[b]);
            for q in 0..c {
                let (va, vb) = (values[a * c + q], values[b * c + q]);
                pred[q] = match (ka, kb, opposite.get(&key(a, b))) {
                    (true, true, Some(&o)) => va.wrapping_add(vb).wrapping_sub(values[o as usize * c + q]),
                    (true, true, None) => va.wrapping_add(vb) >> 1,
                    (true, false, _) => va,
                    (false, true, _) => vb,
                    (false, false, _) if chart_seen[chart as usize] => chart_last[chart as usize * c + q],
                    (false, false, _) => last[q],
                };
            }
            visit(&pred, &mut values[x * c..(x + 1) * c])?;
            known[x] = true;
            last.copy_from_slice(&values[x * c..(x + 1) * c]);
            chart_seen[chart as usize] = true;
            chart_last[chart as usize * c..(chart as usize + 1) * c].copy_from_slice(&values[x * c..(x + 1) * c]);
        }
        if e[0] != e[1] && e[1] != e[2] && e[2] != e[0] {
            for i in 0..3 {
                opposite.entry(key(e[i], e[(i + 1) % 3])).or_insert(e[(i + 2) % 3] as u32);
            }
        }
    }
    Ok(())
}

/// ATTRIBUTES, band 0 with derived entries: `0`, `1`, then, channel by channel, the zigzag-coded
/// residuals of the values against [`traverse`]'s predictions, in the order it visits the
/// entries. `t`'s entries must be [`band0_entries`] of the same triangles and charts.
/// With `rans`, the mode is `1 | 8` and the residuals a [`put_codes`] rANS section.
pub fn write_table_derived(t: &QuantizedTable, channels: usize, triangles: &[[u32; 3]], triangle_chart: &[u32], rans: bool) -> Vec<u8> {
    write_derived(t, channels, triangles, triangle_chart, None, rans).unwrap_or_else(|| write_table(t, channels))
}

/// ATTRIBUTES, band 0 with derived entries and *represented values*: `0`, `1 | 16` (with
/// `rans`, `1 | 16 | 8`), then the residuals of [`write_table_derived`] for the entries that
/// are not representatives ([`representatives`] of band 0's entries under `parent` in
/// `above`, band 1's table): those take their parent entry's values before the traversal
/// starts, are known corners to it and have no residual. `None` when a representative's value
/// differs from its parent entry's, or the triangles miss an entry.
pub fn write_table_derived_represented(
    t: &QuantizedTable,
    channels: usize,
    triangles: &[[u32; 3]],
    triangle_chart: &[u32],
    parent: &[u32],
    above: &Table,
    rans: bool,
) -> Option<Vec<u8>> {
    write_derived(t, channels, triangles, triangle_chart, Some((parent, above)), rans)
}

fn write_derived(
    t: &QuantizedTable,
    channels: usize,
    triangles: &[[u32; 3]],
    triangle_chart: &[u32],
    above: Option<(&[u32], &Table)>,
    rans: bool,
) -> Option<Vec<u8>> {
    let nodes = t.entries.last().map_or(0, |e| e.0 + 1);
    let table = Table::index(&t.entries, nodes);
    let reps = above.map(|(parent, above)| representatives(&table, parent, above)).unwrap_or_default();
    if let Some((_, above)) = above
        && !represented_agree(&reps, &t.values, &above.values, channels)
    {
        return None;
    }
    let known: Vec<bool> = reps.iter().map(Option::is_some).collect();
    let coded = t.entries.len() - known.iter().filter(|&&k| k).count();
    let mut values = t.values.clone();
    let mut residuals: Vec<Vec<u32>> = vec![Vec::with_capacity(t.entries.len()); channels];
    let visit = |pred: &[i32], v: &mut [i32]| {
        for q in 0..channels {
            residuals[q].push(zigzag(v[q].wrapping_sub(pred[q])));
        }
        Ok(())
    };
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, DERIVED_ENTRIES | if above.is_some() { REPRESENTED } else { 0 } | if rans { RANS_VALUES } else { 0 });
    // The entries are the triangles' own: the traversal cannot miss one.
    traverse(&table, triangles, triangle_chart, channels, &mut values, known, visit, "band 0 attributes").ok()?;
    put_codes(&mut out, &residuals.concat(), coded, channels, rans);
    Some(out)
}

/// Reads band j's table: `nodes` = `level_sizes[j]`; at most three entries per triangle.
/// `band0` gives band 0's triangles and their charts, which a table with derived entries needs.
pub fn read_table_with(
    bytes: &[u8],
    what: &str,
    nodes: u32,
    info: &AppearanceInfo,
    triangles: u32,
    band0: Option<(&[[u32; 3]], &[u32])>,
) -> Result<Table, ContainerError> {
    read_band(bytes, what, nodes, info, triangles, band0, None)
}

/// Reads band j's table, whichever its coding: `band0` gives band 0's triangles and their
/// charts (a table with derived entries needs them), `above` frame 0's parents of this band's
/// nodes and the band above's table (a table predicted from it or with represented values
/// needs them; [`needs_above`] says whether).
pub fn read_band(
    bytes: &[u8],
    what: &str,
    nodes: u32,
    info: &AppearanceInfo,
    triangles: u32,
    band0: Option<(&[[u32; 3]], &[u32])>,
    above: Option<(&[u32], &Table)>,
) -> Result<Table, ContainerError> {
    let flags = (RANS_VALUES | REPRESENTED) as u8;
    if bytes.first() != Some(&0) || bytes.len() < 2 || bytes[1] & !flags != DERIVED_ENTRIES as u8 {
        return read_table_above(bytes, what, nodes, info, triangles, above);
    }
    let channels = info.channels();
    let mut c = Cursor::new(bytes, what);
    c.get()?;
    let mode = c.get()?;
    let rans = mode & RANS_VALUES != 0;
    let corrupt = |detail: String| ContainerError::Corrupt { what: what.into(), detail };
    if mode & !(RANS_VALUES | REPRESENTED) != DERIVED_ENTRIES {
        return Err(corrupt(format!("table coding {mode} unknown")));
    }
    let Some((tris, chart_of)) = band0 else {
        return Err(corrupt("derived entries outside band 0".into()));
    };
    if tris.len() != triangles as usize || chart_of.len() != tris.len() {
        return Err(corrupt(format!("{} triangles and {} charts where the header says {triangles}", tris.len(), chart_of.len())));
    }
    let entries = band0_entries(tris, chart_of);
    if let Some(&(n, k)) = entries.iter().find(|&&(n, k)| n >= nodes || k >= info.charts) {
        return Err(corrupt(format!("entry (node {n}, chart {k}) out of range (< {nodes}, < {})", info.charts)));
    }
    let m = entries.len();
    let mut table = Table::index(&entries, nodes);
    let mut values = vec![0i32; m * channels];
    let mut known = vec![false; m];
    if mode & REPRESENTED != 0 {
        let Some((parent, above)) = above else {
            return Err(corrupt("represented values without the band above".into()));
        };
        for (e, r) in representatives(&table, parent, above).into_iter().enumerate() {
            if let Some(a) = r {
                let a = a as usize;
                let from = above.values.get(a * channels..(a + 1) * channels).ok_or_else(|| corrupt("band above without values".into()))?;
                values[e * channels..(e + 1) * channels].copy_from_slice(from);
                known[e] = true;
            }
        }
    }
    let coded = m - known.iter().filter(|&&k| k).count();
    let residuals: Vec<i32> = read_codes(&mut c, coded, channels, rans)?.into_iter().map(unzigzag).collect();
    c.finish()?;
    let mut k = 0;
    let visit = |pred: &[i32], v: &mut [i32]| {
        for q in 0..channels {
            v[q] = pred[q].wrapping_add(*residuals.get(q * coded + k).ok_or_else(|| corrupt("fewer residuals than entries".into()))?);
        }
        k += 1;
        Ok(())
    };
    traverse(&table, tris, chart_of, channels, &mut values, known, visit, what)?;
    table.values = values;
    Ok(table)
}

/// Reads band j's table: `nodes` = `level_sizes[j]`; at most three entries per triangle.
pub fn read_table(bytes: &[u8], what: &str, nodes: u32, info: &AppearanceInfo, triangles: u32) -> Result<Table, ContainerError> {
    read_table_above(bytes, what, nodes, info, triangles, None)
}

/// Whether a table's payload predicts its values from the band above (it then needs the
/// parents of frame 0's hierarchy and that band's table).
pub fn needs_above(bytes: &[u8]) -> bool {
    bytes.len() > 1
        && bytes[0] == 0
        && (bytes[1] & !(RANS_VALUES as u8) == FROM_ABOVE as u8 || bytes[1] & (REPRESENTED | ENTRIES_ABOVE) as u8 != 0)
}

/// [`read_table`] with `above`: frame 0's parents of this band's nodes and the band above's
/// table, which a table predicted from the band above needs.
pub fn read_table_above(
    bytes: &[u8],
    what: &str,
    nodes: u32,
    info: &AppearanceInfo,
    triangles: u32,
    above: Option<(&[u32], &Table)>,
) -> Result<Table, ContainerError> {
    let mut c = Cursor::new(bytes, what);
    let mut chartwise = false;
    let mut predicted = None;
    let mut rans = false;
    let mut represented = false;
    let mut entries_above = false;
    if bytes.first() == Some(&0) && bytes.len() > 1 {
        c.get()?;
        let mode = c.get()?;
        rans = mode & RANS_VALUES != 0;
        represented = mode & REPRESENTED != 0;
        entries_above = mode & ENTRIES_ABOVE != 0;
        match mode & !(RANS_VALUES | if entries_above { ENTRIES_ABOVE } else { 0 }) {
            0 if rans && !entries_above => {}
            CHARTWISE if !entries_above => chartwise = true,
            FROM_ABOVE | REPRESENTED_ABOVE => {
                chartwise = true;
                predicted = Some(above.ok_or_else(|| ContainerError::Corrupt {
                    what: what.into(),
                    detail: "values from the band above, at the top or without it".into(),
                })?);
            }
            DERIVED_ENTRIES => return Err(ContainerError::Corrupt { what: what.into(), detail: "derived entries outside band 0".into() }),
            mode => return Err(ContainerError::Corrupt { what: what.into(), detail: format!("table coding {mode} unknown") }),
        }
    }
    let channels = info.channels();
    // Entries take two bytes at least; varint values one more each (rANS values may take less).
    let min_bytes = if rans || represented { 2 } else { 2 + channels };
    let limit = (nodes as u64 * info.charts as u64).min(3 * triangles as u64);
    let named = |e: ContainerError| match e {
        ContainerError::Corrupt { what: w, detail } if w == "attribute entries" => ContainerError::Corrupt { what: what.into(), detail },
        e => e,
    };
    let entries = match predicted {
        Some((parent, above)) if entries_above => read_entries_above(&mut c, nodes, info.charts, limit, parent, above).map_err(named)?,
        _ => {
            let m = c.count_within(limit, min_bytes, "entries")?;
            read_entries(&mut c, m, nodes, info.charts).map_err(named)?
        }
    };
    let m = entries.len();
    let mut table = Table { first: vec![0; nodes as usize + 1], charts: Vec::with_capacity(m), values: Vec::with_capacity(m * channels) };
    let mut node_of = Vec::with_capacity(m);
    for &(node, chart) in &entries {
        node_of.push(node);
        table.charts.push(chart);
        table.first[node as usize + 1] += 1;
    }
    for n in 0..nodes as usize {
        table.first[n + 1] += table.first[n];
    }
    table.values.resize(m * channels, 0);
    let reps = match predicted {
        Some((parent, above)) if represented => representatives(&table, parent, above),
        _ => Vec::new(),
    };
    let coded = m - reps.iter().filter(|r| r.is_some()).count();
    let codes = read_codes(&mut c, coded, channels, rans)?;
    for k in 0..channels {
        let mut last = vec![0i32; if chartwise { info.charts as usize } else { 1 }];
        let mut at = k * coded;
        for (e, &node) in node_of.iter().enumerate() {
            let chart = table.charts[e];
            let slot = if chartwise { chart as usize } else { 0 };
            let q = match (reps.get(e).copied().flatten(), predicted) {
                (Some(a), Some((_, above))) => above.values.get(a as usize * channels + k).copied().unwrap_or(0),
                _ => {
                    let pred = from_above(predicted, node, chart, channels, k).unwrap_or(last[slot]);
                    at += 1;
                    pred.wrapping_add(unzigzag(codes[at - 1]))
                }
            };
            table.values[e * channels + k] = q;
            last[slot] = q;
        }
    }
    c.finish()?;
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info() -> AppearanceInfo {
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
        let charts =
            Charts { triangle_chart: vec![0, 0, 1, 2, 2, 0], chart_material: vec![0, 1, 1], triangle_group: vec![0, 0, 0, 0, 1, 2] };
        assert_eq!(read_charts(&write_charts(&charts), &info(), 6).unwrap(), charts);
        // New-chart runs: charts 0, 1, 2 open as "next", chart 0 again by id.
        let coded = write_charts_new_runs(&charts);
        assert_eq!(&coded[..2], &[0, 1]);
        assert_eq!(read_charts(&coded, &info(), 6).unwrap(), charts);
        assert!(read_charts(&coded[..coded.len() - 1], &info(), 6).is_err());
        let mut odd = coded.clone();
        odd[1] = 3;
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
        let many = Charts {
            chart_material: (0..seen).map(|c| c % 2).collect(),
            triangle_group: (0..n).map(|t| t / 100).collect(),
            triangle_chart,
        };
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
}
