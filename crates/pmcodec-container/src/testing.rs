//! Test support (cargo feature `test-support`, off in production builds): take a container
//! apart into its decompressed pieces, damage the pieces, and seal them again with every
//! checksum, length and offset recomputed. Damage made this way passes the CRCs, so it reaches
//! what a byte flip never does: the header and index parsers, the payload readers, rANS, the
//! predictors and the replay. The fuzz target `fuzz/fuzz_targets/resealed.rs`, the seeded
//! property test `tests/resealed.rs` and the regression corpus all use it.

use crate::format::{ChunkEntry, ChunkKind, Header, Index, MAGIC, PREAMBLE_LEN, Preamble};
use crate::{ContainerError, CutTarget, Decoder, Distance, Reader, verify};

/// A container taken apart: the header's postcard bytes, and the chunks decompressed, in file
/// order. [`Unsealed::seal`] lays them out again.
#[derive(Clone, Debug)]
pub struct Unsealed {
    /// The preamble's version, written back as is (it decides how the header parses).
    pub version: u16,
    /// The preamble's flags, written back as is; they also decide how chunks are stored on sealing.
    pub flags: u16,
    /// The header as postcard bytes (what the preamble's `header_len` counts).
    pub header: Vec<u8>,
    /// The chunks, in file order; sealing lays them out in this order.
    pub chunks: Vec<Chunk>,
    /// Bytes after the last chunk (none in a valid file).
    pub trailing: Vec<u8>,
}

/// One chunk: its index entry and its decompressed payload.
#[derive(Clone, Debug)]
pub struct Chunk {
    /// Kind, frame and band are written as they are; offset, lengths and CRC are recomputed
    /// on sealing unless `lie` says otherwise.
    pub entry: ChunkEntry,
    /// The decompressed payload; sealing compresses it again (zstd level 1, or stored).
    pub raw: Vec<u8>,
    /// An index field to write as given instead of the true value (the CRC then covers
    /// whatever bytes the entry points at, so the lie still passes the checksum).
    pub lie: Option<Lie>,
}

/// A false index field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lie {
    /// The entry's `offset`.
    Offset(u64),
    /// The entry's `stored_len`.
    StoredLen(u32),
    /// The entry's `raw_len`.
    RawLen(u32),
}

/// Most bytes a chunk is decompressed to while taking a file apart: a damaged input may
/// declare anything.
const UNSEAL_LIMIT: usize = 16 << 20;

