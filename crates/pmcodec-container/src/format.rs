//! The raw serialized types of the `.pmc` container, kept apart from the encoder and decoder
//! (see proto/container.md for the byte-level specification).

use serde::{Deserialize, Serialize};

/// First 8 bytes of every file. The high-bit byte and the CR LF / EOF / LF bytes make text-mode
/// transfers and truncating tools fail loudly, as in PNG's signature.
pub const MAGIC: [u8; 8] = *b"\x89PMC\r\n\x1a\n";
/// Format version this crate writes and reads.
pub const VERSION: u16 = 7;
/// Oldest format version this crate still reads. Versions 3 to 5 differ from 6 in their
/// header ([`HeaderV3`], [`HeaderV4`], [`HeaderV5`], migrated into [`Header`] on reading) and
/// in having neither appearance nor skin chunks; versions 3 to 6 differ from 7 in their index
/// ([`IndexV6`], postcard, migrated into [`Index`]). So servers that upgrade keep serving what
/// they stored.
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
/// Most input triangles a header may declare.
pub const MAX_TRIANGLES: u32 = 1 << 25;
/// Most nodes over all levels a header may declare.
pub const MAX_NODES: u64 = 1 << 25;
/// Most frames a header may declare.
pub const MAX_FRAMES: u32 = 1 << 20;
/// Most levels a header may declare.
pub const MAX_LEVELS: usize = 64;
/// zstd level for chunks: files are written once and read many times.
pub const ZSTD_LEVEL: i32 = 19;
/// zstd level for a Positions payload in the rANS coding (proto/container.md, "Positions",
/// coding 0): the rANS stream is already entropy coded (Duda, "Asymmetric numeral systems",
/// 2013), so zstd finds only its small frequency tables, and level 1 finds them as well as
/// level 19 does (the horse's band-0 chunks: 395,853 bytes at level 1, 395,911 at 19) at a
/// hundredth of the time: level 19's optimal parser on these payloads was most of the coding
/// thread's zstd time.
pub const RANS_ZSTD_LEVEL: i32 = 1;

/// The zstd level a chunk of `kind` with payload `raw` is stored at: [`ZSTD_LEVEL`], but
/// [`RANS_ZSTD_LEVEL`] for a Positions payload in the rANS coding (its first byte is the
/// shift, below 32; the other codings add 32 or 64). A reader needs no level.
pub fn zstd_level(kind: ChunkKind, raw: &[u8]) -> i32 {
    match (kind, raw.first()) {
        (ChunkKind::Positions, Some(&b)) if b < 32 => RANS_ZSTD_LEVEL,
        _ => ZSTD_LEVEL,
    }
}

/// Preamble flag (version 6): a chunk whose `stored_len` equals its `raw_len` is its payload
/// as is, not a zstd frame. The encoder stores a chunk so whenever zstd would not make it
/// shorter: a zstd frame costs 6 to 12 bytes of its own, more than most of a small mesh's
/// per-frame chunks hold (issue 17, "overhead on small meshes").
pub const FLAG_STORED: u16 = 1;
/// Preamble flag (version 6): Delta and Corners chunks with nothing in them (the one-byte
/// payload 0: no swaps, no corner updates) are left out of the file, and a reader takes a
/// missing one as that payload. Most frames of a small mesh swap nothing in most bands, and
/// each chunk costs an index entry (about 8 bytes, 15 before version 7) besides its own bytes.
pub const FLAG_SPARSE: u16 = 2;
/// Preamble flag (version 7): the header's frame names are *front-coded* ([`front_code`]):
/// each name after the first is the previous one's first `k` bytes and a suffix. Names of
/// successive frames share most of their bytes ("waving-cloth@123", "Dance@1.233s"): on
/// RobotExpressive's 595 frames the header was 7,841 bytes, 3,445 front-coded.
pub const FLAG_NAMES: u16 = 4;
/// Preamble flag (version 7): the index is *banded* (proto/container.md, "Index"): its entries
/// in groups by the clients that read them (what every client reads, then per band from the
/// top down its topology, its geometry and its faces), each group's chunks contiguous in the
/// chunk area in the same order, a table of the groups' lengths and CRCs first, and preamble
/// bytes 28..32 the table's length. A client at level L fetches the table and only its bands'
/// groups: on RobotExpressive a 10% client read the whole 28 KB index, 15% of its bytes.
/// Written by default ([`DEFAULT_FLAGS`]) where it is no longer than the frame-by-frame index
/// (`pmcodec encode --frame-index` opts out): its chunk area is no longer frame after frame, so
/// a frame's chunks lie in one byte range per group, which the HTTP index's per-frame `ranges`
/// (proto/http.md) and the players' multi-range requests fetch together.
pub const FLAG_BANDS: u16 = 8;
/// The flags of how chunks are stored and named: what every file of this encoder has, with or
/// without the banded index.
pub const FLAGS: u16 = FLAG_STORED | FLAG_SPARSE | FLAG_NAMES;
/// The flags this encoder sets by default ([`crate::EncodeOptions::chunk_flags`]): [`FLAGS`]
/// and the banded index (dropped where it would be longer than the frame-by-frame one).
pub const DEFAULT_FLAGS: u16 = FLAGS | FLAG_BANDS;
/// The flags this encoder may set and this reader knows.
pub const KNOWN_FLAGS: u16 = FLAGS | FLAG_BANDS;

