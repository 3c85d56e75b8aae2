//! The raw serialized types of the `.pmc` container, kept apart from the encoder and decoder
//! (see proto/container.md for the byte-level specification).

use serde::{Deserialize, Serialize};

/// First 8 bytes of every file. The high-bit byte and the CR LF / EOF / LF bytes make text-mode
/// transfers and truncating tools fail loudly, as in PNG's signature.
pub const MAGIC: [u8; 8] = *b"\x89PMC\r\n\x1a\n";
/// Format version this crate writes and reads.
pub const VERSION: u16 = 6;
/// Oldest format version this crate still reads. Versions 3 to 5 differ from 6 in their
/// header ([`HeaderV3`], [`HeaderV4`], [`HeaderV5`], migrated into [`Header`] on reading) and
/// in having neither appearance nor skin chunks, so servers that upgrade keep serving what they
/// stored.
pub const OLDEST_READABLE: u16 = 3;
/// Size of the fixed preamble.
pub const PREAMBLE_LEN: usize = 32;
/// Upper bound on the header and index sizes a reader accepts (protects allocations).
pub const MAX_TABLE_LEN: u32 = 64 << 20;
/// Caps on the sizes a header may declare, so that what a decoder allocates, which is
/// proportional to them (proto/container.md, "Limits"), stays bounded whatever the input:
/// input vertices, input triangles, nodes of all levels, frames and levels. They are far above
/// any mesh the encoder is meant for (a million vertices) and far below what would exhaust a
/// server.
pub const MAX_VERTICES: u32 = 1 << 24;
pub const MAX_TRIANGLES: u32 = 1 << 25;
pub const MAX_NODES: u64 = 1 << 25;
pub const MAX_FRAMES: u32 = 1 << 20;
pub const MAX_LEVELS: usize = 64;
/// zstd level for chunks: files are written once and read many times.
pub const ZSTD_LEVEL: i32 = 19;

/// Preamble flag (version 6): a chunk whose `stored_len` equals its `raw_len` is its payload
/// as is, not a zstd frame. The encoder stores a chunk so whenever zstd would not make it
/// shorter: a zstd frame costs 6 to 12 bytes of its own, more than most of a small mesh's
/// per-frame chunks hold (issue 17, "overhead on small meshes").
pub const FLAG_STORED: u16 = 1;
/// Preamble flag (version 6): Delta and Corners chunks with nothing in them (the one-byte
/// payload 0: no swaps, no corner updates) are left out of the file, and a reader takes a
/// missing one as that payload. Most frames of a small mesh swap nothing in most bands, and
/// each chunk costs an index entry (about 15 bytes) besides its own bytes.
pub const FLAG_SPARSE: u16 = 2;
/// The flags this encoder sets and this reader knows.
pub const FLAGS: u16 = FLAG_STORED | FLAG_SPARSE;

/// A chunk's stored bytes in a file with preamble `flags`: its zstd frame at `level`, or, with
/// [`FLAG_STORED`], the payload itself when the frame would be no shorter (a frame exactly as
/// long as the payload would read as a stored payload, so it is stored too).
pub fn store_chunk(raw: &[u8], level: i32, flags: u16) -> std::io::Result<Vec<u8>> {
    let z = compress(raw, level)?;
    Ok(if flags & FLAG_STORED != 0 && z.len() >= raw.len() { raw.to_vec() } else { z })
}

/// Inputs up to this size go through [`compress`]'s kept context and are remembered (a small
/// band's Positions payload is compressed to choose its coding, then again to be stored).
/// Larger ones get a context of their own, freed after: zstd sizes a context's tables by its
/// largest input, and a kept one sized by a 135k-vertex band added 20 MiB to the encoder's peak
/// memory, while creating a context costs little beside compressing that much.
const REMEMBERED: usize = 1 << 16;

