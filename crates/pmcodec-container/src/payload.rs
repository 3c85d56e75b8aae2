//! Chunk payloads: every integer is an unsigned LEB128 varint (signed values zigzag-encoded),
//! ids in ascending lists are delta-coded. Readers check every count against the header before
//! allocating and every id against its range.

use crate::ContainerError;

/// Appends `v` as an unsigned LEB128 varint (1 to 5 bytes).
pub fn put(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Zigzag code of `v`: 0, -1, 1, -2 ... to 0, 1, 2, 3 ..., so small magnitudes make short varints.
#[inline]
pub fn zigzag(v: i32) -> u32 {
    ((v << 1) ^ (v >> 31)) as u32
}

/// The inverse of [`zigzag`].
#[inline]
pub fn unzigzag(v: u32) -> i32 {
    ((v >> 1) as i32) ^ -((v & 1) as i32)
}

/// A bounds-checked varint reader over one chunk.
pub struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    what: &'a str,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `bytes`; `what` names the chunk in errors.
    pub fn new(bytes: &'a [u8], what: &'a str) -> Self {
        Cursor { bytes, pos: 0, what }
    }

    /// The next byte, not consumed.
    pub fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    fn corrupt(&self, detail: impl Into<String>) -> ContainerError {
        ContainerError::Corrupt { what: self.what.to_string(), detail: detail.into() }
    }

    /// The next varint; [`ContainerError::Corrupt`] when it ends early or exceeds 32 bits.
    pub fn get(&mut self) -> Result<u32, ContainerError> {
        let mut v: u64 = 0;
        for shift in (0..35).step_by(7) {
            let Some(&b) = self.bytes.get(self.pos) else {
                return Err(self.corrupt(format!("ends inside a number at byte {}", self.pos)));
            };
            self.pos += 1;
            v |= ((b & 0x7f) as u64) << shift;
            if b & 0x80 == 0 {
                return u32::try_from(v).map_err(|_| self.corrupt("number beyond 32 bits"));
            }
        }
        Err(self.corrupt("number longer than 5 bytes"))
    }

    /// A 4-byte little-endian value (a CRC-32 in the version 7 index).
    pub fn u32_le(&mut self) -> Result<u32, ContainerError> {
        let Some(b) = self.bytes.get(self.pos..self.pos + 4) else {
            return Err(self.corrupt(format!("ends inside a 4-byte value at byte {}", self.pos)));
        };
        self.pos += 4;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A value that must be below `limit` (an id).
    pub fn id(&mut self, limit: u32, name: &str) -> Result<u32, ContainerError> {
        let v = self.get()?;
        if v >= limit {
            return Err(self.corrupt(format!("{name} {v} out of range (< {limit})")));
        }
        Ok(v)
    }

    /// A count that must not exceed `limit` (so allocations stay bounded).
    pub fn count(&mut self, limit: u64, name: &str) -> Result<usize, ContainerError> {
        let v = self.get()?;
        if v as u64 > limit {
            return Err(self.corrupt(format!("{v} {name}, more than the {limit} possible")));
        }
        Ok(v as usize)
    }

    /// A count of items of at least `min_bytes` bytes each that must not exceed `limit` nor
    /// what the rest of the payload can hold: checked before anything is sized from it.
    pub fn count_within(&mut self, limit: u64, min_bytes: usize, name: &str) -> Result<usize, ContainerError> {
        let n = self.count(limit, name)?;
        let left = self.bytes.len() - self.pos;
        if n.saturating_mul(min_bytes) > left {
            return Err(self.corrupt(format!("{n} {name} in {left} bytes (each takes at least {min_bytes})")));
        }
        Ok(n)
    }

    /// The next id of an ascending list: previous + delta.
    pub fn ascending(&mut self, prev: &mut Option<u32>, limit: u32, name: &str) -> Result<u32, ContainerError> {
        let d = self.get()?;
        let v = match *prev {
            None => d as u64,
            Some(p) => p as u64 + d as u64 + 1,
        };
        if v >= limit as u64 {
            return Err(self.corrupt(format!("{name} {v} out of range (< {limit})")));
        }
        *prev = Some(v as u32);
        Ok(v as u32)
    }

    /// The next `len` bytes as they are (an entropy-coded stream inside a payload).
    pub fn take(&mut self, len: usize) -> Result<&'a [u8], ContainerError> {
        let Some(b) = self.pos.checked_add(len).and_then(|end| self.bytes.get(self.pos..end)) else {
            return Err(self.corrupt(format!("{len} bytes wanted at byte {} of {}", self.pos, self.bytes.len())));
        };
        self.pos += len;
        Ok(b)
    }

    /// Whether every byte was read.
    pub fn at_end(&self) -> bool {
        self.pos >= self.bytes.len()
    }

    /// Succeeds only when every byte was read: a chunk with bytes left over is corrupt.
    pub fn finish(&self) -> Result<(), ContainerError> {
        if self.pos == self.bytes.len() { Ok(()) } else { Err(self.corrupt(format!("{} bytes left over", self.bytes.len() - self.pos))) }
    }
}

