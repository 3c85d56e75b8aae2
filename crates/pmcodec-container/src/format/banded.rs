//! The banded index (preamble flag [`FLAG_BANDS`], proto/container.md "Index"): entries grouped
//! by who reads them, coarse first, behind a table of group lengths and checksums, so that a
//! client fetches only its level's groups.

use super::{ChunkEntry, ChunkKind, FLAG_BANDS, MAX_LEVELS};

/// Groups of a banded index ([`FLAG_BANDS`]) for a file of `levels` levels: group 0 holds what
/// every client reads (Pose, Charts, Materials and Image chunks); then for each band j from the
/// top down three groups: its topology (Triangles (band 0), Key and Delta chunks), read by the
/// clients of levels up to j and, where their band derives its faces, by every coarser client;
/// its geometry (Positions, Bind, Palette, Joints, Attributes), read by the clients of levels up
/// to j; its faces (Faces and Corners), read by the clients of level j alone.
pub fn group_count(levels: usize) -> usize {
    1 + 3 * levels
}

/// The group of a chunk of `kind` in `band` ([`group_count`]); a band beyond the top counts as
/// the top (such an entry is corrupt, and its band is lost when written).
pub fn group_of(kind: ChunkKind, band: u32, levels: usize) -> usize {
    let top = levels.saturating_sub(1);
    let base = 1 + 3 * (top - (band as usize).min(top));
    match kind {
        ChunkKind::Pose | ChunkKind::Charts | ChunkKind::Materials | ChunkKind::Image => 0,
        ChunkKind::Triangles | ChunkKind::Key | ChunkKind::Delta => base,
        ChunkKind::Positions | ChunkKind::Bind | ChunkKind::Palette | ChunkKind::Joints | ChunkKind::Attributes => base + 1,
        ChunkKind::Faces | ChunkKind::Corners => base + 2,
    }
}

/// The band of group `g >= 1`, and its part (0 topology, 1 geometry, 2 faces).
fn group_band(g: usize, levels: usize) -> (u32, usize) {
    let top = levels.saturating_sub(1);
    ((top - ((g - 1) / 3).min(top)) as u32, (g - 1) % 3)
}

/// Group `g`'s name in messages: "index group 4 (band 2 geometry)".
pub fn group_name(g: usize, levels: usize) -> String {
    if g == 0 {
        return "index group 0 (every client)".into();
    }
    let (band, part) = group_band(g, levels);
    format!("index group {g} (band {band} {})", ["topology", "geometry", "faces"][part])
}

/// The groups a client whose finest level is `level` reads: group 0, the topology and geometry
/// of bands `level..=top`, band `level`'s faces, and when band `level` derives its faces
/// (`derived`, the table's bit) the topology of the bands below it.
pub fn groups_for(levels: usize, level: usize, derived: bool) -> Vec<usize> {
    let top = levels.saturating_sub(1);
    let mut out = vec![0];
    for b in (level..=top).rev() {
        let base = 1 + 3 * (top - b);
        out.extend([base, base + 1]);
        if b == level {
            out.push(base + 2);
        }
    }
    if derived {
        out.extend((0..level.min(levels)).rev().map(|b| 1 + 3 * (top - b)));
    }
    out.sort_unstable();
    out
}

/// One row of a banded index's table: the group's entry bytes, whether it is a faces group
/// whose band derives its faces in some keyframe interval, its chunks' bytes and the CRC-32 of
/// its entry bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GroupRow {
    /// Bytes of the group's entries.
    pub body_len: u32,
    /// Faces groups: some Faces entry of the group is derived (coding 2).
    pub derived: bool,
    /// Bytes of the group's chunks in the chunk area.
    pub chunks_len: u32,
    /// CRC-32 (IEEE) of the group's entry bytes.
    pub crc32: u32,
}

/// Banded entry tag: the kind in bits 0..4, bit 4 set when the raw length is the stored
/// length, the frame's advance over the entry before in the group above.
const BANDED_KIND_BITS: u32 = 4;
const BANDED_SAME: u32 = 1 << BANDED_KIND_BITS;
const BANDED_FRAME_SHIFT: u32 = BANDED_KIND_BITS + 1;
/// Bytes a banded entry takes at least: its tag, its stored length and its CRC.
const MIN_ENTRY_BANDED: usize = 6;

/// A banded index's table ([`FLAG_BANDS`]): the group count, then per group its row: its entry
/// bytes times 2 plus the derived bit, its chunk bytes, and unless it has no entries their CRC.
pub fn parse_table(bytes: &[u8], levels: usize) -> Result<Vec<GroupRow>, crate::ContainerError> {
    let mut c = crate::payload::Cursor::new(bytes, "index table");
    let n = c.count_within(MAX_LEVELS as u64 * 3 + 1, 2, "groups")?;
    if n != group_count(levels) {
        return Err(crate::ContainerError::Corrupt {
            what: "index table".into(),
            detail: format!("{n} groups for {levels} levels (1 + 3 per level)"),
        });
    }
    let mut rows = Vec::with_capacity(n);
    for _ in 0..n {
        let first = c.get()?;
        let chunks_len = c.get()?;
        // An empty group has no CRC (that of no bytes is 0).
        let crc32 = if first >> 1 == 0 { 0 } else { c.u32_le()? };
        rows.push(GroupRow { body_len: first >> 1, derived: first & 1 != 0, chunks_len, crc32 });
    }
    c.finish()?;
    Ok(rows)
}

