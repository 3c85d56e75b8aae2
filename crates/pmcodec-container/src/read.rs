//! Reading: a [`ByteSource`] gives bytes at offsets (a slice, a file, an HTTP range client);
//! the [`Reader`] checks the preamble, header and index once, then fetches, verifies and
//! decompresses chunks on demand.

use crate::ContainerError;
use crate::format::{
    ChunkEntry, ChunkKind, Header, Index, MAX_FRAMES, MAX_LEVELS, MAX_NODES, MAX_TRIANGLES, MAX_VERTICES, PREAMBLE_LEN, Preamble,
};
use std::cell::Cell;
use std::path::Path;

/// Where the bytes of a file come from.
// `len` is fallible (a remote source may not answer), and an empty source is simply a file
// too short to open: an `is_empty` would add nothing.
#[allow(clippy::len_without_is_empty)]
pub trait ByteSource {
    /// Total length in bytes.
    fn len(&self) -> Result<u64, ContainerError>;
    /// Exactly `len` bytes at `offset` (an error if the source is shorter).
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError>;
}

impl ByteSource for [u8] {
    fn len(&self) -> Result<u64, ContainerError> {
        Ok(<[u8]>::len(self) as u64)
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        let start = usize::try_from(offset).map_err(|_| ContainerError::Io("offset beyond memory".into()))?;
        let end = start.checked_add(len).ok_or_else(|| ContainerError::Io("length overflow".into()))?;
        self.get(start..end)
            .map(<[u8]>::to_vec)
            .ok_or_else(|| ContainerError::Io(format!("read of {len} bytes at {offset} beyond the end")))
    }
}

impl ByteSource for Vec<u8> {
    fn len(&self) -> Result<u64, ContainerError> {
        Ok(self.as_slice().len() as u64)
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        self.as_slice().read_at(offset, len)
    }
}

impl<T: ByteSource + ?Sized> ByteSource for &T {
    fn len(&self) -> Result<u64, ContainerError> {
        (**self).len()
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        (**self).read_at(offset, len)
    }
}

/// A file on disk, read with positioned reads.
pub struct FileSource {
    file: std::fs::File,
    len: u64,
}

impl FileSource {
    /// Opens the file at `path` for positioned reads; [`ContainerError::Io`] names the path.
    pub fn open(path: &Path) -> Result<Self, ContainerError> {
        let file = std::fs::File::open(path).map_err(|e| ContainerError::Io(format!("{}: {e}", path.display())))?;
        let len = file.metadata().map_err(|e| ContainerError::Io(format!("{}: {e}", path.display())))?.len();
        Ok(FileSource { file, len })
    }
}

impl ByteSource for FileSource {
    fn len(&self) -> Result<u64, ContainerError> {
        Ok(self.len)
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        use std::os::unix::fs::FileExt;
        if offset.checked_add(len as u64).is_none_or(|end| end > self.len) {
            return Err(ContainerError::Io(format!("read of {len} bytes at {offset} beyond the end ({})", self.len)));
        }
        let mut buf = vec![0u8; len];
        self.file.read_exact_at(&mut buf, offset).map_err(|e| ContainerError::Io(e.to_string()))?;
        Ok(buf)
    }
}

/// An opened container: header and index checked, chunks on demand.
#[derive(Clone)]
pub struct Reader<S> {
    source: S,
    /// Format version of the file (its preamble's).
    version: u16,
    /// The preamble's flags (`format::FLAG_STORED`, `format::FLAG_SPARSE`).
    flags: u16,
    header: Header,
    index: Index,
    data_start: u64,
    file_len: u64,
    bytes_read: Cell<u64>,
    /// With a banded index read in part ([`Reader::open_at`]): the finest level its entries serve.
    level: Option<usize>,
}

impl<S: ByteSource> Reader<S> {
    /// Reads and checks the preamble (magic and version first), the header and the index.
    pub fn open(source: S) -> Result<Self, ContainerError> {
        Self::open_with(source, None)
    }