impl Unsealed {
    /// Takes a file apart. Lenient: it needs the magic, a readable preamble and a postcard
    /// index; a chunk it cannot read or decompress becomes an empty one.
    pub fn open(bytes: &[u8]) -> Result<Unsealed, String> {
        if bytes.len() < PREAMBLE_LEN || bytes[..8] != MAGIC {
            return Err("not a container".into());
        }
        let u16_at = |i: usize| u16::from_le_bytes([bytes[i], bytes[i + 1]]);
        let u32_at = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]) as usize;
        let (version, flags, header_len, index_len) = (u16_at(8), u16_at(10), u32_at(12), u32_at(16));
        let data_start = PREAMBLE_LEN + header_len + index_len;
        if data_start > bytes.len() {
            return Err("header and index beyond the file".into());
        }
        let header = bytes[PREAMBLE_LEN..PREAMBLE_LEN + header_len].to_vec();
        // Version 7's index is laid out by the header's frames.
        let parsed = Header::from_bytes(&bytes[PREAMBLE_LEN..PREAMBLE_LEN + header_len], version).ok();
        let (frames, levels) = parsed.map_or((0, 1), |h| (h.frame_count, h.levels()));
        let table_len = u32_at(28) as u32;
        let index = Index::from_file(&bytes[PREAMBLE_LEN + header_len..data_start], version, flags, table_len, frames, levels)
            .map_err(|e| e.to_string())?;
        let area = &bytes[data_start..];
        let mut end = 0usize;
        let mut chunks = Vec::with_capacity(index.chunks.len());
        for e in index.chunks {
            let range = usize::try_from(e.offset).ok().and_then(|o| Some(o..o.checked_add(e.stored_len as usize)?));
            let stored = range.and_then(|r| {
                end = end.max(r.end);
                area.get(r)
            });
            let raw = match stored {
                Some(s) if flags & crate::format::FLAG_STORED != 0 && e.stored_len == e.raw_len => s.to_vec(),
                _ => stored.and_then(|s| zstd::bulk::decompress(s, UNSEAL_LIMIT.min(e.raw_len as usize)).ok()).unwrap_or_default(),
            };
            chunks.push(Chunk { entry: e, raw, lie: None });
        }
        let trailing = area.get(end..).unwrap_or_default().to_vec();
        Ok(Unsealed { version, flags, header, chunks, trailing })
    }

    /// The file: chunks compressed and laid out in order, the index's offsets, lengths and
    /// CRCs made true (but for lies), the preamble's lengths and CRCs likewise.
    pub fn seal(&self) -> Vec<u8> {
        let mut area = Vec::new();
        let mut entries = Vec::with_capacity(self.chunks.len());
        let levels = self.parsed_header().map_or(1, |h| h.levels());
        let made: Vec<ChunkEntry> = self.chunks.iter().map(|c| c.entry).collect();
        let order = crate::format::file_order(&made, self.flags, levels);
        let chunks: Vec<&Chunk> = order.iter().filter_map(|&i| self.chunks.get(i)).collect();
        for c in &chunks {
            // Level 1 keeps sealing fast; the reader does not care how well a chunk compresses.
            let stored = crate::format::store_chunk(&c.raw, 1, self.flags).unwrap_or_default();
            let mut e = c.entry;
            e.offset = area.len() as u64;
            e.stored_len = stored.len() as u32;
            e.raw_len = c.raw.len() as u32;
            area.extend_from_slice(&stored);
            entries.push(e);
        }
        for (e, c) in entries.iter_mut().zip(&chunks) {
            match c.lie {
                Some(Lie::Offset(o)) => e.offset = o,
                Some(Lie::StoredLen(n)) => e.stored_len = n,
                Some(Lie::RawLen(n)) => e.raw_len = n,
                None => {}
            }
            let covered = usize::try_from(e.offset).ok().and_then(|o| area.get(o..o.checked_add(e.stored_len as usize)?));
            e.crc32 = covered.map_or(0, crc32fast::hash);
        }
        // A version 7 index cannot state an offset (chunks follow one another): an offset lie
        // is lost there, while a stored length lie moves every chunk after it.
        // A version 7 index has a count for every frame the header declares: a damaged count
        // (up to 2^32) would make it gigabytes, for a header the reader refuses before it
        // reads the index anyway.
        let frames = self.parsed_header().map_or(0, |h| h.frame_count.min(crate::format::MAX_FRAMES));
        let (index, table_len) = if self.version >= 7 && self.flags & crate::format::FLAG_BANDS != 0 {
            crate::format::banded_index(&entries, levels).unwrap_or_default()
        } else {
            (Index { chunks: entries }.to_bytes(self.version, frames).unwrap_or_default(), 0)
        };
        let covered = index.get(..table_len as usize).filter(|_| table_len > 0).unwrap_or(&index);
        let pre = Preamble {
            version: self.version,
            flags: self.flags,
            header_len: self.header.len() as u32,
            index_len: index.len() as u32,
            header_crc: crc32fast::hash(&self.header),
            index_crc: crc32fast::hash(covered),
            table_len,
        };
        let mut out = Vec::with_capacity(PREAMBLE_LEN + self.header.len() + index.len() + area.len() + self.trailing.len());
        out.extend_from_slice(&pre.to_bytes());
        out.extend_from_slice(&self.header);
        out.extend_from_slice(&index);
        out.extend_from_slice(&area);
        out.extend_from_slice(&self.trailing);
        out
    }

    /// The header, if it still parses.
    pub fn parsed_header(&self) -> Option<Header> {
        Header::from_bytes(&self.header, self.version).ok()
    }

    /// Replaces the header by `h`, serialized for this file's version.
    pub fn set_header(&mut self, h: &Header) {
        let Ok(mut b) = postcard::to_allocvec(h) else { return };
        // Versions 3 and 4 end before `order` (and 3 before `motion`), one byte each.
        let missing = match self.version {
            v if v >= 5 => 0,
            4 => 1,
            _ => 2,
        };
        b.truncate(b.len().saturating_sub(missing));
        self.header = b;
    }
}