/// Longest shared prefix a front-coded name refers to (its one-character count).
const MAX_SHARED: usize = 127;

/// Front-codes frame names ([`FLAG_NAMES`], proto/container.md "Header"): the first as is,
/// each next one as the character of code `k` (the bytes it shares with the name before, at
/// most 127, ending on a character boundary) followed by its bytes after those `k`.
pub fn front_code(names: &[String]) -> Vec<String> {
    let mut out = Vec::with_capacity(names.len());
    for (i, name) in names.iter().enumerate() {
        let Some(prev) = i.checked_sub(1).and_then(|p| names.get(p)) else {
            out.push(name.clone());
            continue;
        };
        let mut k = prev.bytes().zip(name.bytes()).take_while(|(a, b)| a == b).count().min(MAX_SHARED);
        while !name.is_char_boundary(k) {
            k -= 1;
        }
        let mut coded = String::with_capacity(1 + name.len() - k);
        coded.push(char::from(k as u8));
        coded.push_str(&name[k..]);
        out.push(coded);
    }
    out
}

/// Undoes [`front_code`]. Never fails: an entry that does not start with a count (0 to 127)
/// is a whole name, and a count beyond the name before (or inside one of its characters) is
/// cut back to it, so damaged names stay names.
pub fn front_decode(coded: &[String]) -> Vec<String> {
    let mut out: Vec<String> = Vec::with_capacity(coded.len());
    for (i, entry) in coded.iter().enumerate() {
        let (Some(prev), Some(c)) = (i.checked_sub(1).and_then(|p| out.get(p)), entry.chars().next()) else {
            out.push(entry.clone());
            continue;
        };
        if c as u32 > MAX_SHARED as u32 {
            out.push(entry.clone());
            continue;
        }
        let mut k = (c as usize).min(prev.len());
        while !prev.is_char_boundary(k) {
            k -= 1;
        }
        let name = format!("{}{}", &prev[..k], &entry[1..]);
        out.push(name);
    }
    out
}

mod compress;
pub use compress::{compress, store_chunk};

/// Whether a chunk of `kind` may be left out of a file with preamble `flags`, and then reads
/// as [`left_out_payload`].
pub fn sparse_kind(kind: ChunkKind, flags: u16) -> bool {
    flags & FLAG_SPARSE != 0 && matches!(kind, ChunkKind::Delta | ChunkKind::Corners | ChunkKind::Positions)
}

/// What a chunk of a sparse kind left out of the index reads as: no swaps, no corner updates,
/// and for Positions a band whose residuals are all zero (shift 0, sparse coding, no node
/// listed; proto/container.md, "Chunks").
pub fn left_out_payload(kind: ChunkKind) -> &'static [u8] {
    match kind {
        ChunkKind::Positions => &[64, 0],
        _ => &[0],
    }
}

/// Whether an encoder leaves a chunk of a sparse kind with payload `raw` out: the empty Delta
/// and Corners payload, and a Positions payload with every residual zero in the sparse coding
/// (any shift: zero residuals move nothing whatever their unit).
pub fn leaves_out(kind: ChunkKind, raw: &[u8]) -> bool {
    match kind {
        ChunkKind::Delta | ChunkKind::Corners => raw == [0],
        ChunkKind::Positions => raw.len() == 2 && (64..=64 + 16).contains(&raw[0]) && raw[1] == 0,
        _ => false,
    }
}