    /// [`Reader::open`] for a client whose finest level is `level`: of a banded index
    /// ([`crate::format::FLAG_BANDS`]) it fetches the group table and only the groups that
    /// client reads ([`crate::format::groups_for`]), each checked against its CRC; other files
    /// are read whole. A [`crate::Decoder`] over it decodes levels `level..` only.
    pub fn open_at(source: S, level: usize) -> Result<Self, ContainerError> {
        Self::open_with(source, Some(level))
    }

    /// Whether the entries this reader holds serve a client whose finest level is `level`: all
    /// of them, or those read for that very level. (A reader opened at a finer level lacks the
    /// faces group of each coarser band, and may lack the topology below it that a coarser
    /// band deriving its faces reads.)
    pub fn covers(&self, level: usize) -> bool {
        self.level.is_none_or(|l| l == level)
    }

    fn open_with(source: S, level: Option<usize>) -> Result<Self, ContainerError> {
        let file_len = source.len()?;
        if file_len < PREAMBLE_LEN as u64 {
            // Say "not a .pmc file" for short junk, "truncated" for a cut-off real one.
            let head = source.read_at(0, file_len as usize)?;
            let magic = crate::format::MAGIC;
            return Err(if head.iter().zip(magic.iter()).all(|(a, b)| a == b) {
                ContainerError::Truncated { what: "preamble".into() }
            } else {
                ContainerError::BadMagic
            });
        }
        let pre = Preamble::parse(&source.read_at(0, PREAMBLE_LEN)?)?;
        let data_start = PREAMBLE_LEN as u64 + pre.header_len as u64 + pre.index_len as u64;
        if data_start > file_len {
            return Err(ContainerError::Truncated { what: "header and index".into() });
        }
        let hb = source.read_at(PREAMBLE_LEN as u64, pre.header_len as usize)?;
        if crc32fast::hash(&hb) != pre.header_crc {
            return Err(ContainerError::Checksum { what: "header".into() });
        }
        let mut header = Header::from_bytes(&hb, pre.version)?;
        if pre.flags & crate::format::FLAG_NAMES != 0 {
            header.frame_names = crate::format::front_decode(&header.frame_names);
        }
        let index_at = PREAMBLE_LEN as u64 + pre.header_len as u64;
        let (index, bytes_read, level) = if pre.version >= 7 && pre.flags & crate::format::FLAG_BANDS != 0 {
            check_header(&header)?;
            let (index, read, level) = read_banded(&source, &pre, &header, index_at, file_len - data_start, level)?;
            (index, index_at + read, level)
        } else {
            let ib = source.read_at(index_at, pre.index_len as usize)?;
            if crc32fast::hash(&ib) != pre.index_crc {
                return Err(ContainerError::Checksum { what: "index".into() });
            }
            // Version 7's index is laid out by the header's frames: the header is checked
            // first. (Older versions keep the order of their checks, and so the errors they
            // report.)
            if pre.version >= 7 {
                check_header(&header)?;
            }
            let index = Index::from_bytes(&ib, pre.version, header.frame_count)?;
            check_header(&header)?;
            (index, data_start, None)
        };
        let reader = Reader {
            source,
            version: pre.version,
            flags: pre.flags,
            header,
            index,
            data_start,
            file_len,
            bytes_read: Cell::new(bytes_read),
            level,
        };
        reader.check_index()?;
        Ok(reader)
    }

    /// The file's format version.
    pub fn version(&self) -> u16 {
        self.version
    }

    /// The preamble's flags.
    pub fn flags(&self) -> u16 {
        self.flags
    }

    /// The file's header, migrated to today's version.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// A reader over a borrow of this one's source (header and index copied), e.g. to hand to
    /// a [`crate::Decoder`] while keeping this reader.
    pub fn borrowed(&self) -> Reader<&S> {
        Reader {
            source: &self.source,
            version: self.version,
            flags: self.flags,
            header: self.header.clone(),
            index: self.index.clone(),
            data_start: self.data_start,
            file_len: self.file_len,
            bytes_read: Cell::new(self.bytes_read.get()),
            level: self.level,
        }
    }

    /// The chunk index, in file order.
    pub fn index(&self) -> &Index {
        &self.index
    }