/// Takes `bytes` apart, lets `mutate` change the pieces, and seals them again.
pub fn reseal(bytes: &[u8], mutate: impl FnOnce(&mut Unsealed)) -> Result<Vec<u8>, String> {
    let mut u = Unsealed::open(bytes)?;
    mutate(&mut u);
    Ok(u.seal())
}

/// A small deterministic generator (SplitMix64, Steele, Lea & Flood, *Fast splittable
/// pseudorandom number generators*, 2014): mutations must replay from a seed.
#[derive(Clone, Debug)]
pub struct Rng(pmcodec_eval::SplitMix64);

impl Rng {
    /// A generator whose sequence is fixed by `seed`.
    pub fn new(seed: u64) -> Rng {
        Rng(pmcodec_eval::SplitMix64::new(seed))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `0..n` (0 when n is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next_u64() % n as u64) as usize }
    }

    /// True about once in `one_in` calls (always for 0 and 1).
    pub fn chance(&mut self, one_in: usize) -> bool {
        self.below(one_in) == 0
    }
}

/// Start and end of every varint in `b` (a run of bytes with the high bit set and one without;
/// an unterminated tail counts as one). Payloads are varints but for the rANS stream of a
/// positions chunk, whose bytes then split into arbitrary "varints": harmless.
fn varints(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &x) in b.iter().enumerate() {
        if x & 0x80 == 0 {
            out.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < b.len() {
        out.push((start, b.len()));
    }
    out
}

fn varint(v: u64) -> Vec<u8> {
    let mut out = Vec::new();
    let mut v = v;
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
    out
}

fn read_varint(b: &[u8]) -> u64 {
    b.iter().take(10).enumerate().fold(0u64, |v, (i, &x)| v | (((x & 0x7f) as u64) << (7 * i)))
}

/// A replacement for a number: near it, a boundary, or one of the header's sizes (counts and
/// ids that are off by one, or just fit, are where readers go wrong).
fn new_value(rng: &mut Rng, v: u64, sizes: &[u64]) -> u64 {
    match rng.below(12) {
        0 => 0,
        1 => v.wrapping_add(1),
        2 => v.wrapping_sub(1) & 0xFFFF_FFFF,
        3 => u32::MAX as u64,
        4 => 0x7FFF_FFFF,
        5 => v.wrapping_mul(2) & 0xFFFF_FFFF,
        6 => 1 << rng.below(32),
        7 => rng.next_u64() & 0xFFFF_FFFF,
        // Beyond 32 bits: readers must refuse, not wrap.
        8 => (1u64 << 32) + rng.below(1 << 20) as u64,
        9 => v ^ (1 << rng.below(32)),
        _ => {
            let s = sizes.get(rng.below(sizes.len())).copied().unwrap_or(1);
            match rng.below(3) {
                0 => s,
                1 => s.saturating_sub(1),
                _ => s + 1,
            }
        }
    }
}

/// One damage to a byte string made of varints: a number replaced, removed, inserted,
/// duplicated or swapped, bytes flipped, inserted, removed or cut off.
fn mutate_bytes(rng: &mut Rng, b: &mut Vec<u8>, sizes: &[u64]) {
    let vs = varints(b);
    match rng.below(10) {
        0..=3 if !vs.is_empty() => {
            let (s, e) = vs[rng.below(vs.len())];
            let v = new_value(rng, read_varint(&b[s..e]), sizes);
            b.splice(s..e, varint(v));
        }
        4 if !vs.is_empty() => {
            let (s, e) = vs[rng.below(vs.len())];
            b.drain(s..e);
        }
        5 => {
            let at = vs.get(rng.below(vs.len() + 1)).map_or(b.len(), |v| v.0);
            let v = new_value(rng, 0, sizes);
            b.splice(at..at, varint(v));
        }
        6 if vs.len() >= 2 => {
            let (i, j) = (rng.below(vs.len()), rng.below(vs.len()));
            let (a, c) = (vs[i.min(j)], vs[i.max(j)]);
            if a != c {
                let (x, y) = (b[a.0..a.1].to_vec(), b[c.0..c.1].to_vec());
                b.splice(c.0..c.1, x);
                b.splice(a.0..a.1, y);
            }
        }
        7 if !b.is_empty() => {
            let at = rng.below(b.len());
            b[at] ^= 1 << rng.below(8);
        }
        8 if !b.is_empty() => {
            let at = rng.below(b.len());
            let len = 1 + rng.below((b.len() - at).min(16));
            if rng.chance(2) {
                b.drain(at..at + len);
            } else {
                let copy = b[at..at + len].to_vec();
                b.splice(at..at, copy);
            }
        }
        _ => {
            if !b.is_empty() && rng.chance(2) {
                b.truncate(rng.below(b.len()));
            } else {
                let extra: Vec<u8> = (0..1 + rng.below(8)).map(|_| rng.next_u64() as u8).collect();
                b.extend_from_slice(&extra);
            }
        }
    }
}

/// One structured change to a header: a size, count or setting set to a value readers must
/// refuse or survive.
fn mutate_header(rng: &mut Rng, h: &mut Header) {
    let big = |rng: &mut Rng| -> u32 {
        match rng.below(4) {
            0 => u32::MAX,
            1 => 1 << (20 + rng.below(12)),
            2 => rng.next_u64() as u32,
            _ => 0,
        }
    };
    let near = |rng: &mut Rng, v: u32| -> u32 {
        match rng.below(3) {
            0 => v.wrapping_add(1),
            1 => v.wrapping_sub(1),
            _ => v.wrapping_mul(2),
        }
    };
    match rng.below(14) {
        0 => h.vertex_count = if rng.chance(2) { big(rng) } else { near(rng, h.vertex_count) },
        1 => h.triangle_count = if rng.chance(2) { big(rng) } else { near(rng, h.triangle_count) },
        2 => h.frame_count = if rng.chance(2) { big(rng) } else { near(rng, h.frame_count) },
        3 => {
            let n = h.level_sizes.len();
            if n > 0 {
                let i = rng.below(n);
                h.level_sizes[i] = if rng.chance(2) { big(rng) } else { near(rng, h.level_sizes[i]) };
                if i == 0 && rng.chance(2) {
                    h.vertex_count = h.level_sizes[0];
                }
            }
        }
        4 => {
            if rng.chance(2) {
                h.level_sizes.pop();
            } else {
                let last = h.level_sizes.last().copied().unwrap_or(1);
                h.level_sizes.push(if rng.chance(2) { last } else { 1 });
            }
        }
        5 => h.keyframe_interval = [0, 1, 2, 3, h.frame_count, u32::MAX][rng.below(6)],
        6 => h.frame_rate = [0.0, -1.0, f32::NAN, f32::INFINITY, 1e-30, 1e30][rng.below(6)],
        7 => h.quantization.step = [0.0, -1.0, f32::NAN, f32::INFINITY, 1e-30, 1e30, f32::MIN_POSITIVE][rng.below(7)],
        8 => {
            let v = [f32::NAN, f32::INFINITY, -1e30, 1e30, 0.0][rng.below(5)];
            let i = rng.below(3);
            if rng.chance(2) { h.bbox_min[i] = v } else { h.bbox_max[i] = v }
        }
        9 => h.motion = [crate::Motion::Mean, crate::Motion::Affine, crate::Motion::KeyframeAffine][rng.below(3)],
        10 => h.order = [crate::VertexOrder::Input, crate::VertexOrder::BreadthFirst][rng.below(2)],
        11 => h.branching = big(rng),
        // As many names as frames, or a few more (not more than a few hundred: the count may
        // have been damaged already).
        12 => h.frame_names = (0..rng.below(4) as u32 + h.frame_count.min(256)).map(|i| format!("f{i}")).collect(),
        _ => h.level_sizes.reverse(),
    }
}

/// The numbers damage is drawn towards: the header's counts and level sizes.
fn interesting_sizes(u: &Unsealed) -> Vec<u64> {
    let mut s = vec![0, 1, 2, 3, 31, 32, 4096];
    if let Some(h) = u.parsed_header() {
        s.extend([h.vertex_count as u64, h.triangle_count as u64, h.frame_count as u64]);
        s.extend(h.level_sizes.iter().map(|&x| x as u64));
    }
    s
}

/// One damage that keeps a payload well formed: the chunk is parsed with the payload readers,
/// one of its values is changed to another that is in range (a parent, a move, a corner, a
/// triangle's vertex, a residual, extreme ones included), and it is written back with the
/// payload writers. Such files get past every parser to the replay and the predictors, which
/// must then refuse what the values break (an empty cluster, a degenerate triangle, a
/// prediction that overflows) or decode it. `false` if the chunk did not parse.
pub fn mutate_semantic(u: &mut Unsealed, rng: &mut Rng) -> bool {
    use crate::payload;
    let (Some(h), false) = (u.parsed_header(), u.chunks.is_empty()) else { return false };
    // A header the reader refuses stops it before any chunk, and its sizes (damaged by an
    // earlier step, up to 2^32) would have the payload writers below write gigabytes: a Key
    // chunk in coding 3 reads back as a parent for each of the level's declared nodes.
    if crate::read::check_header(&h).is_err() {
        return false;
    }
    let sizes = &h.level_sizes;
    let i = rng.below(u.chunks.len());
    let (e, raw) = (u.chunks[i].entry, &u.chunks[i].raw);
    let j = e.band as usize;
    let (Some(&n), top) = (sizes.get(j), j + 1 >= sizes.len()) else { return false };
    let above = sizes.get(j + 1).copied().unwrap_or(0);
    let out = match e.kind {
        ChunkKind::Triangles => {
            let Ok(mut t) = payload::read_triangles(raw, "t", h.triangle_count, h.vertex_count, u.version) else { return false };
            if t.is_empty() {
                return false;
            }
            let k = rng.below(t.len());
            let c = rng.below(3);
            // Another vertex, or a corner repeated (a degenerate input triangle).
            t[k][c] = if rng.chance(2) { rng.below(h.vertex_count as usize) as u32 } else { t[k][(c + 1) % 3] };
            payload::write_triangles(&t, u.version)
        }
        ChunkKind::Key if !top => {
            let Ok(mut p) = payload::read_key(raw, "t", sizes, j, u.version) else { return false };
            if p.is_empty() || above == 0 {
                return false;
            }
            let k = rng.below(p.len());
            p[k] = if rng.chance(2) { rng.below(above as usize) as u32 } else { p[rng.below(p.len())] };
            if rng.chance(4) {
                // Every node under one parent: all other clusters empty.
                let to = p[k];
                p.iter_mut().for_each(|x| *x = to);
            }
            payload::write_key(&p, u.version)
        }
        ChunkKind::Delta if !top && above > 0 => {
            let Ok(mut m) = payload::read_delta(raw, "t", sizes, j) else { return false };
            match rng.below(3) {
                0 if !m.is_empty() => {
                    let k = rng.below(m.len());
                    m[k].1 = rng.below(above as usize) as u32;
                }
                1 if !m.is_empty() => {
                    m.remove(rng.below(m.len()));
                }
                _ => {
                    let v = rng.below(n as usize) as u32;
                    m.retain(|x| x.0 != v);
                    m.push((v, rng.below(above as usize) as u32));
                    m.sort_unstable();
                }
            }
            payload::write_delta(&m)
        }
        ChunkKind::Positions => {
            let Ok((shift, mut r)) = payload::read_positions(raw, "t", n) else { return false };
            if r.is_empty() {
                return false;
            }
            let k = rng.below(r.len());
            let a = rng.below(3);
            r[k][a] = [i32::MIN, i32::MAX, -1, 1 << 30, r[k][a].wrapping_neg(), rng.next_u64() as i32][rng.below(6)];
            if rng.chance(4) {
                // A whole band far off: sums of many extreme values.
                let v = r[k][a];
                r.iter_mut().for_each(|x| x[a] = v);
            }
            let shift = if rng.chance(4) { rng.below(crate::payload::MAX_SHIFT as usize + 1) as u32 } else { shift };
            payload::write_positions(shift, &r)
        }
        ChunkKind::Faces if u.version >= 5 && n > 0 => {
            let Ok(mut f) = payload::read_faces(raw, "t", n, h.triangle_count, u.version) else { return false };
            match rng.below(3) {
                0 if !f.is_empty() => {
                    let k = rng.below(f.len());
                    let c = rng.below(3);
                    f[k].1[c] = if rng.chance(2) { rng.below(n as usize) as u32 } else { f[k].1[(c + 1) % 3] };
                }
                1 if !f.is_empty() => {
                    f.remove(rng.below(f.len()));
                }
                _ => {
                    let t = rng.below(h.triangle_count.max(1) as usize) as u32;
                    f.retain(|x| x.0 != t);
                    f.push((t, [0, 1, 2].map(|_| rng.below(n as usize) as u32)));
                    f.sort_unstable();
                }
            }
            payload::write_faces(&f)
        }
        _ => return false,
    };
    u.chunks[i].raw = out;
    true
}

/// Applies one to four random structural damages to `u`: most to chunk payloads (numbers and
/// bytes, or values changed within range and the payload rewritten), the rest to the header (fields or bytes), the index (entries reordered, dropped,
/// duplicated, relabelled, payloads swapped, a field that lies) and the file (version, trailing
/// bytes, a second container appended).
pub fn mutate(u: &mut Unsealed, rng: &mut Rng) {
    for _ in 0..1 + rng.below(4) {
        mutate_once(u, rng);
    }
}

fn mutate_once(u: &mut Unsealed, rng: &mut Rng) {
    let sizes = interesting_sizes(u);
    let n = u.chunks.len();
    match rng.below(24) {
        20..=23 if mutate_semantic(u, rng) => {}
        0..=9 if n > 0 => {
            let i = rng.below(n);
            mutate_bytes(rng, &mut u.chunks[i].raw, &sizes);
        }
        10..=12 => match u.parsed_header() {
            Some(mut h) if !rng.chance(3) => {
                mutate_header(rng, &mut h);
                u.set_header(&h);
            }
            _ => mutate_bytes(rng, &mut u.header, &sizes),
        },
        13 if n >= 2 => {
            let (i, j) = (rng.below(n), rng.below(n));
            if rng.chance(2) {
                u.chunks.swap(i, j);
            } else {
                // Payloads swapped, entries kept: a chunk of another frame or band, or kind.
                let r = std::mem::take(&mut u.chunks[i].raw);
                u.chunks[i].raw = std::mem::replace(&mut u.chunks[j].raw, r);
            }
        }
        14 if n > 0 => {
            let i = rng.below(n);
            if rng.chance(2) {
                u.chunks.remove(i);
            } else {
                let c = u.chunks[i].clone();
                u.chunks.insert(rng.below(n + 1), c);
            }
        }
        15 if n > 0 => {
            let i = rng.below(n);
            let e = &mut u.chunks[i].entry;
            match rng.below(3) {
                0 => {
                    e.kind =
                        [ChunkKind::Triangles, ChunkKind::Key, ChunkKind::Delta, ChunkKind::Positions, ChunkKind::Faces, ChunkKind::Corners]
                            [rng.below(6)]
                }
                1 => e.frame = new_value(rng, e.frame as u64, &sizes) as u32,
                _ => e.band = new_value(rng, e.band as u64, &sizes) as u32,
            }
        }
        16 if n > 0 => {
            let i = rng.below(n);
            let len = u.chunks[i].raw.len() as u64;
            u.chunks[i].lie = Some(match rng.below(3) {
                0 => Lie::Offset(new_value(rng, 0, &sizes)),
                1 => Lie::StoredLen(new_value(rng, len / 2, &sizes) as u32),
                _ => Lie::RawLen(new_value(rng, len, &sizes) as u32),
            });
        }
        17 => u.version = [3, 4, 5][rng.below(3)],
        18 => {
            if rng.chance(2) {
                u.trailing.extend((0..1 + rng.below(64)).map(|_| rng.next_u64() as u8));
            } else {
                let copy = u.seal();
                u.trailing.extend_from_slice(&copy);
            }
        }
        _ => u.flags = rng.next_u64() as u16,
    }
}

/// Everything a client does with a file: open it, verify it, and decode every frame at full
/// resolution, at level 1 (which reads the faces and corners chunks a full client skips) and at
/// the top level, cutting meshes at a triangle budget, a vertex budget, an error bound and a
/// level (with their appearance, when the file has one), then seeking back and forth with kept keyframes. The first error is returned.
pub fn exercise(bytes: &[u8]) -> Result<(), ContainerError> {
    let reader = Reader::open(bytes)?;
    verify(&reader)?;
    let h = reader.header();
    let mut levels = vec![0, 1, h.top()];
    levels.dedup();
    for level in levels.into_iter().filter(|&l| l < h.levels()) {
        let mut d = Decoder::new(reader.borrowed(), level)?;
        for f in 0..h.frame_count {
            d.seek(f)?;
        }
        for target in [
            CutTarget::Triangles(50),
            CutTarget::Vertices(20),
            CutTarget::MaxError(Distance::DiagonalFraction(0.01)),
            CutTarget::Level(level),
        ] {
            d.mesh(target)?;
            if h.appearance.is_some() {
                d.textured_mesh(target)?;
            }
        }
        // Seeks back and forth through kept keyframes (as a server does), and the cut's
        // triangles by node (as the eval tool does).
        d.keep_keyframes(2);
        let last = h.frame_count - 1;
        for f in [0, last / 2, last, 0] {
            let _ = d.chunks_for(f);
            d.seek(f)?;
        }
        d.mesh(CutTarget::Triangles(30))?;
        d.cut_triangles(CutTarget::Vertices(15))?;
    }
    Ok(())
}

/// Keeps an input that failed a fuzzing run as `OUT/KIND-NAME` and says so on stderr, with
/// what it did (a panic's message, or how long it took): the stable-Rust fuzzing examples'
/// record of what to add to the regression corpus.
pub fn keep_failure(out: &std::path::Path, kind: &str, name: &str, bytes: &[u8], what: &str) {
    let path = out.join(format!("{kind}-{name}"));
    match std::fs::write(&path, bytes) {
        Ok(()) => eprintln!("{} {name}: {what} -> {}", kind.to_uppercase(), path.display()),
        Err(e) => eprintln!("{} {name}: {what} (not kept: {}: {e})", kind.to_uppercase(), path.display()),
    }
}

/// The message a panic carried (`catch_unwind`'s payload), or "" when it is not text.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload.downcast_ref::<String>().cloned().or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default()
}

