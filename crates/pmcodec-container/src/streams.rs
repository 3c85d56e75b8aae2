//! What a client drawing down to one level reads of a file, as byte ranges: the server's index
//! answer and `/stream` route and the clients (Rust and, mirrored, the browser player) compute
//! them here, so that a server sending a level's bytes and a client placing them back at their
//! offsets agree on one list.
//!
//! A file's bytes split into its *head* (preamble, header and index) and its chunks. Of a banded
//! index ([`crate::format::FLAG_BANDS`]) the head a client of level L reads is the preamble, the
//! header, the group table and the entries of the groups it reads
//! ([`crate::format::groups_for`]); of any other index, the whole head. Its chunks are those
//! [`crate::reads`] says it reads, frame after frame.

use crate::format::{ChunkEntry, ChunkKind, Header, Index, PREAMBLE_LEN, Preamble};
use crate::{ByteSource, ContainerError};
use std::collections::BTreeMap;
use std::ops::Range;

/// Whether a file with this preamble has a banded index.
pub fn is_banded(pre: &Preamble) -> bool {
    pre.version >= 7 && pre.flags & crate::format::FLAG_BANDS != 0
}

/// The bytes a client reads first, whatever its level: the preamble, the header and, of a
/// banded index, its group table; of any other index, all of it.
pub fn first_read(pre: &Preamble) -> Range<u64> {
    let header_end = PREAMBLE_LEN as u64 + pre.header_len as u64;
    0..header_end + if is_banded(pre) { pre.table_len as u64 } else { pre.index_len as u64 }
}

/// The head a client whose finest level is `level` reads ([`first_read`], then of a banded
/// index the entries of its groups), adjacent ranges merged. `first` holds at least the
/// [`first_read`] bytes (the header and table are parsed from it).
pub fn head_ranges(first: &[u8], level: usize) -> Result<Vec<Range<u64>>, ContainerError> {
    let truncated = || ContainerError::Truncated { what: "header and index table".into() };
    let pre = Preamble::parse(first.get(..PREAMBLE_LEN).ok_or_else(truncated)?)?;
    let head = first_read(&pre);
    if !is_banded(&pre) {
        return Ok(vec![head]);
    }
    let header_at = PREAMBLE_LEN;
    let table_at = header_at + pre.header_len as usize;
    let table = first.get(table_at..head.end as usize).ok_or_else(truncated)?;
    if crc32fast::hash(table) != pre.index_crc {
        return Err(ContainerError::Checksum { what: "index table".into() });
    }
    let header = Header::from_bytes(&first[header_at..table_at], pre.version)?;
    let levels = header.levels();
    let rows = crate::format::parse_table(table, levels)?;
    let derived = rows.get(crate::format::group_of(ChunkKind::Faces, level as u32, levels)).is_some_and(|r| r.derived);
    let wanted = crate::format::groups_for(levels, level.min(levels.saturating_sub(1)), derived);
    let mut out = vec![head.clone()];
    let mut at = head.end;
    for (g, row) in rows.iter().enumerate() {
        let end = at + row.body_len as u64;
        if row.body_len > 0 && wanted.contains(&g) {
            push_merged(&mut out, at..end);
        }
        at = end;
    }
    Ok(out)
}

/// Appends `r` to `ranges`, extending the last one when `r` starts where it ends.
pub fn push_merged(ranges: &mut Vec<Range<u64>>, r: Range<u64>) {
    match ranges.last_mut() {
        Some(last) if last.end == r.start => last.end = r.end,
        _ if r.is_empty() => {}
        _ => ranges.push(r),
    }
}

/// The chunks a client that draws down to `level` and starts playing at frame `from` reads, in
/// the order of `chunks` (frame order, as a [`crate::Reader`] holds them): those of frames from
/// the keyframe at or before `from` that [`crate::reads`] says it reads, and whatever `from`
/// is, the frame-0 chunks every frame reads (the input triangles, the skin's bind chunks, the
/// appearance's charts, materials and attribute tables, and frame 0's Key chunks: attribute
/// values may be predicted through frame 0's hierarchy, and a later keyframe's Key chunk may
/// code its changes from frame 0's).
pub fn chunks_for<'a>(chunks: &'a [ChunkEntry], header: &Header, level: usize, from: u32) -> impl Iterator<Item = (usize, &'a ChunkEntry)> {
    let (interval, start) = (header.keyframe_interval, header.keyframe_before(from.min(header.frame_count.saturating_sub(1))));
    chunks.iter().enumerate().filter(move |(_, e)| {
        let every_frame = match e.kind {
            ChunkKind::Triangles | ChunkKind::Bind | ChunkKind::Charts | ChunkKind::Materials | ChunkKind::Attributes => true,
            ChunkKind::Key => e.frame == 0,
            _ => false,
        };
        crate::reads(chunks, interval, e, level) && (every_frame || e.frame >= start)
    })
}

/// The byte ranges (absolute, `data_start` added) of [`chunks_for`]'s chunks, per frame (chunks
/// every frame reads count as frame 0's), adjacent ranges merged.
pub fn frame_ranges(chunks: &[ChunkEntry], header: &Header, data_start: u64, level: usize, from: u32) -> Vec<Vec<Range<u64>>> {
    let mut out = vec![Vec::new(); header.frame_count as usize];
    for (_, e) in chunks_for(chunks, header, level, from) {
        let f = if e.kind == ChunkKind::Triangles { 0 } else { e.frame as usize };
        if let Some(slot) = out.get_mut(f) {
            let start = data_start + e.offset;
            push_merged(slot, start..start + e.stored_len as u64);
        }
    }
    out
}

