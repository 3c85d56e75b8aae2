//! ATTRIBUTES of a band with values *across its faces* (mode `3 | 64`, with the flags of mode 3:
//! `| 8` rANS residuals, `| 16` represented values, `| 32` entries from the band above;
//! proto/container.md, "Values across the band's faces").
//!
//! Band 0's values are predicted across the input triangles (mode 1, the parallelogram rule of
//! Touma & Gotsman, "Triangle mesh compression", 1998, as Draco predicts texture coordinates);
//! a coarse band's were predicted only from its parent entry's value, about 30 bits a value
//! where band 0's take 20. A coarse band is a mesh too: its faces in frame 0 are the input
//! triangles whose corners walked up frame 0's parents are distinct (what the Faces chunk of
//! band j lists at frame 0, or the derived coding rebuilds), so the same traversal runs on them
//! (Isenburg & Snoeyink, "Compressing texture coordinates with selective linear predictions",
//! 2003, predict from already-decoded neighbours across the mesh's edges the same way). A corner
//! with no known neighbour takes the band above's value of its parent entry; entries no face of
//! frame 0 reaches (pairs only other frames' swaps make) follow in table order, predicted from
//! the band above or else the entry before.

use super::codes::put_codes;
use super::entries::{put_entries, put_entries_above};
use super::payload::{
    ACROSS_FACES, DERIVED_ENTRIES, ENTRIES_ABOVE, FROM_ABOVE, QuantizedTable, RANS_VALUES, REPRESENTED, Table, corner_prediction,
    from_above, representatives, represented_agree,
};
use crate::ContainerError;
use crate::payload::{put, unzigzag, zigzag};

/// Band j's faces in frame 0 and their charts: every input triangle (in input order) whose
/// corners walked up `parents` (frame 0's parent maps of levels 0..j, finest first) are three
/// distinct level-j nodes, with those nodes. `None` when a parent map misses a node.
pub fn band_faces(triangles: &[[u32; 3]], triangle_chart: &[u32], parents: &[&[u32]]) -> Option<(Vec<[u32; 3]>, Vec<u32>)> {
    let mut faces = Vec::new();
    let mut charts = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        let mut c = *tri;
        for p in parents {
            for v in &mut c {
                *v = *p.get(*v as usize)?;
            }
        }
        if c[0] != c[1] && c[1] != c[2] && c[2] != c[0] {
            faces.push(c);
            charts.push(*triangle_chart.get(t)?);
        }
    }
    Some((faces, charts))
}

/// Whether a table's payload predicts its values across the band's faces (its reader then
/// needs them: [`band_faces`]).
pub fn needs_faces(bytes: &[u8]) -> bool {
    bytes.len() > 1 && bytes[0] == 0 && bytes[1] & ACROSS_FACES as u8 != 0
}

/// Visits every entry not `known` once: first across `faces` ([`traverse`], a corner with no
/// known neighbour predicted from the band above), then the rest in table order, each
/// predicted from the band above's value of its parent entry, else the entry before's (zeros
/// for the first). `visit(prediction, values)` as in [`traverse`].
#[allow(clippy::too_many_arguments)]
fn visit_across(
    table: &Table,
    node_of: &[u32],
    channels: usize,
    values: &mut [i32],
    known: &mut [bool],
    above: (&[u32], &Table),
    faces: (&[[u32; 3]], &[u32]),
    mut visit: impl FnMut(&[i32], &mut [i32]) -> Result<(), ContainerError>,
    what: &str,
) -> Result<(), ContainerError> {
    let c = channels;
    let parent_value = |x: usize, q: usize| {
        let (node, chart) = (*node_of.get(x)?, *table.charts.get(x)?);
        from_above(Some(above), node, chart, c, q)
    };
    traverse_faces(table, faces, c, values, known, &parent_value, &mut visit, what)?;
    let mut pred = vec![0i32; c];
    for x in 0..table.len() {
        if known[x] {
            continue;
        }
        for (q, p) in pred.iter_mut().enumerate() {
            *p = parent_value(x, q).unwrap_or(if x > 0 { values[(x - 1) * c + q] } else { 0 });
        }
        visit(&pred, &mut values[x * c..(x + 1) * c])?;
        known[x] = true;
    }
    Ok(())
}