/// Whether an error is one that stops at the outer checks (magic, version, checksums): what
/// resealed damage is meant to get past.
pub fn stopped_at_the_door(e: &ContainerError) -> bool {
    matches!(e, ContainerError::BadMagic | ContainerError::UnsupportedVersion(_) | ContainerError::Checksum { .. })
}

/// The variant of an error, by name: what the regression corpus records per file.
pub fn variant(e: &ContainerError) -> &'static str {
    match e {
        ContainerError::Io(_) => "Io",
        ContainerError::BadMagic => "BadMagic",
        ContainerError::UnsupportedVersion(_) => "UnsupportedVersion",
        ContainerError::Truncated { .. } => "Truncated",
        ContainerError::Checksum { .. } => "Checksum",
        ContainerError::Corrupt { .. } => "Corrupt",
        ContainerError::Mesh(_) => "Mesh",
        ContainerError::Build(_) => "Build",
        ContainerError::Delta { .. } => "Delta",
        ContainerError::Options(_) => "Options",
        ContainerError::TrailingBytes { .. } => "TrailingBytes",
        ContainerError::NoSuchFrame { .. } => "NoSuchFrame",
        ContainerError::Cancelled => "Cancelled",
    }
}

/// What [`exercise`] makes of a file: `ok`, or the variant of its error.
pub fn outcome(bytes: &[u8]) -> &'static str {
    match exercise(bytes) {
        Ok(()) => "ok",
        Err(e) => variant(&e),
    }
}