/// Bytes held at some offsets of a file, served as a [`ByteSource`]; a read outside them is an
/// error that names the missing range (the client fetches before it decodes).
#[derive(Debug, Default)]
pub struct Sparse {
    len: u64,
    pieces: BTreeMap<u64, Vec<u8>>,
}

impl Sparse {
    /// No bytes yet of a file of `len` bytes.
    pub fn new(len: u64) -> Self {
        Sparse { len, pieces: BTreeMap::new() }
    }

    /// Holds `bytes` at `offset`.
    pub fn insert(&mut self, offset: u64, bytes: Vec<u8>) {
        self.pieces.insert(offset, bytes);
    }

    /// Whether bytes `offset..offset + len` are held (in one piece).
    pub fn has(&self, offset: u64, len: u64) -> bool {
        self.pieces.range(..=offset).next_back().is_some_and(|(&s, b)| s + b.len() as u64 >= offset + len)
    }

    /// Bytes held in all.
    pub fn held(&self) -> u64 {
        self.pieces.values().map(|b| b.len() as u64).sum()
    }
}

impl ByteSource for Sparse {
    fn len(&self) -> Result<u64, ContainerError> {
        Ok(self.len)
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        if let Some((&s, b)) = self.pieces.range(..=offset).next_back() {
            let i = (offset - s) as usize;
            if let Some(bytes) = i.checked_add(len).and_then(|end| b.get(i..end)) {
                return Ok(bytes.to_vec());
            }
        }
        Err(ContainerError::Io(format!("bytes {offset}..{} were not fetched", offset + len as u64)))
    }
}

/// The length of the file whose head `first` starts ([`first_read`] bytes at least, and of an
/// index that is not banded, the whole index): the chunk area ends with its last chunk.
fn file_len(first: &[u8], pre: &Preamble) -> Result<u64, ContainerError> {
    let header_end = PREAMBLE_LEN + pre.header_len as usize;
    let data_start = header_end as u64 + pre.index_len as u64;
    let truncated = || ContainerError::Truncated { what: "header and index".into() };
    let header = Header::from_bytes(first.get(PREAMBLE_LEN..header_end).ok_or_else(truncated)?, pre.version)?;
    if is_banded(pre) {
        let table = first.get(header_end..header_end + pre.table_len as usize).ok_or_else(truncated)?;
        let rows = crate::format::parse_table(table, header.levels())?;
        return Ok(data_start + rows.iter().map(|r| r.chunks_len as u64).sum::<u64>());
    }
    let ib = first.get(header_end..data_start as usize).ok_or_else(truncated)?;
    let index = Index::from_bytes(ib, pre.version, header.frame_count)?;
    Ok(data_start + index.chunks.iter().map(|e| e.offset + e.stored_len as u64).max().unwrap_or(0))
}

/// The file as a client of `level` that asked to start at frame `from` holds it after reading
/// `body`, the server's `/stream?level=level&from=from` answer: the [`head_ranges`] one after
/// the other, then the [`frame_ranges`] frame after frame, each placed back at its offset. A
/// [`crate::Reader::open_at`] of that level over it, and a [`crate::Decoder`] of that level,
/// read only what it holds.
pub fn stream_source(body: &[u8], level: usize, from: u32) -> Result<Sparse, ContainerError> {
    let truncated = |what: &str| ContainerError::Truncated { what: format!("stream: {what}") };
    let pre = Preamble::parse(body.get(..PREAMBLE_LEN).ok_or_else(|| truncated("preamble"))?)?;
    let first = body.get(..first_read(&pre).end as usize).ok_or_else(|| truncated("header and index"))?;
    let mut source = Sparse::new(file_len(first, &pre)?);
    let mut at = 0usize;
    let mut take = |source: &mut Sparse, r: Range<u64>, what: &str| -> Result<(), ContainerError> {
        let n = (r.end - r.start) as usize;
        let bytes = body.get(at..at + n).ok_or_else(|| truncated(what))?;
        source.insert(r.start, bytes.to_vec());
        at += n;
        Ok(())
    };
    for r in head_ranges(first, level)? {
        take(&mut source, r, "index")?;
    }
    let reader = crate::Reader::open_at(&source, level)?;
    let (h, start) = (reader.header().clone(), reader.data_start());
    let ranges = frame_ranges(&reader.index().chunks, &h, start, level, from);
    drop(reader);
    for r in ranges.into_iter().flatten() {
        take(&mut source, r, "chunks")?;
    }
    if at != body.len() {
        return Err(ContainerError::TrailingBytes { bytes: (body.len() - at) as u64 });
    }
    Ok(source)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn merged_ranges_join_only_adjacent_ones() {
        let mut v = Vec::new();
        push_merged(&mut v, 0..4);
        push_merged(&mut v, 4..9);
        push_merged(&mut v, 9..9);
        push_merged(&mut v, 12..13);
        assert_eq!(v, vec![0..9, 12..13]);
    }

    #[test]
    fn sparse_reads_only_what_it_holds() {
        let mut s = Sparse::new(100);
        s.insert(10, vec![1, 2, 3, 4]);
        assert_eq!(s.read_at(11, 2).unwrap(), vec![2, 3]);
        assert!(s.read_at(12, 4).is_err());
        assert!(s.read_at(0, 1).is_err());
        assert!(s.has(10, 4) && !s.has(9, 2));
        assert_eq!(s.held(), 4);
    }
}