fn put_ascending(out: &mut Vec<u8>, prev: &mut Option<u32>, v: u32) {
    put(
        out,
        match *prev {
            None => v,
            Some(p) => v - p - 1,
        },
    );
    *prev = Some(v);
}

/// TRIANGLES: count, then three corners per triangle; from version 7 each corner as the
/// zigzag-coded difference from the same corner of the triangle before (from 0 for the first;
/// 32-bit wrapping), as FACES codes corners: triangles near in input order share vertices or
/// lie next to them, so most differences take one byte, often a repeated one (cloth of 5,618
/// triangles: 13,854 bytes as plain ids; `cargo run --release -p pmcodec-container --example
/// overhead`). Versions up to 6 store plain ids.
pub fn write_triangles(tris: &[[u32; 3]], version: u16) -> Vec<u8> {
    let mut out = Vec::with_capacity(tris.len() * 8);
    put(&mut out, tris.len() as u32);
    let mut last = [0u32; 3];
    for t in tris {
        for i in 0..3 {
            put(&mut out, if version >= 7 { zigzag(t[i].wrapping_sub(last[i]) as i32) } else { t[i] });
        }
        last = *t;
    }
    out
}

/// The TRIANGLES payload (corners below `vertices`) in whichever coding stores shorter: the
/// varint differences of [`write_triangles`] (version 7) or coding 1, a Faces chunk's bit
/// coding of every triangle ("Triangles"), kept only when it reads back as the same triangles.
pub fn write_triangles_best(tris: &[[u32; 3]], vertices: u32) -> Vec<u8> {
    let plain = write_triangles(tris, crate::format::VERSION);
    if tris.is_empty() {
        return plain;
    }
    let faces: Vec<(u32, [u32; 3])> = tris.iter().enumerate().map(|(t, &c)| (t as u32, c)).collect();
    let bits = crate::topology::write_faces(&faces);
    let same = read_triangles(&bits, "triangles", tris.len() as u32, vertices, crate::format::VERSION).is_ok_and(|t| t == tris);
    if same && stored_size(&bits) < stored_size(&plain) { bits } else { plain }
}

