//! The Charts and Attributes chunk payloads (varints, as every payload; proto/container.md,
//! "Appearance").

use super::charts::Charts;
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
    let mut out = Vec::new();
    put(&mut out, c.count() as u32);
    for &m in &c.chart_material {
        put(&mut out, m);
    }
    let charts = runs(&c.triangle_chart);
    put(&mut out, charts.len() as u32);
    for (ch, n) in charts {
        put(&mut out, ch);
        put(&mut out, n);
    }
    let groups = runs(&c.triangle_group);
    put(&mut out, groups.len() as u32);
    let mut last = 0u32;
    for (g, n) in groups {
        put(&mut out, zigzag(g.wrapping_sub(last) as i32));
        put(&mut out, n);
        last = g;
    }
    out
}

pub fn read_charts(bytes: &[u8], info: &AppearanceInfo, triangles: u32) -> Result<Charts, ContainerError> {
    let what = "charts chunk";
    let bad = |detail: String| ContainerError::Corrupt { what: what.into(), detail };
    let mut c = Cursor::new(bytes, what);
    let count = c.count_within(info.charts as u64, 1, "charts")?;
    if count != info.charts as usize {
        return Err(bad(format!("{count} charts where the header says {}", info.charts)));
    }
    let mut charts = Charts { triangle_chart: Vec::with_capacity(triangles as usize), ..Default::default() };
    for _ in 0..count {
        charts.chart_material.push(c.id(info.materials.max(1), "material")?);
    }
    let n = c.count_within(triangles as u64, 2, "chart runs")?;
    for _ in 0..n {
        let chart = c.id(info.charts, "chart")?;
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

/// One level's attribute table: entries ascending by (node, chart), each with `channels`
/// quantized values (texture coordinates in `uv_step` units from `uv_min`, colours 0..=255).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct QuantizedTable {
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
    put(&mut out, t.entries.len() as u32);
    let mut prev: Option<(u32, u32)> = None;
    for &(node, chart) in &t.entries {
        match prev {
            Some((pn, pc)) if pn == node => {
                put(&mut out, 0);
                put(&mut out, chart - pc - 1);
            }
            Some((pn, _)) => {
                put(&mut out, node - pn);
                put(&mut out, chart);
            }
            None => {
                put(&mut out, node);
                put(&mut out, chart);
            }
        }
        prev = Some((node, chart));
    }
    for k in 0..channels {
        let mut last = 0i32;
        for e in 0..t.entries.len() {
            let q = t.values[e * channels + k];
            put(&mut out, zigzag(q.wrapping_sub(last)));
            last = q;
        }
    }
    out
}

/// A decoded attribute table, indexed by node: entries of node n are `first[n]..first[n+1]`.
#[derive(Clone, Debug, Default)]
pub struct Table {
    pub first: Vec<u32>,
    pub charts: Vec<u32>,
    pub values: Vec<i32>,
}

impl Table {
    /// The quantized values of (node, chart), if the table has that entry.
    pub fn get(&self, node: u32, chart: u32, channels: usize) -> Option<&[i32]> {
        let lo = *self.first.get(node as usize)? as usize;
        let hi = *self.first.get(node as usize + 1)? as usize;
        let e = lo + self.charts[lo..hi].iter().position(|&c| c == chart)?;
        Some(&self.values[e * channels..(e + 1) * channels])
    }

    pub fn len(&self) -> usize {
        self.charts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.charts.is_empty()
    }
}

/// Reads band j's table: `nodes` = `level_sizes[j]`; at most three entries per triangle.
pub fn read_table(bytes: &[u8], what: &str, nodes: u32, info: &AppearanceInfo, triangles: u32) -> Result<Table, ContainerError> {
    let channels = info.channels();
    let mut c = Cursor::new(bytes, what);
    let m = c.count_within((nodes as u64 * info.charts as u64).min(3 * triangles as u64), 2 + channels, "entries")?;
    let mut table = Table { first: vec![0; nodes as usize + 1], charts: Vec::with_capacity(m), values: Vec::with_capacity(m * channels) };
    let mut prev: Option<(u32, u32)> = None;
    let mut node_of = Vec::with_capacity(m);
    for _ in 0..m {
        let d = c.get()?;
        let raw_chart = c.get()?;
        let (node, chart) = match prev {
            Some((pn, pc)) if d == 0 => (pn as u64, pc as u64 + raw_chart as u64 + 1),
            Some((pn, _)) => (pn as u64 + d as u64, raw_chart as u64),
            None => (d as u64, raw_chart as u64),
        };
        if node >= nodes as u64 || chart >= info.charts as u64 {
            return Err(ContainerError::Corrupt {
                what: what.into(),
                detail: format!("entry (node {node}, chart {chart}) out of range (< {nodes}, < {})", info.charts),
            });
        }
        prev = Some((node as u32, chart as u32));
        node_of.push(node as u32);
        table.charts.push(chart as u32);
        table.first[node as usize + 1] += 1;
    }
    for n in 0..nodes as usize {
        table.first[n + 1] += table.first[n];
    }
    table.values.resize(m * channels, 0);
    for k in 0..channels {
        let mut last = 0i32;
        for e in 0..m {
            last = last.wrapping_add(unzigzag(c.get()?));
            table.values[e * channels + k] = last;
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
        let charts =
            Charts { triangle_chart: vec![0, 0, 1, 2, 2, 0], chart_material: vec![0, 1, 1], triangle_group: vec![0, 0, 0, 0, 1, 2] };
        assert_eq!(read_charts(&write_charts(&charts), &info(), 6).unwrap(), charts);
        assert!(read_charts(&write_charts(&charts), &info(), 7).is_err(), "runs cover 6 of 7");
    }
}