/// ATTRIBUTES of a band below the top with values *across its faces*: `0`, `3 | 64` (with
/// `represented`, `| 16`; with `entries_above`, `| 32`; with `rans`, `| 8`), then the entries as
/// mode 3 (or `| 32`) writes them, then the residuals against [`visit_across`]'s predictions in
/// its visiting order, channel by channel (a [`put_codes`] section). `faces` are band j's faces
/// in frame 0 ([`band_faces`]). `None` when a representative's value differs from its parent
/// entry's or a face's corner has no entry.
#[allow(clippy::too_many_arguments)]
pub fn write_table_across(
    t: &QuantizedTable,
    channels: usize,
    parent: &[u32],
    above: &Table,
    faces: (&[[u32; 3]], &[u32]),
    rans: bool,
    represented: bool,
    entries_above: bool,
) -> Option<Vec<u8>> {
    let (residuals, coded) = across_residuals(t, channels, represented, (parent, above), faces, "attributes")?;
    let mut out = Vec::new();
    put(&mut out, 0);
    let flags =
        if represented { REPRESENTED } else { 0 } | if entries_above { ENTRIES_ABOVE } else { 0 } | if rans { RANS_VALUES } else { 0 };
    put(&mut out, FROM_ABOVE | ACROSS_FACES | flags);
    if entries_above {
        put_entries_above(&mut out, &t.entries, parent, above);
    } else {
        put_entries(&mut out, &t.entries);
    }
    put_codes(&mut out, &residuals, coded, channels, rans);
    Some(out)
}

/// ATTRIBUTES, band 0 with derived entries, represented values and values *across the
/// triangles* averaged with the parent entry's: `0`, `1 | 16 | 64` (with `rans`, `| 8`), then
/// the residuals against [`visit_across`]'s predictions over band 0's faces (the triangles with
/// three distinct corners, [`band_faces`] with no parents). `t`'s entries must be
/// [`band0_entries`](super::payload::band0_entries) of the triangles and charts. `None` where
/// mode `1 | 16` is `None`.
pub fn write_table_derived_across(
    t: &QuantizedTable,
    channels: usize,
    triangles: &[[u32; 3]],
    triangle_chart: &[u32],
    parent: &[u32],
    above: &Table,
    rans: bool,
) -> Option<Vec<u8>> {
    let faces = band_faces(triangles, triangle_chart, &[])?;
    let f = (&faces.0[..], &faces.1[..]);
    let (residuals, coded) = across_residuals(t, channels, true, (parent, above), f, "band 0 attributes")?;
    let mut out = Vec::new();
    put(&mut out, 0);
    put(&mut out, DERIVED_ENTRIES | REPRESENTED | ACROSS_FACES | if rans { RANS_VALUES } else { 0 });
    put_codes(&mut out, &residuals, coded, channels, rans);
    Some(out)
}

/// The residual codes of table `t` against [`visit_across`]'s predictions over `faces`,
/// channel after channel, and how many values each channel codes (those its representatives,
/// with `represented`, leave out). `None` where a representative's value differs from its
/// parent entry's or a face's corner has no entry.
fn across_residuals(
    t: &QuantizedTable,
    channels: usize,
    represented: bool,
    (parent, above): (&[u32], &Table),
    faces: (&[[u32; 3]], &[u32]),
    what: &str,
) -> Option<(Vec<u32>, usize)> {
    let nodes = t.entries.last().map_or(0, |e| e.0 + 1);
    let table = Table::index(&t.entries, nodes);
    let reps = if represented { representatives(&table, parent, above) } else { Vec::new() };
    if !represented_agree(&reps, &t.values, &above.values, channels) {
        return None;
    }
    let mut known: Vec<bool> = reps.iter().map(Option::is_some).collect();
    known.resize(t.entries.len(), false);
    let coded = known.iter().filter(|&&k| !k).count();
    let node_of: Vec<u32> = t.entries.iter().map(|e| e.0).collect();
    let mut values = t.values.clone();
    let mut residuals: Vec<Vec<u32>> = vec![Vec::with_capacity(coded); channels];
    let visit = |pred: &[i32], v: &mut [i32]| {
        for q in 0..channels {
            residuals[q].push(zigzag(v[q].wrapping_sub(pred[q])));
        }
        Ok(())
    };
    visit_across(&table, &node_of, channels, &mut values, &mut known, (parent, above), faces, visit, what).ok()?;
    Some((residuals.concat(), coded))
}