    /// Length of the source in bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// Offset of the chunk area (preamble + header + index).
    pub fn data_start(&self) -> u64 {
        self.data_start
    }

    /// Bytes fetched from the source so far (preamble, header, index and chunks).
    pub fn bytes_read(&self) -> u64 {
        self.bytes_read.get()
    }

    /// The byte source.
    pub fn source(&self) -> &S {
        &self.source
    }

    /// The entry of a chunk, if the file has it.
    pub fn find(&self, kind: ChunkKind, frame: u32, band: u32) -> Option<&ChunkEntry> {
        // Entries are in file order: triangles, then per frame per band (coarse first) key,
        // delta, positions. Binary search on (frame) then scan the few entries of that frame.
        let chunks = &self.index.chunks;
        let start = chunks.partition_point(|e| e.kind == ChunkKind::Triangles || e.frame < frame);
        chunks[start..].iter().take_while(|e| e.frame == frame).find(|e| e.kind == kind && e.band == band)
    }

    /// Whether band `level`'s faces and corner updates are derived in the keyframe interval of
    /// `frame` (its keyframe's Faces chunk is coding 2, proto/container.md "Faces"), which a
    /// reader tells from the index entry alone.
    pub fn derives(&self, frame: u32, level: usize) -> bool {
        crate::derive::derives(&self.index.chunks, self.header.keyframe_interval, frame, level)
    }

    /// Whether a client whose finest level is `level` reads chunk `e`: [`ChunkKind::read_at`],
    /// and where band `level` is derived ([`Reader::derives`]), the Triangles chunk and the Key
    /// and Delta chunks of the bands below it.
    pub fn reads(&self, e: &ChunkEntry, level: usize) -> bool {
        crate::derive::reads(&self.index.chunks, self.header.keyframe_interval, e, level)
    }

    /// Fetches one chunk, checks its CRC before decompressing, and decompresses it into at most
    /// its declared raw length.
    pub fn read_chunk(&self, e: &ChunkEntry) -> Result<Vec<u8>, ContainerError> {
        let what = e.describe();
        let offset = self.data_start + e.offset;
        if offset + e.stored_len as u64 > self.file_len {
            return Err(ContainerError::Truncated { what });
        }
        let stored = self.source.read_at(offset, e.stored_len as usize)?;
        self.bytes_read.set(self.bytes_read.get() + stored.len() as u64);
        if crc32fast::hash(&stored) != e.crc32 {
            return Err(ContainerError::Checksum { what });
        }
        if self.flags & crate::format::FLAG_STORED != 0 && e.stored_len == e.raw_len {
            return Ok(stored.to_vec());
        }
        // A zstd frame states its content size: one that disagrees with the index is refused
        // before a buffer of the index's size is set aside for it.
        if let Ok(Some(n)) = zstd::zstd_safe::get_frame_content_size(&stored)
            && n != e.raw_len as u64
        {
            return Err(ContainerError::Corrupt { what, detail: format!("zstd frame of {n} bytes where the index says {}", e.raw_len) });
        }
        let raw = decompress(&stored, e.raw_len as usize)
            .map_err(|err| ContainerError::Corrupt { what: what.clone(), detail: format!("zstd: {err}") })?;
        if raw.len() != e.raw_len as usize {
            return Err(ContainerError::Corrupt { what, detail: format!("{} bytes where the index says {}", raw.len(), e.raw_len) });
        }
        Ok(raw)
    }