/// The fixed 32-byte preamble.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Preamble {
    /// Format version of the file ([`OLDEST_READABLE`]..=[`VERSION`]); it decides how the header parses.
    pub version: u16,
    /// Bits of [`FLAG_STORED`] and [`FLAG_SPARSE`] (version 6; 0 in older files).
    pub flags: u16,
    /// Length of the postcard header that follows the preamble.
    pub header_len: u32,
    /// Length of the postcard index that follows the header.
    pub index_len: u32,
    /// CRC-32 (IEEE) of the header bytes.
    pub header_crc: u32,
    /// CRC-32 (IEEE) of the index bytes; with [`FLAG_BANDS`], of the index's group table.
    pub index_crc: u32,
    /// With [`FLAG_BANDS`]: length of the index's group table (bytes 28..32, reserved and 0
    /// in other files).
    pub table_len: u32,
}

impl Preamble {
    /// The 32 bytes: magic, the fields little-endian, 4 reserved zero bytes (proto/container.md, "Preamble").
    pub fn to_bytes(&self) -> [u8; PREAMBLE_LEN] {
        let mut b = [0u8; PREAMBLE_LEN];
        b[..8].copy_from_slice(&MAGIC);
        b[8..10].copy_from_slice(&self.version.to_le_bytes());
        b[10..12].copy_from_slice(&self.flags.to_le_bytes());
        b[12..16].copy_from_slice(&self.header_len.to_le_bytes());
        b[16..20].copy_from_slice(&self.index_len.to_le_bytes());
        b[20..24].copy_from_slice(&self.header_crc.to_le_bytes());
        b[24..28].copy_from_slice(&self.index_crc.to_le_bytes());
        b[28..32].copy_from_slice(&self.table_len.to_le_bytes());
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
            table_len: u32_at(28),
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
    /// Size of one quantum in input units, the same on every axis.
    pub step: f32,
}

/// The options the file was encoded with (for `info`, and to re-encode alike).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EncodedWith {
    /// The base poses the quadrics were summed over (`first-frame`, `all-frames`, `sampled-N`).
    pub base_poses: String,
    /// The per-vertex weights of the base poses (`none`, `tertiles`, `smooth`).
    pub base_weights: String,
    /// Growth exponent of the QEM across levels (Kircher & Garland equation 2).
    pub beta: f64,
    /// Smallest improvement, as a fraction of a node's error, that a swap had to bring.
    pub min_relative_benefit: f64,
    /// Independent-set passes per level per frame.
    pub max_passes: u32,
    /// Whether swaps also had to keep the homeomorphism rule (section 4.2).
    pub homeomorphism: bool,
    /// Whether swaps were ranked by the exact change of error rather than equation 1's estimate.
    pub exact_benefit: bool,
    /// The quantization's error bound, when it was given as one (a fraction of the diagonal).
    pub max_error: Option<f64>,
    /// The quantization's bit count, when it was given as one.
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
    /// Input vertices.
    pub vertex_count: u32,
    /// Input triangles.
    pub triangle_count: u32,
    /// Frames.
    pub frame_count: u32,
    /// Playback rate in frames per second.
    pub frame_rate: f32,
    /// |M_0| .. |M_top|.
    pub level_sizes: Vec<u32>,
    /// The hierarchy's branching factor: each level about this many times fewer nodes than the one below.
    pub branching: u32,
    /// Lower corner of the bounding box over all frames; quantized positions count from it.
    pub bbox_min: [f32; 3],
    /// Upper corner of the bounding box over all frames.
    pub bbox_max: [f32; 3],
    /// The position quantum.
    pub quantization: Quantization,
    /// A keyframe every this many frames (0: only frame 0).
    pub keyframe_interval: u32,
    /// The options the file was encoded with.
    pub encoded_with: EncodedWith,
    /// The encoder's name and version (`pmcodec 0.1.0`).
    pub generator: String,
    /// One name per frame (file names for OBJ input, `anim@time` for glTF).
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

    /// Number of levels (bands).
    pub fn levels(&self) -> usize {
        self.level_sizes.len()
    }

    /// Index of the coarsest level.
    pub fn top(&self) -> usize {
        self.level_sizes.len().saturating_sub(1)
    }

    /// Whether `frame` is a keyframe: frame 0 and every `keyframe_interval`-th frame.
    pub fn is_keyframe(&self, frame: u32) -> bool {
        frame == 0 || (self.keyframe_interval > 0 && frame.is_multiple_of(self.keyframe_interval))
    }

    /// The keyframe at or before `frame`.
    pub fn keyframe_before(&self, frame: u32) -> u32 {
        if self.keyframe_interval == 0 { 0 } else { frame - frame % self.keyframe_interval }
    }