/// What [`compress`] keeps per thread: its context, and the last small input with its frame.
#[derive(Default)]
struct Compression {
    context: Option<(i32, zstd::bulk::Compressor<'static>)>,
    last: Vec<(i32, Vec<u8>, Vec<u8>)>,
}

thread_local! {
    static CCTX: std::cell::RefCell<Compression> = std::cell::RefCell::new(Compression::default());
}

/// `raw` as one zstd frame at `level`, the same bytes as `zstd::bulk::compress` gives. Small
/// inputs go through one context per thread (creating a level-19 context per chunk cost about
/// 2% of a whole encode of the horse), and the last two are remembered with their frames, so a
/// payload compressed once to measure it and once to store it is compressed once.
pub fn compress(raw: &[u8], level: i32) -> std::io::Result<Vec<u8>> {
    if raw.len() > REMEMBERED {
        return zstd::bulk::compress(raw, level);
    }
    CCTX.with(|cell| {
        let Ok(mut state) = cell.try_borrow_mut() else {
            return zstd::bulk::compress(raw, level);
        };
        if let Some((_, _, z)) = state.last.iter().find(|(l, r, _)| *l == level && r.as_slice() == raw) {
            return Ok(z.clone());
        }
        if state.context.as_ref().is_none_or(|(l, _)| *l != level) {
            state.context = Some((level, zstd::bulk::Compressor::new(level)?));
        }
        let z = match state.context.as_mut() {
            Some((_, c)) => c.compress(raw)?,
            None => zstd::bulk::compress(raw, level)?,
        };
        if state.last.len() == 2 {
            state.last.remove(0);
        }
        state.last.push((level, raw.to_vec(), z.clone()));
        Ok(z)
    })
}

/// Whether a chunk of `kind` left out of a file with preamble `flags` reads as empty.
pub fn sparse_kind(kind: ChunkKind, flags: u16) -> bool {
    flags & FLAG_SPARSE != 0 && matches!(kind, ChunkKind::Delta | ChunkKind::Corners)
}

/// The fixed 32-byte preamble.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Preamble {
    pub version: u16,
    pub flags: u16,
    pub header_len: u32,
    pub index_len: u32,
    pub header_crc: u32,
    pub index_crc: u32,
}

impl Preamble {
    pub fn to_bytes(&self) -> [u8; PREAMBLE_LEN] {
        let mut b = [0u8; PREAMBLE_LEN];
        b[..8].copy_from_slice(&MAGIC);
        b[8..10].copy_from_slice(&self.version.to_le_bytes());
        b[10..12].copy_from_slice(&self.flags.to_le_bytes());
        b[12..16].copy_from_slice(&self.header_len.to_le_bytes());
        b[16..20].copy_from_slice(&self.index_len.to_le_bytes());
        b[20..24].copy_from_slice(&self.header_crc.to_le_bytes());
        b[24..28].copy_from_slice(&self.index_crc.to_le_bytes());
        // 28..32 reserved, zero.
        b
    }

    /// Parses and checks magic and version first, as a reader must.
    pub fn parse(b: &[u8]) -> Result<Self, crate::ContainerError> {
        use crate::ContainerError as E;
        if b.len() < PREAMBLE_LEN {
            return Err(E::Truncated { what: "preamble".into() });
        }
        if b[..8] != MAGIC {
            return Err(E::BadMagic);
        }
        let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let version = u16_at(8);
        if !(OLDEST_READABLE..=VERSION).contains(&version) {
            return Err(E::UnsupportedVersion(version));
        }
        let p = Preamble {
            version,
            flags: u16_at(10),
            header_len: u32_at(12),
            index_len: u32_at(16),
            header_crc: u32_at(20),
            index_crc: u32_at(24),
        };
        if p.header_len > MAX_TABLE_LEN || p.index_len > MAX_TABLE_LEN {
            return Err(E::Corrupt { what: "preamble".into(), detail: "header or index length beyond 64 MiB".into() });
        }
        Ok(p)
    }
}

/// How positions are quantized: `q = round((p - bbox_min) / step)` per axis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quantization {
    pub step: f32,
}