/// Parses group `g`'s entry bytes: its chunks start at `offset` in the chunk area and take
/// `row.chunks_len` bytes; entries of frames beyond `frames` are corrupt.
pub fn parse_group(
    bytes: &[u8],
    g: usize,
    row: &GroupRow,
    offset: u64,
    levels: usize,
    frames: u32,
) -> Result<Vec<ChunkEntry>, crate::ContainerError> {
    let what = group_name(g, levels);
    let corrupt = |detail: String| crate::ContainerError::Corrupt { what: what.clone(), detail };
    if crc32fast::hash(bytes) != row.crc32 {
        return Err(crate::ContainerError::Checksum { what: what.clone() });
    }
    let mut c = crate::payload::Cursor::new(bytes, &what);
    let mut out = Vec::with_capacity(bytes.len() / MIN_ENTRY_BANDED);
    let (mut frame, mut at) = (0u32, offset);
    while !c.at_end() {
        let tag = c.get()?;
        let kind = ChunkKind::try_from(tag & (BANDED_SAME - 1)).map_err(&corrupt)?;
        frame = frame
            .checked_add(tag >> BANDED_FRAME_SHIFT)
            .filter(|&f| f < frames)
            .ok_or_else(|| corrupt("a frame beyond the header's".into()))?;
        let band = if g == 0 { c.get()? } else { group_band(g, levels).0 };
        if group_of(kind, band, levels) != g {
            return Err(corrupt(format!("a {} chunk, which belongs to another group", kind.name())));
        }
        let stored_len = c.get()?;
        let raw_len = if tag & BANDED_SAME != 0 { stored_len } else { c.get()? };
        let crc32 = c.u32_le()?;
        out.push(ChunkEntry { kind, frame, band, offset: at, stored_len, raw_len, crc32 });
        at += stored_len as u64;
    }
    if at - offset != row.chunks_len as u64 {
        return Err(corrupt(format!("chunks of {} bytes where the table says {}", at - offset, row.chunks_len)));
    }
    let derived = out.iter().any(crate::derive::entry_is_derived);
    if derived != row.derived {
        return Err(corrupt(format!(
            "the table says its band {} its faces, its entries say otherwise",
            if row.derived { "derives" } else { "sends" }
        )));
    }
    Ok(out)
}

/// The banded index of `entries` (in file order: grouped by [`group_of`], offsets following
/// one another) and the length of its table. It writes what it can of entries that break that
/// layout (frames out of order advance by 0; bands beyond the top become the top; offsets are
/// dropped): the encoder never makes such entries, the test support's damage does on purpose.
pub fn banded_index(entries: &[ChunkEntry], levels: usize) -> Result<(Vec<u8>, u32), crate::ContainerError> {
    let n = group_count(levels);
    let mut bodies = vec![Vec::new(); n];
    let mut rows = vec![GroupRow { body_len: 0, derived: false, chunks_len: 0, crc32: 0 }; n];
    let mut frames = vec![0u32; n];
    let too_big = |what: &str| crate::ContainerError::Io(format!("index: a group's {what} beyond 4 GiB"));
    for e in entries {
        let g = group_of(e.kind, e.band, levels);
        let same = if e.raw_len == e.stored_len { BANDED_SAME } else { 0 };
        let advance = e.frame.saturating_sub(frames[g]);
        frames[g] = frames[g].max(e.frame);
        let body = &mut bodies[g];
        crate::payload::put(body, u32::from(e.kind) | same | advance << BANDED_FRAME_SHIFT);
        if g == 0 {
            crate::payload::put(body, e.band);
        }
        crate::payload::put(body, e.stored_len);
        if same == 0 {
            crate::payload::put(body, e.raw_len);
        }
        body.extend_from_slice(&e.crc32.to_le_bytes());
        rows[g].chunks_len = rows[g].chunks_len.checked_add(e.stored_len).ok_or_else(|| too_big("chunks"))?;
        rows[g].derived |= crate::derive::entry_is_derived(e);
    }
    let mut out = Vec::new();
    crate::payload::put(&mut out, n as u32);
    for (row, body) in rows.iter_mut().zip(&bodies) {
        row.body_len = u32::try_from(body.len()).ok().filter(|&l| l < 1 << 31).ok_or_else(|| too_big("entries"))?;
        row.crc32 = crc32fast::hash(body);
        crate::payload::put(&mut out, row.body_len << 1 | u32::from(row.derived));
        crate::payload::put(&mut out, row.chunks_len);
        if row.body_len > 0 {
            out.extend_from_slice(&row.crc32.to_le_bytes());
        }
    }
    let table_len = out.len() as u32;
    for body in bodies {
        out.extend_from_slice(&body);
    }
    Ok((out, table_len))
}

/// The order chunks take in a file with preamble `flags` of `levels` levels, as positions in
/// `entries` (given in the order the encoder makes them, frame after frame): the same, or with
/// [`FLAG_BANDS`] grouped by [`group_of`], each group in that order.
pub fn file_order(entries: &[ChunkEntry], flags: u16, levels: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..entries.len()).collect();
    if flags & FLAG_BANDS != 0 {
        order.sort_by_key(|&i| group_of(entries[i].kind, entries[i].band, levels));
    }
    order
}

/// Puts entries read from a banded index (group after group) in the order readers look them up
/// in: the Triangles chunk, then frame after frame (stable, so group order within a frame).
pub fn frame_order(entries: &mut [ChunkEntry]) {
    entries.sort_by_key(|e| (e.kind != ChunkKind::Triangles, e.frame));
}