/// The most bytes opening, verifying and decoding a file may allocate (proto/container.md,
/// "Limits"): per declared node, triangle and frame, per byte of the largest chunk (stored and
/// decompressed, with the payload parsed), per byte of the file (its tables parsed), and a
/// constant. `tests/memory.rs` and the fuzz target hold the decoder to it.
pub fn allocation_bound<S: crate::ByteSource>(reader: &Reader<S>) -> usize {
    let h = reader.header();
    let largest = reader.index().chunks.iter().map(|e| e.raw_len as u64 + e.stored_len as u64).max().unwrap_or(0);
    let declared = h.node_count() as usize + h.triangle_count as usize + h.frame_count as usize;
    BYTES_PER_ELEMENT * declared + BYTES_PER_CHUNK_BYTE * largest as usize + BYTES_PER_FILE_BYTE * reader.file_len() as usize + SLACK
}

/// What a file that does not open may allocate: its tables, parsed.
pub fn allocation_bound_unopened(file_len: usize) -> usize {
    BYTES_PER_FILE_BYTE * file_len + SLACK
}

const BYTES_PER_ELEMENT: usize = 1024;
const BYTES_PER_CHUNK_BYTE: usize = 16;
const BYTES_PER_FILE_BYTE: usize = 16;
const SLACK: usize = 1 << 20;