    fn check_index(&self) -> Result<(), ContainerError> {
        let h = &self.header;
        let area = self.file_len - self.data_start;
        let mut last = None;
        let mut end = 0u64;
        let mut triangles_seen = false;
        let mut appearance_seen = std::collections::HashSet::new();
        for e in &self.index.chunks {
            let what = e.describe();
            let bad = |detail: String| ContainerError::Corrupt { what: what.clone(), detail };
            let Some(chunk_end) = e.offset.checked_add(e.stored_len as u64).filter(|&x| x <= area) else {
                return Err(ContainerError::Truncated { what });
            };
            end = end.max(chunk_end);
            if !matches!(e.kind, ChunkKind::Triangles | ChunkKind::Image) && (e.frame >= h.frame_count || e.band as usize >= h.levels()) {
                return Err(bad("frame or band beyond the header's counts".into()));
            }
            check_appearance_entry(h, e, &mut appearance_seen).map_err(bad)?;
            if e.kind == ChunkKind::Triangles {
                if e.frame != 0 || e.band != 0 {
                    return Err(bad(format!("frame {} band {}, where the triangles chunk is frame 0 band 0", e.frame, e.band)));
                }
                if triangles_seen {
                    return Err(bad("a second triangles chunk".into()));
                }
                triangles_seen = true;
            }
            crate::skin::check_entry(h, e).map_err(bad)?;
            let (least, most) = raw_len_range(h, e.kind, e.band as usize);
            if e.raw_len as u64 > most {
                return Err(bad(format!("declared size {} beyond the {most} bytes the header allows", e.raw_len)));
            }
            if (e.raw_len as u64) < least {
                return Err(bad(format!("declared size {} below the {least} bytes the header's counts need", e.raw_len)));
            }
            let key = (e.kind != ChunkKind::Triangles, e.frame);
            if last.is_some_and(|l| l > key) {
                return Err(bad("index entries out of order".into()));
            }
            last = Some(key);
        }
        // The container ends with its last chunk: bytes after it (garbage, or a second
        // container appended) are refused rather than ignored. (A banded index's table
        // accounts for every byte of the chunk area, checked when it was read.)
        if self.flags & crate::format::FLAG_BANDS == 0 && end < area {
            return Err(ContainerError::TrailingBytes { bytes: area - end });
        }
        Ok(())
    }
}

/// Reads a banded index ([`crate::format::FLAG_BANDS`]) at `index_at`: its table (checked
/// against the preamble's CRC), then every group, or with `level` the groups a client of that
/// level reads. Returns its entries in frame order, the index bytes fetched, and the level the
/// entries serve (`None`: all of them).
#[allow(clippy::type_complexity)]
fn read_banded<S: ByteSource>(
    source: &S,
    pre: &Preamble,
    h: &Header,
    index_at: u64,
    area: u64,
    level: Option<usize>,
) -> Result<(Index, u64, Option<usize>), ContainerError> {
    use crate::format::{groups_for, parse_group, parse_table};
    let corrupt = |detail: String| ContainerError::Corrupt { what: "index table".into(), detail };
    if pre.table_len > pre.index_len {
        return Err(corrupt(format!("{} bytes in an index of {}", pre.table_len, pre.index_len)));
    }
    let tb = source.read_at(index_at, pre.table_len as usize)?;
    if crc32fast::hash(&tb) != pre.index_crc {
        return Err(ContainerError::Checksum { what: "index table".into() });
    }
    let levels = h.levels();
    let rows = parse_table(&tb, levels)?;
    let bodies: u64 = rows.iter().map(|r| r.body_len as u64).sum();
    if bodies != (pre.index_len - pre.table_len) as u64 {
        return Err(corrupt(format!("groups of {bodies} bytes in {} bytes after the table", pre.index_len - pre.table_len)));
    }
    let chunks: u64 = rows.iter().map(|r| r.chunks_len as u64).sum();
    if chunks > area {
        return Err(ContainerError::Truncated { what: "chunk area".into() });
    }
    if chunks < area {
        return Err(ContainerError::TrailingBytes { bytes: area - chunks });
    }
    // (Level 0 reads every group but the faces of the bands above it.)
    let level = level.filter(|&l| l < levels);
    let wanted = match level {
        None => (0..rows.len()).collect(),
        Some(l) => groups_for(levels, l, rows.get(crate::format::group_of(ChunkKind::Faces, l as u32, levels)).is_some_and(|r| r.derived)),
    };
    let (mut body_at, mut chunk_at) = (index_at + pre.table_len as u64, 0u64);
    let mut read = pre.table_len as u64;
    let mut entries = Vec::new();
    for (g, row) in rows.iter().enumerate() {
        if wanted.contains(&g) {
            let body = source.read_at(body_at, row.body_len as usize)?;
            read += body.len() as u64;
            entries.extend(parse_group(&body, g, row, chunk_at, levels, h.frame_count)?);
        }
        body_at += row.body_len as u64;
        chunk_at += row.chunks_len as u64;
    }
    crate::format::frame_order(&mut entries);
    Ok((Index { chunks: entries }, read, level))
}