/// Reads a TRIANGLES chunk of a file of format `version` (see [`write_triangles`]): exactly
/// `triangles` triangles, every index below `vertices`.
pub fn read_triangles(bytes: &[u8], what: &str, triangles: u32, vertices: u32, version: u16) -> Result<Vec<[u32; 3]>, ContainerError> {
    if version >= 7
        && let Some(start) = crate::topology::coded(bytes, what)?
    {
        // Coding 1: a Faces chunk's coding 1 of every triangle in order (each gap 0).
        let faces = crate::topology::read_faces(bytes, start, what, vertices, triangles)?;
        if faces.len() != triangles as usize {
            return Err(ContainerError::Corrupt {
                what: what.to_string(),
                detail: format!("{} triangles where the header says {triangles}", faces.len()),
            });
        }
        return Ok(faces.into_iter().map(|(_, c)| c).collect());
    }
    let mut c = Cursor::new(bytes, what);
    let n = c.count_within(triangles as u64, 3, "triangles")?;
    if n != triangles as usize {
        return Err(c.corrupt(format!("{n} triangles where the header says {triangles}")));
    }
    let mut out = Vec::with_capacity(n);
    let mut last = [0u32; 3];
    for _ in 0..n {
        let mut t = [0u32; 3];
        for (i, x) in t.iter_mut().enumerate() {
            *x = if version >= 7 { last[i].wrapping_add(unzigzag(c.get()?) as u32) } else { c.get()? };
            if *x >= vertices {
                return Err(c.corrupt(format!("vertex {x} out of range (< {vertices})")));
            }
        }
        last = t;
        out.push(t);
    }
    c.finish()?;
    Ok(out)
}

/// KEY band j: the parent map (|M_j| entries; none for the top band); from version 7 each
/// parent as the zigzag-coded difference from the node before's (from 0 for the first; 32-bit
/// wrapping): nodes near in id order are near on the surface and often share their cluster, so
/// the differences are small and often 0 (cloth of 2,916 vertices, 200 frames, 13 keyframes:
/// 43,886 B to 35,380 B; `cargo run --release -p pmcodec-container --example overhead`).
/// Versions up to 6 store plain ids.
pub fn write_key(parent: &[u32], version: u16) -> Vec<u8> {
    let mut out = Vec::with_capacity(parent.len() * 2 + 4);
    put(&mut out, parent.len() as u32);
    let mut last = 0u32;
    for &p in parent {
        put(&mut out, if version >= 7 { zigzag(p.wrapping_sub(last) as i32) } else { p });
        last = p;
    }
    out
}

/// Reads a KEY chunk of a file of format `version` (see [`write_key`]) for `band`:
/// `sizes[band]` parents below `sizes[band + 1]` (none for the top band).
pub fn read_key(bytes: &[u8], what: &str, sizes: &[u32], band: usize, version: u16) -> Result<Vec<u32>, ContainerError> {
    read_key_from(bytes, what, sizes, band, version, None)
}

/// Key coding 3: the payload's coding byte (proto/container.md, "Key").
pub const KEY_FROM_FIRST: u8 = 3;

/// Whether a Key payload is in coding 3 (the changes from frame 0's parent map of its band),
/// which [`read_key_from`] reads with frame 0's parents.
pub fn key_from_first(bytes: &[u8]) -> bool {
    bytes.len() > 2 && bytes[0] == 0 && bytes[1] == KEY_FROM_FIRST
}

/// [`read_key`] with `first`, the band's parents in frame 0's Key chunk, which a keyframe's Key
/// chunk in coding 3 changes (and needs: without them such a chunk is an error that says so).
pub fn read_key_from(
    bytes: &[u8],
    what: &str,
    sizes: &[u32],
    band: usize,
    version: u16,
    first: Option<&[u32]>,
) -> Result<Vec<u32>, ContainerError> {
    let top = sizes.len() - 1;
    if version >= 7 && key_from_first(bytes) {
        let corrupt = |detail: String| ContainerError::Corrupt { what: what.to_string(), detail };
        if band >= top {
            return Err(corrupt("Key coding 3 in the top band".into()));
        }
        let first = first.ok_or_else(|| corrupt("Key coding 3 read without frame 0's parents (or in frame 0's Key chunk)".into()))?;
        if first.len() != sizes[band] as usize {
            return Err(corrupt(format!("{} parents of frame 0 for {} nodes", first.len(), sizes[band])));
        }
        let moves = crate::topology::read_delta(bytes, 2, what, sizes[band], sizes[band + 1])?;
        let mut parent = first.to_vec();
        for (v, p) in moves {
            parent[v as usize] = p;
        }
        return Ok(parent);
    }
    if let Some(start) = crate::topology::coded(bytes, what)? {
        let (expected, limit) = if band < top { (sizes[band], sizes[band + 1]) } else { (0, 0) };
        return crate::topology::read_key(bytes, start, what, expected, limit);
    }
    let mut c = Cursor::new(bytes, what);
    let n = c.count_within(sizes[band] as u64, 1, "parents")?;
    let expected = if band < top { sizes[band] as usize } else { 0 };
    if n != expected {
        return Err(c.corrupt(format!("{n} parents for {expected} nodes")));
    }
    let limit = if band < top { sizes[band + 1] } else { 0 };
    let mut parent = Vec::with_capacity(n);
    let mut last = 0u32;
    for _ in 0..n {
        let p = if version >= 7 { last.wrapping_add(unzigzag(c.get()?) as u32) } else { c.get()? };
        if p >= limit {
            return Err(c.corrupt(format!("parent {p} out of range (< {limit})")));
        }
        parent.push(p);
        last = p;
    }
    c.finish()?;
    Ok(parent)
}