    /// Nodes over all levels.
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
    /// See [`Header::vertex_count`].
    pub vertex_count: u32,
    /// See [`Header::triangle_count`].
    pub triangle_count: u32,
    /// See [`Header::frame_count`].
    pub frame_count: u32,
    /// See [`Header::frame_rate`].
    pub frame_rate: f32,
    /// See [`Header::level_sizes`].
    pub level_sizes: Vec<u32>,
    /// See [`Header::branching`].
    pub branching: u32,
    /// See [`Header::bbox_min`].
    pub bbox_min: [f32; 3],
    /// See [`Header::bbox_max`].
    pub bbox_max: [f32; 3],
    /// See [`Header::quantization`].
    pub quantization: Quantization,
    /// See [`Header::keyframe_interval`].
    pub keyframe_interval: u32,
    /// See [`Header::encoded_with`].
    pub encoded_with: EncodedWith,
    /// See [`Header::generator`].
    pub generator: String,
    /// See [`Header::frame_names`].
    pub frame_names: Vec<String>,
}

/// Band 0's motions version 4 knew (a third discriminant is not a version 4 file).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MotionV4 {
    /// [`Motion::Mean`].
    Mean,
    /// [`Motion::Affine`].
    Affine,
}

/// The header of format version 4: version 3's and band 0's motion; band 0 in input order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeaderV4 {
    /// Version 3's fields, first in the bytes.
    pub v3: HeaderV3,
    /// Band 0's prediction on inter frames.
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
    /// Version 3's fields, first in the bytes.
    pub v3: HeaderV3,
    /// Band 0's prediction on inter frames.
    pub motion: Motion,
    /// Band 0's decoding order.
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
    /// The Palette chunk's entries coded as rigid transforms where they are: quaternion, scale
    /// and translation (version 6, skinned files; files written since this chunk carry Joints
    /// chunks instead of Palette chunks; read as Palette chunks are).
    Joints = 13,
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
            13 => ChunkKind::Joints,
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
            ChunkKind::Key | ChunkKind::Delta | ChunkKind::Positions | ChunkKind::Bind | ChunkKind::Palette | ChunkKind::Joints => {
                band >= min_level
            }
            ChunkKind::Pose => true,
            ChunkKind::Faces | ChunkKind::Corners => band == min_level,
            ChunkKind::Charts | ChunkKind::Materials | ChunkKind::Image => true,
            ChunkKind::Attributes => band >= min_level,
        }
    }

    /// The kind's name in messages and `pmcodec info` (`keyframe`, `delta`, `positions`, ...).
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
            ChunkKind::Joints => "joints",
        }
    }
}

/// One index entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChunkEntry {
    /// What the chunk holds.
    pub kind: ChunkKind,
    /// The frame it belongs to (0 for per-file chunks).
    pub frame: u32,
    /// The band (level) it belongs to; an image's index for Image chunks.
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

/// The chunk index as readers hold it: every entry with its kind, frame, band and offset,
/// whichever way the file wrote it ([`Index::from_bytes`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Index {
    /// Every chunk, in file order (by offset).
    pub chunks: Vec<ChunkEntry>,
}

/// The chunk index of versions 3 to 6: postcard, every entry whole (about 15 bytes each, of
/// which kind, frame, band and offset can be told from the order; issue 17).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct IndexV6 {
    /// Every chunk, in file order, each entry with all its fields.
    pub chunks: Vec<ChunkEntry>,
}

impl From<IndexV6> for Index {
    fn from(v6: IndexV6) -> Self {
        Index { chunks: v6.chunks }
    }
}

/// Version 7 index entry tag: the kind in bits 0..5, bit 5 set when the raw length equals the
/// stored length (and is not written), the band above.
const TAG_KIND_BITS: u32 = 5;
const TAG_SAME_LEN: u32 = 1 << TAG_KIND_BITS;
const TAG_BAND_SHIFT: u32 = TAG_KIND_BITS + 1;
/// Bytes a version 7 entry takes at least: its tag, its stored length and its CRC.
const MIN_ENTRY_V7: usize = 6;

