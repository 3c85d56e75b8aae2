//! An attribute table's entries, listed or coded from the band above's (proto/container.md,
//! "Attributes, band j": *entries from the band above*).

use super::payload::Table;
use crate::ContainerError;
use crate::payload::{Cursor, put};

/// ENTRIES FROM ABOVE: `n` (the entries' nodes are below it), then for each node c < n and each
/// entry (P[c], k) of the band above in its order, one bit: whether (c, k) is an entry (packed
/// from bit 0 of byte 0 upward, the bytes the bits need); then `x` and the x entries whose
/// chart the parent has no entry in, listed as [`super::payload::write_table`] lists entries. A node's entries
/// mostly lie in its parent's charts (the parent's are their union in frame 0), so a bit each
/// replaces two varints (Fox's band 1: 159 B of listed entries).
pub(super) fn put_entries_above(out: &mut Vec<u8>, entries: &[(u32, u32)], parent: &[u32], above: &Table) {
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
pub(super) fn read_entries_above(
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
pub(super) fn put_entries(out: &mut Vec<u8>, entries: &[(u32, u32)]) {
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
pub(super) fn read_entries(c: &mut Cursor<'_>, m: usize, nodes: u32, charts: u32) -> Result<Vec<(u32, u32)>, ContainerError> {
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