/// The options the file was encoded with (for `info`, and to re-encode alike).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EncodedWith {
    pub base_poses: String,
    pub base_weights: String,
    pub beta: f64,
    pub min_relative_benefit: f64,
    pub max_passes: u32,
    pub homeomorphism: bool,
    pub exact_benefit: bool,
    pub max_error: Option<f64>,
    pub quant_bits: Option<u8>,
}

/// How input vertices (band 0) are predicted on frames that are not keyframes
/// (proto/container.md, "Positions, band j").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Motion {
    /// The previous position plus the mean motion of the lower neighbours.
    #[default]
    Mean,
    /// The affine motion of the vertex's stencil, fitted on the previous frame (version 4): on
    /// the horse at 12 bits, 17% fewer position bytes for about 0.4 ms more decoding per frame.
    Affine,
    /// The same affine motion as weights on the stencil's motions, the weights taken from the
    /// keyframe's geometry (version 5): nearly the bits of `Affine`, about the decoding time of
    /// `Mean`.
    KeyframeAffine,
}

/// The order band 0 (the input vertices) is decoded in, which decides each vertex's lower
/// neighbours and stencil (proto/container.md, "Band 0 order").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum VertexOrder {
    /// Input order (what versions 3 and 4 use).
    #[default]
    Input,
    /// Breadth first over the input triangles' edges: a vertex's decoded neighbours then lie
    /// on the front that reached it, on one side, rather than wherever the input numbering put
    /// them, and its stencil fits its motion better.
    BreadthFirst,
}

/// The header (postcard).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub vertex_count: u32,
    pub triangle_count: u32,
    pub frame_count: u32,
    pub frame_rate: f32,
    /// |M_0| .. |M_top|.
    pub level_sizes: Vec<u32>,
    pub branching: u32,
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
    pub quantization: Quantization,
    /// A keyframe every this many frames (0: only frame 0).
    pub keyframe_interval: u32,
    pub encoded_with: EncodedWith,
    pub generator: String,
    pub frame_names: Vec<String>,
    /// Band 0's prediction on inter frames.
    pub motion: Motion,
    /// Band 0's decoding order.
    pub order: VertexOrder,
    /// Texture coordinates, colours and materials (version 6; `None` for a bare surface).
    pub appearance: Option<crate::appearance::AppearanceInfo>,
    /// The skin, when node positions are predicted by skinning (version 6).
    pub skin: Option<crate::skin::SkinHeader>,
}

impl Header {
    /// Parses the header of a file of format `version` (checked by [`Preamble::parse`]): each
    /// old version as the type it was written as, then migrated field by field into today's.
    /// A header must end with its last field (what its encoder wrote), except version 5's:
    /// its readers ignored bytes after it, and still do.
    pub fn from_bytes(bytes: &[u8], version: u16) -> Result<Header, crate::ContainerError> {
        let corrupt = |detail: String| crate::ContainerError::Corrupt { what: "header".into(), detail };
        match version {
            3 => exactly::<HeaderV3>(bytes).map(|h| HeaderV5::from(HeaderV4::from(h)).into()),
            4 => exactly::<HeaderV4>(bytes).map(|h| HeaderV5::from(h).into()),
            5 => postcard::from_bytes::<HeaderV5>(bytes).map(Header::from).map_err(|e| corrupt(e.to_string())),
            _ => exactly(bytes),
        }
    }

    pub fn levels(&self) -> usize {
        self.level_sizes.len()
    }

    pub fn top(&self) -> usize {
        self.level_sizes.len().saturating_sub(1)
    }

    pub fn is_keyframe(&self, frame: u32) -> bool {
        frame == 0 || (self.keyframe_interval > 0 && frame.is_multiple_of(self.keyframe_interval))
    }

    /// The keyframe at or before `frame`.
    pub fn keyframe_before(&self, frame: u32) -> u32 {
        if self.keyframe_interval == 0 { 0 } else { frame - frame % self.keyframe_interval }
    }

    pub fn node_count(&self) -> u64 {
        self.level_sizes.iter().map(|&s| s as u64).sum()
    }
}

