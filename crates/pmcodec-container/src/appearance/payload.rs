//! The Charts and Attributes chunk payloads (varints, as every payload; proto/container.md,
//! "Appearance").

pub use super::chart_runs::{
    charts_need_triangles, read_charts, read_charts_with, write_charts, write_charts_grown, write_charts_neighbours, write_charts_new_runs,
    write_charts_recent,
};
use super::codes::{put_codes, read_codes};
use super::entries::{put_entries, put_entries_above, read_entries, read_entries_above};
use super::format::AppearanceInfo;
use crate::ContainerError;
use crate::payload::{Cursor, put, unzigzag, zigzag};

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

/// Whether every represented entry's values equal its parent entry's.
pub(super) fn represented_agree(reps: &[Option<u32>], values: &[i32], above: &[i32], channels: usize) -> bool {
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
pub(super) fn from_above(above: Option<(&[u32], &Table)>, node: u32, chart: u32, channels: usize, k: usize) -> Option<i32> {
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
pub(super) const RANS_VALUES: u32 = 8;
/// Set in a table's mode with [`FROM_ABOVE`] or [`DERIVED_ENTRIES`]: representatives
/// ([`representatives`]) take their parent entry's values and have no residual. Files before
/// it never set it.
pub(super) const REPRESENTED: u32 = 16;
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
pub(super) const DERIVED_ENTRIES: u32 = 1;
/// Set with [`DERIVED_ENTRIES`] (band 0): texture coordinate set 0 is predicted from the
/// bind positions of the Bind chunk of band 0 where a triangle's edge is known
/// ([`super::project`]). Files before it never set it.
pub(super) const BIND_POSITIONS: u32 = 4;
/// The coding of a listed table with chart-wise value differences ([`write_table_chartwise`]).
const CHARTWISE: u32 = 2;
/// The coding of a listed table with values predicted from the band above
/// ([`write_table_from_above`]).
pub(super) const FROM_ABOVE: u32 = 3;
/// [`FROM_ABOVE`] with [`REPRESENTED`] ([`write_table_represented`]).
const REPRESENTED_ABOVE: u32 = FROM_ABOVE | REPRESENTED;
/// Set with [`FROM_ABOVE`]: the entries are coded from the band above's
/// ([`put_entries_above`]). Files before it never set it.
pub(super) const ENTRIES_ABOVE: u32 = 32;
/// Set with [`FROM_ABOVE`]: the values are predicted across the band's faces
/// ([`super::across`]). Files before it never set it.
pub(super) const ACROSS_FACES: u32 = 64;

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
/// `values`) are never visited; the others see them as known corners; `known` ends with the
/// visited ones set too.
#[allow(clippy::too_many_arguments)]
fn traverse(
    table: &Table,
    triangles: &[[u32; 3]],
    triangle_chart: &[u32],
    channels: usize,
    values: &mut [i32],
    known: &mut Vec<bool>,
    positions: Option<&[[i64; 3]]>,
    mut visit: impl FnMut(&[i32], &mut [i32]) -> Result<(), ContainerError>,
    what: &str,
) -> Result<(), ContainerError> {
    let c = channels;
    known.resize(table.len(), false);
    // With positions, each chart's orientation in texture space: its last whole triangle's.
    let mut side = vec![1i32; triangle_chart.iter().map(|&k| k as usize + 1).max().unwrap_or(0)];
    // Edge (entry a, entry b), a < b, of an earlier triangle -> that triangle's third entry.
    let mut opposite: std::collections::HashMap<u64, u32> = std::collections::HashMap::new();
    let key = |a: usize, b: usize| ((a.min(b) as u64) << 32) | a.max(b) as u64;
    let mut last = vec![0i32; c];
    // The last entry made known in each chart, if any.
    let charts = triangle_chart.iter().map(|&k| k as usize + 1).max().unwrap_or(0);
    let mut chart_last = vec![0i32; charts * c];
    let mut chart_seen = vec![false; charts];
    let mut pred = vec![0i32; c];
    // With positions, the triangles breadth first within their charts; else in input order.
    let order: Vec<u32> =
        if positions.is_some() { super::project::breadth_first(triangles, triangle_chart) } else { (0..triangles.len() as u32).collect() };
    for &t in &order {
        let (t, tri) = (t as usize, &triangles[t as usize]);
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
                // The opposite corner only where both edge corners are known (its one use).
                let o = if ka && kb { opposite.get(&key(a, b)).map(|&o| values[o as usize * c + q]) } else { None };
                pred[q] = match corner_prediction((ka, va), (kb, vb), o) {
                    Some(p) => p,
                    None if chart_seen[chart as usize] => chart_last[chart as usize * c + q],
                    None => last[q],
                };
            }
            // Texture coordinate set 0 from the positions, where both edge corners are known.
            if let (Some(pos), true, true) = (positions, ka && kb, c >= 2) {
                let at = |v: u32| {
                    pos.get(v as usize).copied().ok_or_else(|| ContainerError::Corrupt {
                        what: what.into(),
                        detail: format!("no position for vertex {v} of triangle {t}"),
                    })
                };
                let uv = |e: usize| [values[e * c], values[e * c + 1]];
                let (pa, pb, px) = (at(tri[(i + 1) % 3])?, at(tri[(i + 2) % 3])?, at(tri[i])?);
                if let Some(p) = super::project::predict(pa, pb, px, uv(a), uv(b), side[chart as usize]) {
                    pred[..2].copy_from_slice(&p);
                }
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
            if positions.is_some() && c >= 2 {
                let uv = |e: usize| [values[e * c], values[e * c + 1]];
                let o = super::project::orientation(uv(e[0]), uv(e[1]), uv(e[2]));
                if o != 0 {
                    side[chart as usize] = o;
                }
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
    write_derived(t, channels, triangles, triangle_chart, None, None, rans).unwrap_or_else(|| write_table(t, channels))
}

/// [`write_table_derived`] (`above` None) or [`write_table_derived_represented`] with *bind
/// positions*: the mode also has [`BIND_POSITIONS`], and where a corner's two edge corners are
/// known its texture coordinates (set 0) are predicted from `bind`, the bind positions of
/// the level-0 nodes (the Bind chunk of band 0), as [`super::project::predict`] places them.
/// `None` without texture coordinates, or where the other codings would be.
pub fn write_table_derived_bind(
    t: &QuantizedTable,
    channels: usize,
    (triangles, triangle_chart): (&[[u32; 3]], &[u32]),
    above: Option<(&[u32], &Table)>,
    bind: &[[i64; 3]],
    rans: bool,
) -> Option<Vec<u8>> {
    (channels >= 2).then(|| write_derived(t, channels, triangles, triangle_chart, above, Some(bind), rans)).flatten()
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
    write_derived(t, channels, triangles, triangle_chart, Some((parent, above)), None, rans)
}

fn write_derived(
    t: &QuantizedTable,
    channels: usize,
    triangles: &[[u32; 3]],
    triangle_chart: &[u32],
    above: Option<(&[u32], &Table)>,
    bind: Option<&[[i64; 3]]>,
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
    let mut known: Vec<bool> = reps.iter().map(Option::is_some).collect();
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
    let flags = if above.is_some() { REPRESENTED } else { 0 }
        | if rans { RANS_VALUES } else { 0 }
        | if bind.is_some() { BIND_POSITIONS } else { 0 };
    put(&mut out, DERIVED_ENTRIES | flags);
    // The entries are the triangles' own: the traversal cannot miss one.
    traverse(&table, triangles, triangle_chart, channels, &mut values, &mut known, bind, visit, "band 0 attributes").ok()?;
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
    read_band_bind(bytes, what, nodes, info, (triangles, band0), above, None)
}

/// Whether a table's payload predicts texture coordinates from the bind positions of the
/// level-0 nodes (the Bind chunk of frame 0, band 0), which [`read_band_bind`] then needs.
pub fn needs_bind(bytes: &[u8]) -> bool {
    let flags = (RANS_VALUES | REPRESENTED | ACROSS_FACES | BIND_POSITIONS) as u8;
    bytes.len() > 1 && bytes[0] == 0 && bytes[1] & !flags == DERIVED_ENTRIES as u8 && bytes[1] & BIND_POSITIONS as u8 != 0
}

/// Band 0's triangles and their charts, as [`read_band`] takes them.
pub type Band0<'a> = Option<(&'a [[u32; 3]], &'a [u32])>;

/// [`read_band`] with `bind`, the bind positions of the level-0 nodes, which a band 0 with
/// bind positions ([`needs_bind`]) needs.
pub fn read_band_bind(
    bytes: &[u8],
    what: &str,
    nodes: u32,
    info: &AppearanceInfo,
    (triangles, band0): (u32, Band0<'_>),
    above: Option<(&[u32], &Table)>,
    bind: Option<&[[i64; 3]]>,
) -> Result<Table, ContainerError> {
    let flags = (RANS_VALUES | REPRESENTED | ACROSS_FACES | BIND_POSITIONS) as u8;
    if bytes.first() != Some(&0) || bytes.len() < 2 || bytes[1] & !flags != DERIVED_ENTRIES as u8 {
        return read_table_above(bytes, what, nodes, info, triangles, above);
    }
    let channels = info.channels();
    let mut c = Cursor::new(bytes, what);
    c.get()?;
    let mode = c.get()?;
    let rans = mode & RANS_VALUES != 0;
    let corrupt = |detail: String| ContainerError::Corrupt { what: what.into(), detail };
    let across = mode & ACROSS_FACES != 0;
    let by_bind = mode & BIND_POSITIONS != 0;
    if mode & !(RANS_VALUES | REPRESENTED | ACROSS_FACES | BIND_POSITIONS) != DERIVED_ENTRIES
        || (across && (mode & REPRESENTED == 0 || by_bind))
        || (by_bind && info.uv_sets == 0)
    {
        return Err(corrupt(format!("table coding {mode} unknown")));
    }
    let bind = if by_bind { Some(bind.ok_or_else(|| corrupt("bind positions needed and not given".into()))?) } else { None };
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
    if across {
        // Mode 1 | 16 | 64: the values across the triangles, averaged with the parent entry's.
        let Some((parent, above)) = above else {
            return Err(corrupt("represented values without the band above".into()));
        };
        let reps = representatives(&table, parent, above);
        let coded = m - reps.iter().filter(|r| r.is_some()).count();
        let codes = read_codes(&mut c, coded, channels, rans)?;
        c.finish()?;
        let faces = super::across::band_faces(tris, chart_of, &[]).ok_or_else(|| corrupt("triangles without charts".into()))?;
        let node_of: Vec<u32> = entries.iter().map(|e| e.0).collect();
        let f = (&faces.0[..], &faces.1[..]);
        table.values = super::across::read_values(&table, &node_of, &reps, channels, (parent, above), f, &codes, coded, what)?;
        return Ok(table);
    }
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
    traverse(&table, tris, chart_of, channels, &mut values, &mut known, bind, visit, what)?;
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
        && (bytes[1] & !(RANS_VALUES as u8) == FROM_ABOVE as u8 || bytes[1] & (REPRESENTED | ENTRIES_ABOVE | ACROSS_FACES) as u8 != 0)
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
    read_table_across(bytes, what, nodes, info, triangles, above, None)
}

/// [`read_table_above`] with `faces`: band j's faces in frame 0 and their charts
/// ([`super::across::band_faces`]), which a table with values across the faces (mode `3 | 64`)
/// needs ([`super::across::needs_faces`] says whether).
pub fn read_table_across(
    bytes: &[u8],
    what: &str,
    nodes: u32,
    info: &AppearanceInfo,
    triangles: u32,
    above: Option<(&[u32], &Table)>,
    faces: Option<(&[[u32; 3]], &[u32])>,
) -> Result<Table, ContainerError> {
    let mut c = Cursor::new(bytes, what);
    let mut across = false;
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
        across = mode & ACROSS_FACES != 0;
        let flags = RANS_VALUES | if entries_above || across { ENTRIES_ABOVE | ACROSS_FACES } else { 0 };
        match mode & !flags {
            0 if rans && !entries_above && !across => {}
            CHARTWISE if !entries_above && !across => chartwise = true,
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
    if across {
        let corrupt = |detail: &str| ContainerError::Corrupt { what: what.into(), detail: detail.into() };
        let (Some(above), Some(faces)) = (predicted, faces) else {
            return Err(corrupt("values across the band's faces without its faces"));
        };
        table.values = super::across::read_values(&table, &node_of, &reps, channels, above, faces, &codes, coded, what)?;
        c.finish()?;
        return Ok(table);
    }
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

/// A corner's value predicted from the other two corners of its triangle, `(known, value)`
/// each, and the value of the corner across their edge where one is known: the parallelogram
/// rule with all three (Isenburg & Snoeyink, "Compressing texture coordinates with selective
/// linear predictions", 2003), the edge's midpoint without the opposite corner, the one known
/// corner, else none (the caller falls back to the chart's or the table's last value).
pub(super) fn corner_prediction((ka, va): (bool, i32), (kb, vb): (bool, i32), opposite: Option<i32>) -> Option<i32> {
    match (ka, kb, opposite) {
        (true, true, Some(o)) => Some(va.wrapping_add(vb).wrapping_sub(o)),
        (true, true, None) => Some(va.wrapping_add(vb) >> 1),
        (true, false, _) => Some(va),
        (false, true, _) => Some(vb),
        (false, false, _) => None,
    }
}

#[cfg(test)]
#[path = "payload_tests.rs"]
pub(crate) mod tests;