/// The values of a table with values across its faces, its entries (`table`, `node_of`) and
/// representatives (`reps`) read, from its `coded` residual codes per channel.
#[allow(clippy::too_many_arguments)]
pub(super) fn read_values(
    table: &Table,
    node_of: &[u32],
    reps: &[Option<u32>],
    channels: usize,
    above: (&[u32], &Table),
    faces: (&[[u32; 3]], &[u32]),
    codes: &[u32],
    coded: usize,
    what: &str,
) -> Result<Vec<i32>, ContainerError> {
    let corrupt = |detail: &str| ContainerError::Corrupt { what: what.into(), detail: detail.into() };
    let m = table.len();
    let mut values = vec![0i32; m * channels];
    let mut known = vec![false; m];
    for (e, r) in reps.iter().enumerate() {
        if let Some(a) = *r {
            let a = a as usize;
            let from = above.1.values.get(a * channels..(a + 1) * channels).ok_or_else(|| corrupt("band above without values"))?;
            values[e * channels..(e + 1) * channels].copy_from_slice(from);
            known[e] = true;
        }
    }
    let mut k = 0;
    let visit = |pred: &[i32], v: &mut [i32]| {
        for q in 0..channels {
            let z = codes.get(q * coded + k).filter(|_| k < coded).ok_or_else(|| corrupt("fewer residuals than entries"))?;
            v[q] = pred[q].wrapping_add(unzigzag(*z));
        }
        k += 1;
        Ok(())
    };
    visit_across(table, node_of, channels, &mut values, &mut known, above, faces, visit, what)?;
    Ok(values)
}

/// The traversal of the band's faces (proto/container.md, "Values across the band's faces"):
/// faces in order, each one's corners in order; a corner whose entry is not yet known is
/// predicted from its face's two other corners: the parallelogram `a + b - o` when both are
/// known and an earlier face shares their edge (o its third corner; Touma & Gotsman 1998),
/// else their mean, else the one known corner; that prediction is averaged with the band
/// above's value p of the corner's parent entry where there is one, `(pred + p) >> 1`: on a
/// coarse band the two err about equally and apart, so their mean errs less (Isenburg &
/// Snoeyink 2003 likewise select among linear predictions). With no known corner: p, else
/// the last value made known in the face's chart, else the last made known (zeros at first).
#[allow(clippy::too_many_arguments)]
fn traverse_faces(
    table: &Table,
    faces: (&[[u32; 3]], &[u32]),
    c: usize,
    values: &mut [i32],
    known: &mut [bool],
    parent_value: &dyn Fn(usize, usize) -> Option<i32>,
    mut visit: impl FnMut(&[i32], &mut [i32]) -> Result<(), ContainerError>,
    what: &str,
) -> Result<(), ContainerError> {
    let (tris, face_chart) = faces;
    let mut opposite: std::collections::HashMap<u64, u32> = std::collections::HashMap::new();
    let key = |a: usize, b: usize| ((a.min(b) as u64) << 32) | a.max(b) as u64;
    let mut entries = Vec::with_capacity(tris.len());
    for (t, (tri, &chart)) in tris.iter().zip(face_chart).enumerate() {
        let mut e = [0usize; 3];
        for i in 0..3 {
            e[i] = table.find(tri[i], chart).ok_or_else(|| ContainerError::Corrupt {
                what: what.into(),
                detail: format!("no entry for node {}, chart {chart} of face {t}", tri[i]),
            })?;
        }
        entries.push(e);
    }
    let charts = face_chart.iter().map(|&k| k as usize + 1).max().unwrap_or(0);
    let mut last = vec![0i32; c];
    let mut chart_last = vec![0i32; charts * c];
    let mut chart_seen = vec![false; charts];
    let mut pred = vec![0i32; c];
    for (e, &chart) in entries.iter().zip(face_chart) {
        let chart = chart as usize;
        for i in 0..3 {
            let x = e[i];
            if known[x] {
                continue;
            }
            let (a, b) = (e[(i + 1) % 3], e[(i + 2) % 3]);
            let (ka, kb) = (known[a], known[b]);
            for q in 0..c {
                let (va, vb) = (values[a * c + q], values[b * c + q]);
                let p = parent_value(x, q);
                // The opposite corner only where both edge corners are known (its one use).
                let o = if ka && kb { opposite.get(&key(a, b)).map(|&o| values[o as usize * c + q]) } else { None };
                let from_corners = corner_prediction((ka, va), (kb, vb), o);
                pred[q] = match (from_corners, p) {
                    (Some(f), Some(p)) => f.wrapping_add(p) >> 1,
                    (Some(f), None) => f,
                    (None, Some(p)) => p,
                    (None, None) if chart_seen[chart] => chart_last[chart * c + q],
                    (None, None) => last[q],
                };
            }
            visit(&pred, &mut values[x * c..(x + 1) * c])?;
            known[x] = true;
            last.copy_from_slice(&values[x * c..(x + 1) * c]);
            chart_seen[chart] = true;
            chart_last[chart * c..(chart + 1) * c].copy_from_slice(&values[x * c..(x + 1) * c]);
        }
        // Band faces have distinct corners (`band_faces`), and so distinct entries.
        for i in 0..3 {
            opposite.entry(key(e[i], e[(i + 1) % 3])).or_insert(e[(i + 2) % 3] as u32);
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "across_tests.rs"]
mod tests;
