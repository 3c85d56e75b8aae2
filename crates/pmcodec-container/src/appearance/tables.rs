//! The encoder's attribute tables: for every level L and every (level-L node, chart) pair
//! that some cut can show in ANY frame (the hierarchy changes by swaps, so the pairs do), the
//! attribute value a decoder draws there.
//!
//! A shown triangle's corners are cut nodes, each its corner's ancestor at its own level; the
//! levels can differ (a budget cut mixes them). A cut is a front, so a corner cut at its
//! level-L ancestor g shares g with every corner under g: the triangle shows only if its other
//! corners lie under other level-L nodes. Those (g, chart) pairs are the table, and it covers
//! every cut a decoder can make. At level 0 the value is the input's wedge (one per (vertex, chart),
//! see [`super::charts`]). Above, it is solved from the cluster's fine wedges of that chart:
//! their mean weighted by a third of the area of each fine triangle of the chart at them,
//! summed over the frames (Garland & Heckbert 1998 weight attribute quadrics by area the same
//! way), which keeps a coarse node's value inside its chart's region of the texture.

// Corners index several parallel arrays in step (triangles, wedges, ancestors).
#![allow(clippy::needless_range_loop)]

use super::charts::Charts;
use super::format::AppearanceInfo;
use super::payload::{QuantizedTable, Table, representatives};
use glam::Vec3;
use pmcodec_mesh::Appearance;
/// Attribute values of a wedge, in channel order (uv0, uv1, colour).
pub fn wedge_values(app: &Appearance, info: &AppearanceInfo, w: usize, out: &mut Vec<f64>) {
    out.clear();
    if info.uv_sets >= 1 {
        out.extend(app.uv0[w].map(f64::from));
    }
    if info.uv_sets >= 2 {
        out.extend(app.uv1[w].map(f64::from));
    }
    if info.colors {
        out.extend(app.colors[w].map(f64::from));
    }
}

/// Quantizes a value of channel `k` (texture coordinates on the header's grid, colours to 8
/// bits).
pub fn quantize(info: &AppearanceInfo, k: usize, x: f64) -> i32 {
    if k < 2 * info.uv_sets as usize {
        let a = k % 2;
        ((x - info.uv_min[a] as f64) / info.uv_step[a] as f64).round() as i32
    } else {
        (x.clamp(0.0, 1.0) * 255.0).round() as i32
    }
}

/// Sums per (node, chart) of one level above 0.
///
/// Entries are found by node: `first[g]` is node g's latest entry and `next[e]` the one
/// before it (a node spans one chart, or a few at seams). Every corner of every level of every
/// frame looks its entry up, and a hash map's probe was a third of the encoder's coding thread
/// on a 34,102-vertex skinned character (issue 17, "Encode cost").
#[derive(Default)]
struct LevelSums {
    first: Vec<u32>,
    next: Vec<u32>,
    /// (node, chart) of each entry.
    keys: Vec<(u32, u32)>,
    weight: Vec<f64>,
    sums: Vec<f64>,
    needed: Vec<bool>,
}

impl LevelSums {
    /// The entry of (`node`, `chart`), made (zero) if it is new.
    fn entry(&mut self, node: u32, chart: u32, channels: usize) -> usize {
        const NONE: u32 = u32::MAX;
        let g = node as usize;
        if g >= self.first.len() {
            self.first.resize(g + 1, NONE);
        }
        let mut e = self.first[g];
        while e != NONE {
            if self.keys[e as usize].1 == chart {
                return e as usize;
            }
            e = self.next[e as usize];
        }
        let e = self.keys.len();
        self.next.push(self.first[g]);
        self.first[g] = e as u32;
        self.keys.push((node, chart));
        self.weight.push(0.0);
        self.sums.resize(self.sums.len() + channels, 0.0);
        self.needed.push(false);
        e
    }
}