impl Index {
    /// Parses the index of a file of format `version` whose header declares `frames` frames.
    /// Version 7 (proto/container.md, "Index"): per frame, the count of its entries, then each
    /// entry's tag (kind, band, whether the raw length is the stored length), stored length,
    /// raw length unless the tag says it is the stored one, and CRC-32 (4 bytes, little-endian);
    /// offsets follow from the order, every chunk starting where the one before ends. Every
    /// count is checked against what the rest of the bytes can hold before anything is sized
    /// from it.
    pub fn from_bytes(bytes: &[u8], version: u16, frames: u32) -> Result<Index, crate::ContainerError> {
        let corrupt = |detail: String| crate::ContainerError::Corrupt { what: "index".into(), detail };
        if version < 7 {
            return postcard::from_bytes::<IndexV6>(bytes).map(Index::from).map_err(|e| corrupt(e.to_string()));
        }
        let mut c = crate::payload::Cursor::new(bytes, "index");
        let mut chunks = Vec::new();
        let mut offset = 0u64;
        for frame in 0..frames {
            let n = c.count_within(u32::MAX as u64, MIN_ENTRY_V7, "chunks")?;
            chunks.reserve(n);
            for _ in 0..n {
                let tag = c.get()?;
                let kind = ChunkKind::try_from(tag & (TAG_SAME_LEN - 1)).map_err(corrupt)?;
                let stored_len = c.get()?;
                let raw_len = if tag & TAG_SAME_LEN != 0 { stored_len } else { c.get()? };
                let crc32 = c.u32_le()?;
                chunks.push(ChunkEntry { kind, frame, band: tag >> TAG_BAND_SHIFT, offset, stored_len, raw_len, crc32 });
                offset += stored_len as u64;
            }
        }
        c.finish()?;
        Ok(Index { chunks })
    }

    /// Parses a whole index of a file of format `version` with preamble `flags` and
    /// `table_len`, whose header declares `frames` frames and `levels` levels: a banded one
    /// ([`FLAG_BANDS`]) group after group, each group's CRC checked, its entries then put in
    /// [`frame_order`]; others as [`Index::from_bytes`].
    pub fn from_file(
        bytes: &[u8],
        version: u16,
        flags: u16,
        table_len: u32,
        frames: u32,
        levels: usize,
    ) -> Result<Index, crate::ContainerError> {
        if flags & FLAG_BANDS == 0 || version < 7 {
            return Index::from_bytes(bytes, version, frames);
        }
        let corrupt = |detail: String| crate::ContainerError::Corrupt { what: "index".into(), detail };
        let table = bytes.get(..table_len as usize).ok_or_else(|| corrupt(format!("a table of {table_len} bytes in {}", bytes.len())))?;
        let rows = parse_table(table, levels)?;
        let (mut at, mut offset) = (table_len as usize, 0u64);
        let mut chunks = Vec::new();
        for (g, row) in rows.iter().enumerate() {
            let body = at
                .checked_add(row.body_len as usize)
                .and_then(|end| bytes.get(at..end))
                .ok_or_else(|| corrupt("groups beyond its end".into()))?;
            chunks.extend(parse_group(body, g, row, offset, levels, frames)?);
            at += row.body_len as usize;
            offset += row.chunks_len as u64;
        }
        if at != bytes.len() {
            return Err(corrupt(format!("{} bytes after its last group", bytes.len() - at)));
        }
        frame_order(&mut chunks);
        Ok(Index { chunks })
    }

    /// The index as a file of format `version` stores it, for a header of `frames` frames.
    /// Version 7 groups entries by frame and implies offsets from the order, so it writes what
    /// it can of entries that break that layout (a frame out of order joins the frame before;
    /// offsets are dropped; a frame at or beyond `frames` joins the last frame, so that the
    /// index takes bytes for the entries and frames there are, not for a frame number up to
    /// 2^32): the encoder never makes such entries, and the test support's damage does on purpose.
    pub fn to_bytes(&self, version: u16, frames: u32) -> Result<Vec<u8>, postcard::Error> {
        if version < 7 {
            return postcard::to_stdvec(&IndexV6 { chunks: self.chunks.clone() });
        }
        let span = if frames == 0 { u32::from(!self.chunks.is_empty()) } else { frames };
        let mut out = Vec::with_capacity(8 * self.chunks.len() + span as usize);
        let mut rest = self.chunks.as_slice();
        for frame in 0..span {
            let n = if frame + 1 == span { rest.len() } else { rest.iter().take_while(|e| e.frame <= frame).count() };
            let (group, after) = rest.split_at(n);
            rest = after;
            crate::payload::put(&mut out, n as u32);
            for e in group {
                let same = if e.raw_len == e.stored_len { TAG_SAME_LEN } else { 0 };
                crate::payload::put(&mut out, u32::from(e.kind) | same | e.band << TAG_BAND_SHIFT);
                crate::payload::put(&mut out, e.stored_len);
                if same == 0 {
                    crate::payload::put(&mut out, e.raw_len);
                }
                out.extend_from_slice(&e.crc32.to_le_bytes());
            }
        }
        Ok(out)
    }
}

mod banded;
pub use banded::{
    GroupRow, banded_index, file_order, frame_order, group_count, group_name, group_of, groups_for, parse_group, parse_table,
};

#[cfg(test)]
#[path = "format_tests.rs"]
mod tests;