/// The decompressed sizes a chunk of this kind and band may declare, from the header's
/// counts: every number takes 1 to 5 bytes, and the formats say how many numbers a chunk holds
/// (proto/container.md, "Limits"). The upper end bounds decompression; the lower end makes a
/// header that claims more triangles or nodes than its chunks hold fail at open, before a
/// decoder sizes anything from it.
fn raw_len_range(h: &Header, kind: ChunkKind, band: usize) -> (u64, u64) {
    let t = h.triangle_count as u64;
    let n = h.level_sizes.get(band).map_or(0, |&n| n as u64);
    let below_top = band < h.top();
    match kind {
        // Coding 1 (version 7) takes at least 4 bits a triangle after its two bytes `0 1`.
        ChunkKind::Triangles => (if t == 0 { 1 } else { 2 + t.div_ceil(2) }, 5 + 15 * t),
        // A bit-coded Key chunk (coding 1) takes at least a bit per parent; coding 3 (changes
        // from frame 0's) three bytes.
        ChunkKind::Key if below_top => ((1 + n.div_ceil(8)).min(3), 5 + 5 * n),
        ChunkKind::Key => (1, 5),
        ChunkKind::Delta => (1, 5 + 10 * n),
        ChunkKind::Faces => (1, 5 + 20 * t),
        ChunkKind::Corners => (1, 5 + 25 * t),
        ChunkKind::Positions => (1, POSITIONS_SLACK + 24 * n),
        // Appearance (version 6): a chart per triangle at most; an attribute entry per alive
        // triangle corner at most, each a node, a chart and its channels.
        ChunkKind::Charts => (3, 15 + 25 * t),
        ChunkKind::Attributes => {
            let channels = h.appearance.as_ref().map_or(0, |a| a.channels() as u64);
            (1, 5 + (10 + 5 * channels) * 3 * t)
        }
        ChunkKind::Materials => (4, MAX_MATERIALS_LEN),
        ChunkKind::Image => (1, MAX_IMAGE_LEN),
        ChunkKind::Bind | ChunkKind::Pose | ChunkKind::Palette | ChunkKind::Joints => crate::skin::raw_len_range(h, kind, n),
    }
}

/// Largest Materials chunk (postcard of the materials, textures, samplers and image names).
pub const MAX_MATERIALS_LEN: u64 = 16 << 20;
/// Largest image (one Image chunk).
pub const MAX_IMAGE_LEN: u64 = 256 << 20;
/// Most materials and images a file may declare.
pub const MAX_MATERIALS: u32 = 1 << 16;
pub const MAX_IMAGES: u32 = 1 << 12;

/// Appearance chunks: only in a file whose header has an appearance, on frame 0, each band of
/// each kind once, Charts and Materials in band 0, Images in bands below the image count.
fn check_appearance_entry(h: &Header, e: &ChunkEntry, seen: &mut std::collections::HashSet<(ChunkKind, u32)>) -> Result<(), String> {
    if !matches!(e.kind, ChunkKind::Charts | ChunkKind::Attributes | ChunkKind::Materials | ChunkKind::Image) {
        return Ok(());
    }
    let Some(info) = &h.appearance else {
        return Err("an appearance chunk in a file whose header has no appearance".into());
    };
    if e.frame != 0 {
        return Err(format!("frame {}, where appearance chunks are frame 0", e.frame));
    }
    let band_ok = match e.kind {
        ChunkKind::Charts | ChunkKind::Materials => e.band == 0,
        ChunkKind::Image => e.band < info.images,
        _ => true,
    };
    if !band_ok {
        return Err(format!("band {} out of range for its kind", e.band));
    }
    if !seen.insert((e.kind, e.band)) {
        return Err("a second chunk of this kind and band".into());
    }
    Ok(())
}