/// Accumulates the tables frame by frame ([`TableBuilder::observe`] with each frame's parent
/// maps), then quantizes them ([`TableBuilder::finish`]).
pub struct TableBuilder<'a> {
    triangles: &'a [[u32; 3]],
    app: &'a Appearance,
    charts: Charts,
    info: AppearanceInfo,
    /// A third of each triangle's area in the first frame (a tiny floor keeps slivers counted).
    weight: Vec<f64>,
    levels: Vec<LevelSums>,
    ancestor: Vec<u32>,
    scratch: Vec<f64>,
    /// The first frame's hierarchy (`parent[k][v]`), which the Key chunks of frame 0 carry.
    first_parent: Option<Vec<Vec<u32>>>,
}

impl<'a> TableBuilder<'a> {
    pub fn new(
        triangles: &'a [[u32; 3]],
        first_frame: &[Vec3],
        app: &'a Appearance,
        charts: Charts,
        info: AppearanceInfo,
        levels: usize,
    ) -> Self {
        let weight = triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| first_frame[v as usize].as_dvec3());
                ((p[1] - p[0]).cross(p[2] - p[0]).length() / 6.0).max(1e-30)
            })
            .collect();
        TableBuilder {
            triangles,
            app,
            charts,
            info,
            weight,
            levels: (0..levels).map(|_| LevelSums::default()).collect(),
            ancestor: Vec::new(),
            scratch: Vec::new(),
            first_parent: None,
        }
    }

    pub fn charts(&self) -> &Charts {
        &self.charts
    }

    pub fn info(&self) -> &AppearanceInfo {
        &self.info
    }

    pub fn appearance(&self) -> &Appearance {
        self.app
    }

    pub fn triangles(&self) -> &[[u32; 3]] {
        self.triangles
    }

    /// The parents of level `j`'s nodes in the first frame observed, if any.
    pub fn first_parent(&self, j: usize) -> Option<&[u32]> {
        self.first_parent.as_ref()?.get(j).map(Vec::as_slice)
    }

    /// Adds one frame's hierarchy (`parent[k][v]`, k below the top).
    pub fn observe(&mut self, parent: &[Vec<u32>]) {
        self.observe_times(parent, 1);
    }

    /// Adds `times` frames that share one hierarchy (`parent[k][v]`, k below the top): what
    /// [`TableBuilder::observe`] of each would add, in one pass over the triangles.
    pub fn observe_times(&mut self, parent: &[Vec<u32>], times: u32) {
        // One frame's weights are the triangles' own (times 1.0, exactly), as before.
        let times = times as f64;
        if self.first_parent.is_none() {
            self.first_parent = Some(parent.to_vec());
        }
        let channels = self.info.channels();
        self.ancestor.clear();
        self.ancestor.extend(0..parent.first().map_or(0, |p| p.len() as u32));
        for l in 1..self.levels.len() {
            for a in self.ancestor.iter_mut() {
                *a = parent[l - 1][*a as usize];
            }
            let sums = &mut self.levels[l];
            for (t, tri) in self.triangles.iter().enumerate() {
                let g = tri.map(|v| self.ancestor[v as usize]);
                let chart = self.charts.triangle_chart[t];
                for i in 0..3 {
                    let e = sums.entry(g[i], chart, channels);
                    wedge_values(self.app, &self.info, self.app.corner_wedges[t][i] as usize, &mut self.scratch);
                    let w = self.weight[t] * times;
                    sums.weight[e] += w;
                    for (s, x) in sums.sums[e * channels..].iter_mut().zip(&self.scratch) {
                        *s += w * x;
                    }
                    // A cut holding g[i] for this corner shows the triangle exactly when the other
                    // corners lie outside g[i]'s cluster: corners inside it are cut at g[i] too (a
                    // cut is a front), while corners under one other node can still be cut apart,
                    // below this level, in a budget cut that mixes levels.
                    sums.needed[e] |= g[i] != g[(i + 1) % 3] && g[i] != g[(i + 2) % 3];
                }
            }
        }
    }

    /// The quantized table of every level, level 0 first.
    pub fn finish(&mut self) -> Vec<QuantizedTable> {
        let channels = self.info.channels();
        let mut out = Vec::with_capacity(self.levels.len());
        // Level 0: the wedge of each (vertex, chart) pair.
        let mut pairs: Vec<(u32, u32, u32)> = Vec::with_capacity(self.triangles.len() * 3);
        for (t, tri) in self.triangles.iter().enumerate() {
            for i in 0..3 {
                pairs.push((tri[i], self.charts.triangle_chart[t], self.app.corner_wedges[t][i]));
            }
        }
        pairs.sort_unstable();
        pairs.dedup_by_key(|p| (p.0, p.1));
        let mut t0 = QuantizedTable::default();
        for (v, c, w) in pairs {
            t0.entries.push((v, c));
            wedge_values(self.app, &self.info, w as usize, &mut self.scratch);
            t0.values.extend(self.scratch.iter().enumerate().map(|(k, &x)| quantize(&self.info, k, x)));
        }
        // Per band, per entry: whether it represents an entry above or is represented below.
        let mut tied: Vec<Vec<bool>> = vec![vec![false; t0.entries.len()]];
        out.push(t0);
        let info = &self.info;
        for (l, sums) in self.levels.iter().enumerate().skip(1) {
            let mut keys: Vec<((u32, u32), usize)> =
                sums.keys.iter().enumerate().filter(|&(e, _)| sums.needed[e]).map(|(e, &k)| (k, e)).collect();
            keys.sort_unstable();
            let mut table = QuantizedTable::default();
            tied.push(vec![false; keys.len()]);
            for (key, e) in keys {
                table.entries.push(key);
                let w = sums.weight[e];
                table.values.extend((0..channels).map(|k| quantize(info, k, sums.sums[e * channels + k] / w)));
            }
            // A coarse value is its representative child's (payload::representatives, under
            // frame 0's hierarchy), not the mean above: one of the input's own values, which the
            // band below then need not send again. The mean stays where no child of frame 0's
            // hierarchy has an entry in the chart (pairs only other frames' swaps make).
            if let (Some(parent), Some(below)) = (self.first_parent(l - 1), out.get(l - 1)) {
                let nodes = table.entries.last().map_or(0, |e| e.0 + 1);
                let index = Table::index(&table.entries, nodes);
                let below_nodes = below.entries.last().map_or(0, |e| e.0 + 1);
                let reps = representatives(&Table::index(&below.entries, below_nodes), parent, &index);
                for (e, r) in reps.into_iter().enumerate() {
                    if let Some(a) = r {
                        let a = a as usize;
                        tied[l - 1][e] = true;
                        tied[l][a] = true;
                        table.values[a * channels..(a + 1) * channels].copy_from_slice(&below.values[e * channels..(e + 1) * channels]);
                    }
                }
            }
            out.push(table);
        }
        self.free_from_above(&mut out, &tied);
        out
    }

    /// Gives each *free* entry of a band between 0 and the top (one that no entry below
    /// represents and that represents none above: a pair only other frames' swaps make, whose
    /// value no other entry copies) the value of its parent entry in the band above (the
    /// node's parent in frame 0's hierarchy, same chart), where that entry exists, instead of
    /// its cluster's mean. Every coding of a band below the top predicts such an entry from
    /// that parent entry (proto/container.md, modes 3 and 19 and the leftovers of `| 64`), so
    /// its residual there is 0. The value is one of the chart's input values under the
    /// parent's cluster, which holds the node's, so it errs by at most that cluster's extent
    /// in the texture, one level coarser than the mean, and only in the frames whose swaps
    /// make the pair. Bands go top down, so each parent value is final when copied.
    fn free_from_above(&self, out: &mut [QuantizedTable], tied: &[Vec<bool>]) {
        let channels = self.info.channels();
        for l in (1..out.len().saturating_sub(1)).rev() {
            let Some(parent) = self.first_parent(l) else { continue };
            let (below, above) = out.split_at_mut(l + 1);
            let (table, up) = (&mut below[l], &above[0]);
            let index = Table::index(&up.entries, up.entries.last().map_or(0, |e| e.0 + 1));
            for (e, &(node, chart)) in table.entries.iter().enumerate() {
                if tied.get(l).and_then(|t| t.get(e)).copied().unwrap_or(true) {
                    continue;
                }
                let Some(a) = parent.get(node as usize).and_then(|&p| index.find(p, chart)) else { continue };
                table.values[e * channels..(e + 1) * channels].copy_from_slice(&up.values[a * channels..(a + 1) * channels]);
            }
        }
    }
}

#[cfg(test)]
#[path = "tables_tests.rs"]
mod tests;