/// A postcard value that fills `bytes` exactly.
fn exactly<'a, T: Deserialize<'a>>(bytes: &'a [u8]) -> Result<T, crate::ContainerError> {
    let corrupt = |detail: String| crate::ContainerError::Corrupt { what: "header".into(), detail };
    let (value, rest) = postcard::take_from_bytes(bytes).map_err(|e| corrupt(e.to_string()))?;
    if !rest.is_empty() {
        return Err(corrupt(format!("{} bytes after its last field", rest.len())));
    }
    Ok(value)
}

/// The header of format version 3: today's fields up to `frame_names`; band 0 always moved by
/// the mean motion and decoded in input order. Postcard writes a struct as its fields one after
/// another, so the later versions nest it as their first field and read the same bytes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeaderV3 {
    pub vertex_count: u32,
    pub triangle_count: u32,
    pub frame_count: u32,
    pub frame_rate: f32,
    pub level_sizes: Vec<u32>,
    pub branching: u32,
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
    pub quantization: Quantization,
    pub keyframe_interval: u32,
    pub encoded_with: EncodedWith,
    pub generator: String,
    pub frame_names: Vec<String>,
}

/// Band 0's motions version 4 knew (a third discriminant is not a version 4 file).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MotionV4 {
    Mean,
    Affine,
}

/// The header of format version 4: version 3's and band 0's motion; band 0 in input order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeaderV4 {
    pub v3: HeaderV3,
    pub motion: MotionV4,
}

impl From<HeaderV3> for HeaderV4 {
    fn from(v3: HeaderV3) -> Self {
        HeaderV4 { v3, motion: MotionV4::Mean }
    }
}

/// The header of format version 5: version 3's, band 0's motion and order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeaderV5 {
    pub v3: HeaderV3,
    pub motion: Motion,
    pub order: VertexOrder,
}

impl From<HeaderV4> for HeaderV5 {
    fn from(v4: HeaderV4) -> Self {
        let motion = match v4.motion {
            MotionV4::Mean => Motion::Mean,
            MotionV4::Affine => Motion::Affine,
        };
        HeaderV5 { v3: v4.v3, motion, order: VertexOrder::Input }
    }
}

impl From<HeaderV5> for Header {
    fn from(v5: HeaderV5) -> Self {
        let HeaderV5 { v3, motion, order } = v5;
        Header {
            vertex_count: v3.vertex_count,
            triangle_count: v3.triangle_count,
            frame_count: v3.frame_count,
            frame_rate: v3.frame_rate,
            level_sizes: v3.level_sizes,
            branching: v3.branching,
            bbox_min: v3.bbox_min,
            bbox_max: v3.bbox_max,
            quantization: v3.quantization,
            keyframe_interval: v3.keyframe_interval,
            encoded_with: v3.encoded_with,
            generator: v3.generator,
            frame_names: v3.frame_names,
            motion,
            order,
            appearance: None,
            skin: None,
        }
    }
}

/// What a chunk holds. Serialized as its number (a varint), so kinds added by later versions
/// keep the numbers they were given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "u32", try_from = "u32")]
pub enum ChunkKind {
    /// The input triangles (band 0 only; one per file).
    Triangles,
    /// A keyframe's band: the parent map of that level.
    Key,
    /// A frame's swaps for one band: net parent changes of that level's nodes.
    Delta,
    /// A frame's quantized node positions for one band.
    Positions,
    /// A keyframe's triangles alive at the band's level with their corners there (bands >= 1;
    /// read only by a client whose finest level is that band).
    Faces,
    /// A frame's corner updates at the band's level (bands >= 1; read only by a client whose
    /// finest level is that band).
    Corners,
    /// Each triangle's chart, each chart's material and smoothing group (version 6; frame 0,
    /// band 0; every client reads it).
    Charts = 6,
    /// The band's (node, chart) attribute table: texture coordinates and colours (version 6;
    /// frame 0; read by clients whose finest level is the band or finer).
    Attributes = 7,
    /// Materials, textures, samplers and image descriptions, postcard (version 6; frame 0,
    /// band 0; every client reads it).
    Materials = 8,
    /// One image's encoded bytes, PNG or JPEG; band = the image's index (version 6; frame 0;
    /// every client that draws textures reads them all).
    Image = 9,
    /// The skin of every node of the band: bind position and influences (version 6, frame 0).
    Bind = 10,
    /// A frame's joint palette and which bands skinning predicts (version 6, band 0; read by
    /// every client). Files written since the Palette chunk carry Palette chunks instead.
    Pose = 11,
    /// A frame's values of the palette entries whose coarsest user is the band, and the band
    /// mask (version 6, skinned files; read by clients whose finest level is the band or finer,
    /// so a coarse client reads only the joints its bands are skinned by).
    Palette = 12,
}