/// Bytes a positions chunk may hold beyond 24 per node: its first number, three frequency
/// tables of up to 32 entries, and the stream length and rANS states.
const POSITIONS_SLACK: u64 = 1024;

/// Checks the header's own consistency before anything is sized from it.
pub(crate) fn check_header(h: &Header) -> Result<(), ContainerError> {
    let bad = |d: String| Err(ContainerError::Corrupt { what: "header".into(), detail: d });
    if let Some(detail) = crate::skin::check_header(h) {
        return bad(detail);
    }
    if h.level_sizes.is_empty() || h.level_sizes.len() > MAX_LEVELS {
        return bad(format!("{} levels", h.level_sizes.len()));
    }
    if h.level_sizes[0] != h.vertex_count {
        return bad(format!("level 0 has {} nodes for {} vertices", h.level_sizes[0], h.vertex_count));
    }
    if h.level_sizes.windows(2).any(|w| w[1] == 0 || w[1] > w[0]) {
        return bad(format!("level sizes {:?} do not shrink", h.level_sizes));
    }
    if h.vertex_count > MAX_VERTICES {
        return bad(format!("{} vertices, more than the {MAX_VERTICES} a file may have", h.vertex_count));
    }
    if h.triangle_count > MAX_TRIANGLES {
        return bad(format!("{} triangles, more than the {MAX_TRIANGLES} a file may have", h.triangle_count));
    }
    if h.node_count() > MAX_NODES {
        return bad(format!("{} nodes in all levels, more than the {MAX_NODES} a file may have", h.node_count()));
    }
    if h.frame_count == 0 {
        return bad("no frames".into());
    }
    if h.frame_count > MAX_FRAMES {
        return bad(format!("{} frames, more than the {MAX_FRAMES} a file may have", h.frame_count));
    }
    if !(h.quantization.step.is_finite() && h.quantization.step > 0.0) {
        return bad(format!("quantization step {}", h.quantization.step));
    }
    if !(h.frame_rate.is_finite() && h.frame_rate > 0.0) {
        return bad(format!("frame rate {}", h.frame_rate));
    }
    if h.bbox_min.iter().chain(&h.bbox_max).any(|x| !x.is_finite()) {
        return bad("bounding box is not finite".into());
    }
    if let Some(a) = &h.appearance {
        if a.charts == 0 || a.charts > h.triangle_count {
            return bad(format!("appearance: {} charts for {} triangles", a.charts, h.triangle_count));
        }
        if a.groups == 0 || a.groups > h.triangle_count {
            return bad(format!("appearance: {} smoothing groups for {} triangles", a.groups, h.triangle_count));
        }
        if a.materials > MAX_MATERIALS || a.images > MAX_IMAGES {
            return bad(format!("appearance: {} materials and {} images, more than a file may have", a.materials, a.images));
        }
        if a.uv_sets > 2 {
            return bad(format!("appearance: {} texture coordinate sets", a.uv_sets));
        }
        if a.uv_min.iter().any(|x| !x.is_finite()) || a.uv_step.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return bad("appearance: texture coordinate grid is not finite and positive".into());
        }
    }
    Ok(())
}

thread_local! {
    /// One zstd decompression context per thread, reused: creating one per chunk cost about
    /// a tenth of the decoding time of a frame.
    static DCTX: std::cell::RefCell<Option<zstd::bulk::Decompressor<'static>>> = const { std::cell::RefCell::new(None) };
}

fn decompress(stored: &[u8], capacity: usize) -> std::io::Result<Vec<u8>> {
    DCTX.with(|cell| {
        let mut slot = cell.try_borrow_mut().map_err(|_| std::io::Error::other("zstd context busy"))?;
        if slot.is_none() {
            *slot = Some(zstd::bulk::Decompressor::new()?);
        }
        match slot.as_mut() {
            Some(d) => d.decompress(stored, capacity),
            None => zstd::bulk::decompress(stored, capacity),
        }
    })
}