/// FACES band j: a count, then per triangle alive at level j on the keyframe, ascending, the
/// triangle (delta-coded) and its three level-j corners, each as the zigzag difference from the
/// same corner of the entry before (0 before the first): triangles near in input order are near
/// on the surface, and so are their nodes' ids (29% fewer bytes than plain ids on the horse).
/// Versions 3 and 4 store plain ids, and code CORNERS chunks the same way (corner updates:
/// the triangles whose level-j corners changed on a frame; two equal corners: the triangle
/// stopped being alive at j).
pub fn write_faces(faces: &[(u32, [u32; 3])]) -> Vec<u8> {
    let mut out = Vec::with_capacity(faces.len() * 6 + 4);
    put(&mut out, faces.len() as u32);
    let mut prev = None;
    let mut last = [0u32; 3];
    for (t, c) in faces {
        put_ascending(&mut out, &mut prev, *t);
        for i in 0..3 {
            put(&mut out, zigzag(c[i].wrapping_sub(last[i]) as i32));
        }
        last = *c;
    }
    out
}

/// Reads a FACES chunk; with `version` < 5, corners as plain ids, which is also how versions 3
/// and 4 code their CORNERS chunks.
pub fn read_faces(bytes: &[u8], what: &str, size: u32, triangles: u32, version: u16) -> Result<Vec<(u32, [u32; 3])>, ContainerError> {
    if let Some(start) = crate::topology::coded(bytes, what)? {
        return crate::topology::read_faces(bytes, start, what, size, triangles);
    }
    let mut c = Cursor::new(bytes, what);
    let m = c.count_within(triangles as u64, 4, "faces")?;
    let mut faces = Vec::with_capacity(m);
    let mut prev = None;
    let mut last = [0u32; 3];
    for _ in 0..m {
        let t = c.ascending(&mut prev, triangles, "triangle")?;
        let mut corners = [0u32; 3];
        for (i, x) in corners.iter_mut().enumerate() {
            *x = if version >= 5 { last[i].wrapping_add(unzigzag(c.get()?) as u32) } else { c.get()? };
            if *x >= size {
                return Err(c.corrupt(format!("corner {x} out of range (< {size})")));
            }
        }
        last = corners;
        faces.push((t, corners));
    }
    c.finish()?;
    Ok(faces)
}

/// Whether a triangle's corners are three different nodes: it is alive at their level.
#[inline]
fn alive(c: &[u32; 3]) -> bool {
    c[0] != c[1] && c[1] != c[2] && c[0] != c[2]
}