impl From<ChunkKind> for u32 {
    fn from(k: ChunkKind) -> u32 {
        k as u32
    }
}

impl TryFrom<u32> for ChunkKind {
    type Error = String;
    fn try_from(v: u32) -> Result<Self, String> {
        Ok(match v {
            0 => ChunkKind::Triangles,
            1 => ChunkKind::Key,
            2 => ChunkKind::Delta,
            3 => ChunkKind::Positions,
            4 => ChunkKind::Faces,
            5 => ChunkKind::Corners,
            6 => ChunkKind::Charts,
            7 => ChunkKind::Attributes,
            8 => ChunkKind::Materials,
            9 => ChunkKind::Image,
            10 => ChunkKind::Bind,
            11 => ChunkKind::Pose,
            12 => ChunkKind::Palette,
            _ => return Err(format!("unknown chunk kind {v}")),
        })
    }
}

impl ChunkKind {
    /// Whether a client whose finest level is `min_level` reads chunks of this kind in `band`:
    /// every band from its level up, except faces and corners, which only the band of its
    /// finest level needs (finer clients derive them).
    pub fn read_at(self, band: usize, min_level: usize) -> bool {
        match self {
            ChunkKind::Triangles => min_level == 0,
            ChunkKind::Key | ChunkKind::Delta | ChunkKind::Positions | ChunkKind::Bind | ChunkKind::Palette => band >= min_level,
            ChunkKind::Pose => true,
            ChunkKind::Faces | ChunkKind::Corners => band == min_level,
            ChunkKind::Charts | ChunkKind::Materials | ChunkKind::Image => true,
            ChunkKind::Attributes => band >= min_level,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ChunkKind::Triangles => "triangles",
            ChunkKind::Key => "keyframe",
            ChunkKind::Delta => "delta",
            ChunkKind::Positions => "positions",
            ChunkKind::Faces => "faces",
            ChunkKind::Corners => "corners",
            ChunkKind::Charts => "charts",
            ChunkKind::Attributes => "attributes",
            ChunkKind::Materials => "materials",
            ChunkKind::Image => "image",
            ChunkKind::Bind => "bind",
            ChunkKind::Pose => "pose",
            ChunkKind::Palette => "palette",
        }
    }
}

/// One index entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChunkEntry {
    pub kind: ChunkKind,
    pub frame: u32,
    pub band: u32,
    /// Offset from the end of the index (the start of the chunk area).
    pub offset: u64,
    /// Stored (compressed) length.
    pub stored_len: u32,
    /// Length after decompression.
    pub raw_len: u32,
    /// CRC-32 (IEEE) of the stored bytes.
    pub crc32: u32,
}

impl ChunkEntry {
    /// A name for error messages: "frame 12 band 3 positions".
    pub fn describe(&self) -> String {
        match self.kind {
            ChunkKind::Triangles => "triangles chunk".into(),
            ChunkKind::Charts => "charts chunk".into(),
            ChunkKind::Materials => "materials chunk".into(),
            ChunkKind::Image => format!("image {} chunk", self.band),
            ChunkKind::Attributes => format!("band {} attributes", self.band),
            k => format!("frame {} band {} {}", self.frame, self.band, k.name()),
        }
    }
}

/// The chunk index (postcard).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Index {
    pub chunks: Vec<ChunkEntry>,
}