/// CORNERS band j from version 5: a count, then for each updated triangle t (ascending,
/// delta-coded), if t is alive at level j before the update (its corners as the reader holds
/// them, `before[t]`, are distinct), a mask 1..=7 of the corners that change (bit i: corner i)
/// and their new values, in corner order; otherwise its three new corners. A reader holds the
/// corners of every triangle alive at j exactly (they come with the keyframe and every change
/// to them is sent), so most updates, one corner of a living triangle moving to a neighbouring
/// node, cost a mask and one small difference. (Versions 3 and 4 code CORNERS as FACES.)
pub fn write_corner_updates(updates: &[(u32, [u32; 3])], before: &[[u32; 3]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(updates.len() * 4 + 2);
    put(&mut out, updates.len() as u32);
    let mut prev = None;
    for &(t, c) in updates {
        put_ascending(&mut out, &mut prev, t);
        match before.get(t as usize) {
            Some(b) if alive(b) => {
                let mask = (0..3).filter(|&i| c[i] != b[i]).fold(0u32, |m, i| m | 1 << i);
                put(&mut out, mask);
                for i in (0..3).filter(|&i| c[i] != b[i]) {
                    put(&mut out, zigzag(c[i].wrapping_sub(b[i]) as i32));
                }
            }
            _ => c.iter().for_each(|&x| put(&mut out, x)),
        }
    }
    out
}

/// Reads a version-5 CORNERS chunk against the corners the reader holds (`before`, one per
/// triangle): the updated triangles and their new corners.
pub fn read_corner_updates(bytes: &[u8], what: &str, size: u32, before: &[[u32; 3]]) -> Result<Vec<(u32, [u32; 3])>, ContainerError> {
    if let Some(start) = crate::topology::coded(bytes, what)? {
        return crate::topology::read_corner_updates(bytes, start, what, size, before);
    }
    let mut c = Cursor::new(bytes, what);
    let triangles = before.len() as u32;
    let m = c.count_within(triangles as u64, 2, "corner updates")?;
    let mut updates = Vec::with_capacity(m);
    let mut prev = None;
    for _ in 0..m {
        let t = c.ascending(&mut prev, triangles, "triangle")?;
        let mut corners = before[t as usize];
        if alive(&corners) {
            let mask = c.get()?;
            if !(1..=7).contains(&mask) {
                return Err(c.corrupt(format!("triangle {t}: corner mask {mask} (1 to 7)")));
            }
            for (i, x) in corners.iter_mut().enumerate() {
                if mask & (1 << i) != 0 {
                    *x = x.wrapping_add(unzigzag(c.get()?) as u32);
                    if *x >= size {
                        return Err(c.corrupt(format!("corner {x} out of range (< {size})")));
                    }
                }
            }
        } else {
            for x in corners.iter_mut() {
                *x = c.id(size, "corner")?;
            }
        }
        updates.push((t, corners));
    }
    c.finish()?;
    Ok(updates)
}

/// What a chunk payload takes in the file: zstd-compressed or as it is, whichever is shorter
/// (as `format::store_chunk` stores it with the *stored* flag).
fn stored_size(raw: &[u8]) -> usize {
    crate::format::compress(raw, crate::format::ZSTD_LEVEL).map_or(raw.len(), |z| z.len().min(raw.len()))
}

/// The FACES payload of band j (corners below `size`) in whichever coding stores shorter: the
/// varint coding of [`write_faces`] or the bit coding (coding 1, `topology`). The bit coding is
/// kept only when it reads back as the same faces.
pub fn write_faces_best(faces: &[(u32, [u32; 3])], size: u32, triangles: u32) -> Vec<u8> {
    let plain = write_faces(faces);
    let bits = crate::topology::write_faces(faces);
    let same = read_faces(&bits, "faces", size, triangles, crate::format::VERSION).is_ok_and(|f| f == faces);
    if same && bits.len() <= plain.len() && stored_size(&bits) < stored_size(&plain) { bits } else { plain }
}

/// The CORNERS payload of band j in whichever coding stores shorter: the varint coding of
/// [`write_corner_updates`] or the transitions of coding 1 (`topology`), kept only when they
/// read back as the same updates.
pub fn write_corner_updates_best(updates: &[(u32, [u32; 3])], before: &[[u32; 3]], size: u32) -> Vec<u8> {
    let plain = write_corner_updates(updates, before);
    if updates.is_empty() {
        return plain;
    }
    let bits = crate::topology::write_corner_updates(updates, before, size);
    let same = read_corner_updates(&bits, "corners", size, before).is_ok_and(|u| u == updates);
    if same && bits.len() <= plain.len() && stored_size(&bits) < stored_size(&plain) { bits } else { plain }
}

/// The KEY payload of band j (parents below `limit`) in whichever coding stores shorter: the
/// varint coding of [`write_key`] (version 7) or the bit coding (coding 1, `topology`).
/// With `first` (a keyframe after frame 0: frame 0's parents of the band), coding 3 too.
pub fn write_key_best(parent: &[u32], limit: u32, first: Option<&[u32]>) -> Vec<u8> {
    let plain = write_key(parent, crate::format::VERSION);
    if parent.is_empty() {
        return plain;
    }
    let bits = crate::topology::write_key(parent);
    let start = 2;
    let same = crate::topology::read_key(&bits, start, "key", parent.len() as u32, limit).is_ok_and(|p| p == parent);
    let best = if same && bits.len() <= plain.len() && stored_size(&bits) < stored_size(&plain) { bits } else { plain };
    match first.filter(|f| f.len() == parent.len()) {
        Some(first) => {
            let changes = write_key_changes(parent, first);
            let sizes = [parent.len() as u32, limit, 0];
            let same = read_key_from(&changes, "key", &sizes, 0, crate::format::VERSION, Some(first)).is_ok_and(|p| p == parent);
            if same && stored_size(&changes) < stored_size(&best) { changes } else { best }
        }
        None => best,
    }
}

/// KEY coding 3: the nodes whose parent differs from `first`'s (frame 0's), with their parents
/// here, as a Delta chunk's coding 1 codes moves, after the bytes `0 3`.
pub fn write_key_changes(parent: &[u32], first: &[u32]) -> Vec<u8> {
    let moves: Vec<(u32, u32)> =
        parent.iter().zip(first).enumerate().filter(|(_, (p, f))| p != f).map(|(v, (&p, _))| (v as u32, p)).collect();
    let mut out = crate::topology::write_delta(&moves);
    out[1] = KEY_FROM_FIRST;
    out
}

/// The DELTA payload of band j (nodes below `nodes`, parents below `parents`) in whichever
/// coding stores shorter: the varints of [`write_delta`] or the bit coding (coding 1).
pub fn write_delta_best(moves: &[(u32, u32)], nodes: u32, parents: u32) -> Vec<u8> {
    let plain = write_delta(moves);
    if moves.is_empty() {
        return plain;
    }
    let bits = crate::topology::write_delta(moves);
    let same = crate::topology::read_delta(&bits, 2, "delta", nodes, parents).is_ok_and(|m| m == moves);
    if same && bits.len() <= plain.len() && stored_size(&bits) < stored_size(&plain) { bits } else { plain }
}

/// DELTA band j: net parent changes of level-j nodes, a count then (node ascending and
/// delta-coded, new parent) pairs. Degenerate sets are not stored: decoders derive them.
pub fn write_delta(moves: &[(u32, u32)]) -> Vec<u8> {
    let mut out = Vec::with_capacity(moves.len() * 4 + 2);
    put(&mut out, moves.len() as u32);
    let mut prev = None;
    for &(v, to) in moves {
        put_ascending(&mut out, &mut prev, v);
        put(&mut out, to);
    }
    out
}

/// Reads what [`write_delta`] writes for `band`: at most `sizes[band]` moves, nodes strictly ascending, parents in level `band + 1`.
pub fn read_delta(bytes: &[u8], what: &str, sizes: &[u32], band: usize) -> Result<Vec<(u32, u32)>, ContainerError> {
    let top = sizes.len() - 1;
    if let Some(start) = crate::topology::coded(bytes, what)? {
        let (nodes, parents) = if band < top { (sizes[band], sizes[band + 1]) } else { (0, 0) };
        return crate::topology::read_delta(bytes, start, what, nodes, parents);
    }
    let mut c = Cursor::new(bytes, what);
    let n = c.count_within(if band < top { sizes[band] as u64 } else { 0 }, 2, "moves")?;
    let mut moves = Vec::with_capacity(n);
    let mut prev = None;
    for _ in 0..n {
        let v = c.ascending(&mut prev, sizes[band], "node")?;
        moves.push((v, c.id(sizes[band + 1], "parent")?));
    }
    c.finish()?;
    Ok(moves)
}

mod positions;
pub use positions::{MAX_SHIFT, read_positions, write_positions};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_and_zigzag_round_trip() {
        let mut out = Vec::new();
        let values = [0u32, 1, 127, 128, 16383, 16384, u32::MAX];
        for &v in &values {
            put(&mut out, v);
        }
        let mut c = Cursor::new(&out, "test");
        for &v in &values {
            assert_eq!(c.get().unwrap(), v);
        }
        c.finish().unwrap();
        for v in [0, 1, -1, i32::MAX, i32::MIN, 12345, -54321] {
            assert_eq!(unzigzag(zigzag(v)), v);
        }
        assert!(Cursor::new(&[0x80], "x").get().is_err());
        assert!(Cursor::new(&[0xff, 0xff, 0xff, 0xff, 0x7f], "x").get().is_err());
    }

    #[test]
    fn positions_round_trip() {
        let r: Vec<[i32; 3]> = (0..500i32).map(|i| [i % 7 - 3, (i * 37) % 101 - 50, if i % 50 == 0 { i32::MIN } else { 0 }]).collect();
        let bytes = write_positions(3, &r);
        assert_eq!(read_positions(&bytes, "t", 500).unwrap(), (3, r.clone()));
        // A small band is stored as varints when that is smaller; it reads back the same.
        let small = &r[..20];
        let plain = write_positions(2, small);
        assert_eq!(plain[0], 2 + 32, "varint coding chosen for 20 nodes");
        assert_eq!(read_positions(&plain, "t", 20).unwrap(), (2, small.to_vec()));
        assert!(read_positions(&plain, "t", 21).is_err());
        let mut bad = plain.clone();
        bad[0] = 2 + 96;
        assert!(read_positions(&bad, "t", 20).unwrap_err().to_string().contains("residual coding 3"));
        assert!(read_positions(&bytes, "t", 499).is_err());
        assert!(read_positions(&bytes[..bytes.len() - 1], "t", 500).is_err());
    }

    #[test]
    fn zero_heavy_bands_are_listed_sparsely() {
        // A band of zeros, small or large: the coding, the shift and a count of none.
        for n in [7usize, 300, 5000] {
            let zeros = vec![[0i32; 3]; n];
            let bytes = write_positions(4, &zeros);
            assert_eq!(bytes, [4 + 64, 0], "{n} nodes");
            assert_eq!(read_positions(&bytes, "t", n as u32).unwrap(), (4, zeros));
        }
        // One node in 50 missed (the first, some inside, the last): listed after their gaps.
        let n: i32 = 5000;
        let r: Vec<[i32; 3]> = (0..n).map(|i| if i % 50 == 0 || i == n - 1 { [i % 7 - 3, -i, 1] } else { [0; 3] }).collect();
        let bytes = write_positions(1, &r);
        assert_eq!(bytes[0], 1 + 64, "sparse coding chosen");
        assert!(bytes.len() < 101 * 7, "{} bytes", bytes.len());
        assert_eq!(read_positions(&bytes, "t", n as u32).unwrap(), (1, r.clone()));
        // Damage: a listed node beyond the band, more listed nodes than bytes, bytes left over.
        let e = read_positions(&bytes, "band 3 positions", 4999).unwrap_err().to_string();
        assert!(e.contains("band 3 positions") && e.contains("listed node 4999 beyond the band's 4999"), "{e}");
        let e = read_positions(&[64, 9, 0, 0, 0, 0], "t", 20).unwrap_err().to_string();
        assert!(e.contains("9 listed nodes in 4 bytes"), "{e}");
        assert!(read_positions(&[64, 0, 0], "t", 20).unwrap_err().to_string().contains("left over"));
        // A dense band keeps rANS: listing every node costs more.
        let dense: Vec<[i32; 3]> = (0..3000).map(|i| [i % 5 - 2, 1, (i % 3) - 1]).collect();
        assert_eq!(write_positions(0, &dense)[0], 0, "rANS for a dense band");
    }

    #[test]
    fn triangles_round_trip_in_either_coding() {
        let tris = vec![[0, 1, 7], [1, 8, 7], [1, 2, 8], [6, 0, 5]];
        for version in [6, 7] {
            let bytes = write_triangles(&tris, version);
            assert_eq!(read_triangles(&bytes, "t", 4, 9, version).unwrap(), tris, "version {version}");
            let e = read_triangles(&bytes, "t", 4, 8, version).unwrap_err().to_string();
            assert!(e.contains("vertex 8 out of range"), "{e}");
            assert!(read_triangles(&bytes, "t", 3, 9, version).is_err());
            assert!(read_triangles(&bytes[..bytes.len() - 1], "t", 4, 9, version).is_err());
        }
        // Differences: the second triangle's corners are 1, 7, 0 from the first's.
        assert_eq!(write_triangles(&tris, 7)[..7], [4, 0, 2, 14, 2, 14, 0]);
        assert_eq!(write_triangles(&tris, 6)[..4], [4, 0, 1, 7]);
    }

    #[test]
    fn delta_faces_and_key_round_trip() {
        let moves = vec![(0, 3), (5, 1), (6, 0)];
        let bytes = write_delta(&moves);
        assert_eq!(read_delta(&bytes, "t", &[10, 4, 1], 0).unwrap(), moves);
        // Out-of-range parent is an error naming it.
        let e = read_delta(&bytes, "t", &[10, 2, 1], 0).unwrap_err().to_string();
        assert!(e.contains("parent 3 out of range"), "{e}");
        let faces = vec![(1, [0, 1, 2]), (9, [3, 4, 3])];
        let bytes = write_faces(&faces);
        assert_eq!(read_faces(&bytes, "t", 5, 10, 5).unwrap(), faces);
        let e = read_faces(&bytes, "t", 4, 10, 5).unwrap_err().to_string();
        assert!(e.contains("corner 4 out of range"), "{e}");
        assert!(read_faces(&bytes, "t", 5, 9, 5).is_err());
        // Corner updates against what the reader holds: triangle 1 alive (one corner moves),
        // triangle 2 not alive (all three sent); a reader holding other corners reads others.
        let before = vec![[0, 1, 2], [0, 1, 2], [3, 3, 4], [0, 0, 0]];
        let updates = vec![(1, [0, 4, 2]), (2, [3, 1, 4])];
        let bytes = write_corner_updates(&updates, &before);
        assert_eq!(read_corner_updates(&bytes, "t", 5, &before).unwrap(), updates);
        let e = read_corner_updates(&bytes, "t", 4, &before).unwrap_err().to_string();
        assert!(e.contains("corner 4 out of range"), "{e}");
        assert!(read_corner_updates(&bytes, "t", 5, &before[..2]).is_err());
        // A mask of no corner is refused by name.
        let e = read_corner_updates(&[1, 1, 0], "t", 5, &before).unwrap_err().to_string();
        assert!(e.contains("corner mask 0"), "{e}");
        let parent = vec![0, 1, 1, 0];
        for version in [6, 7] {
            assert_eq!(read_key(&write_key(&parent, version), "t", &[4, 2, 1], 0, version).unwrap(), parent);
            let e = read_key(&write_key(&parent, version), "t", &[4, 1], 0, version).unwrap_err().to_string();
            assert!(e.contains("parent 1 out of range"), "{e}");
        }
        // Differences from the node before's: 0, +1, 0, -1.
        assert_eq!(write_key(&parent, 7), [4, 0, 2, 0, 1]);
    }
}
