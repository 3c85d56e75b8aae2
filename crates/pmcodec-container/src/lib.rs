//! The `.pmc` container of pmcodec: a progressive multiresolution deforming mesh (Kircher &
//! Garland section 5) stored as keyframes, per-frame topology deltas and quantized node
//! positions, organised by band so that a reader fetching with HTTP range requests reads only
//! the levels it needs. The byte format is specified in `proto/container.md`.
//!
//! - [`encode`] turns a [`pmcodec_mesh::Sequence`] into file bytes.
//! - [`Reader`] opens any [`ByteSource`] (a slice, a file, an HTTP client) and checks and
//!   decompresses chunks; [`Decoder`] replays frames and extracts meshes at any cut.
//! - [`verify`] and [`summary`] back the CLI's `verify` and `info`.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod appearance;
mod bits;
mod decode;
mod derive;
mod encode;
pub mod format;
mod grid;
pub mod payload;
pub mod predict;
mod rans;
mod read;
mod skin;
pub mod streams;
#[cfg(feature = "test-support")]
pub mod testing;
mod topology;

pub use decode::{BudgetCut, BudgetPriorities, Decoder, banded_priority};
pub use derive::{derives, reads};
pub use encode::{
    DerivedTopology, EncodeOptions, EncodeReport, FRAMES_AHEAD, PaletteCoding, QuantizationChoice, SkinPlacement, SkinTrial, StreamError,
    encode, encode_posed, encode_stream, encode_until, encode_with_report, skin_trial, write_file,
};
pub use format::{ChunkEntry, ChunkKind, Header, Index, Motion, VertexOrder};
pub use pmcodec_hierarchy::{CutTarget, Distance};
pub use predict::coarse_shift;
pub use read::{ByteSource, FileSource, Reader};
pub use skin::{NodeSkin, SkinHeader, SkinnedCoarse, bind_position, influences, palette_transforms};

use serde::Serialize;

/// Everything that can go wrong reading or writing a container. Messages name the region or
/// chunk at fault ("frame 12 band 3 positions: checksum mismatch").
#[derive(Debug, thiserror::Error)]
pub enum ContainerError {
    /// An I/O error of the byte source, or a value that could not be serialized while writing.
    #[error("I/O: {0}")]
    Io(String),
    /// The first 8 bytes are not [`format::MAGIC`].
    #[error("not a .pmc file (bad magic number)")]
    BadMagic,
    /// The preamble's version is outside [`format::OLDEST_READABLE`]..=[`format::VERSION`].
    #[error("container version {0} is not supported (this build reads versions {o} to {v})", o = format::OLDEST_READABLE, v = format::VERSION)]
    UnsupportedVersion(u16),
    /// A region (preamble, header, index, a chunk) reaches past the end of the source.
    #[error("{what}: the file ends before it does")]
    Truncated {
        /// The region, as in "frame 12 band 3 positions".
        what: String,
    },
    /// A region's CRC-32 does not match its bytes.
    #[error("{what}: checksum mismatch")]
    Checksum {
        /// The region.
        what: String,
    },
    /// A region passed its checksum but its contents break the format (a count over the
    /// header's, an id out of range, a chunk the index lacks, bytes left over).
    #[error("{what}: {detail}")]
    Corrupt {
        /// The region.
        what: String,
        /// What is wrong in it.
        detail: String,
    },
    /// The input sequence failed [`pmcodec_mesh::Sequence::validate`] or the encoder's own checks.
    #[error("invalid input: {0}")]
    Mesh(#[from] pmcodec_mesh::MeshError),
    /// The hierarchy could not be built from the input (Kircher & Garland section 3).
    #[error("building the hierarchy: {0}")]
    Build(#[from] pmcodec_hierarchy::BuildError),
    /// A keyframe or topology delta did not apply to the replayed hierarchy (a file that
    /// passed its checksums but whose swaps are inconsistent).
    #[error("{what}: {source}")]
    Delta {
        /// The frame and chunk.
        what: String,
        /// What the replay refused.
        source: pmcodec_hierarchy::progressive::DeltaError,
    },
    /// The options or the request do not fit the input or the file (a quantization that does not
    /// fit 30 bits, an empty sequence, appearance asked of a file without one).
    #[error("invalid options: {0}")]
    Options(String),
    /// The source is longer than its last chunk's end (checked when a reader opens a whole file).
    #[error("{bytes} bytes after the end of the container (its last chunk ends before the file does)")]
    TrailingBytes {
        /// How many bytes follow the last chunk.
        bytes: u64,
    },
    /// The encoder's progress callback asked it to stop, or the input stream ended early.
    #[error("encoding cancelled")]
    Cancelled,
    /// A seek past the last frame.
    #[error("frame {frame} is beyond the {frames} frames of the file")]
    NoSuchFrame {
        /// The frame asked for.
        frame: u32,
        /// Frames in the file.
        frames: u32,
    },
}

/// Byte counts of a file by chunk kind and band, and the figures derived from them.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// The file's header, as read (migrated to today's version).
    pub header: Header,
    /// Length of the whole file.
    pub file_bytes: u64,
    /// Bytes before the chunk area: preamble, header and index.
    pub preamble_header_index_bytes: u64,
    /// Stored bytes of the input triangles chunk.
    pub triangles_bytes: u64,
    /// Per band (index = level): stored bytes of key, delta (swaps), positions, faces and
    /// corners chunks.
    pub key_bytes: Vec<u64>,
    /// Per band: stored bytes of Faces chunks.
    pub faces_bytes: Vec<u64>,
    /// Per band: stored bytes of Corners chunks.
    pub corners_bytes: Vec<u64>,
    /// Per band: stored bytes of Delta chunks (swaps).
    pub delta_bytes: Vec<u64>,
    /// Per band: stored bytes of Positions chunks.
    pub positions_bytes: Vec<u64>,
    /// Per band: bytes of Delta chunks after decompression.
    pub delta_raw_bytes: Vec<u64>,
    /// Per band: stored bytes of its nodes' skins (bind positions and influences).
    pub bind_bytes: Vec<u64>,
    /// Stored bytes of the joint palettes of every frame, all bands (Pose and Palette chunks).
    pub pose_bytes: u64,
    /// Stored bytes of the Palette chunks per band: a client stopping at level L reads bands
    /// L.. only (a file's older Pose chunks are read by every client, and counted in
    /// `pose_bytes` alone).
    pub palette_bytes: Vec<u64>,
    /// Positions, all bands, in bits per input vertex per frame.
    pub positions_bits_per_vertex_frame: f64,
    /// Topology deltas (swaps), all bands, per frame (compressed and raw): what a
    /// full-resolution client reads.
    pub delta_bytes_per_frame: f64,
    /// Topology deltas per frame before compression.
    pub delta_raw_bytes_per_frame: f64,
    /// Bytes a client stopping at each level reads per frame (swaps and positions of bands >=
    /// level, and the corner updates of its own level).
    pub bytes_per_frame_to_level: Vec<f64>,
    /// Appearance (version 6), stored bytes: the charts, the attribute table per band, the
    /// materials, and the images.
    pub charts_bytes: u64,
    /// Per band: stored bytes of its Attributes chunk.
    pub attributes_bytes: Vec<u64>,
    /// Stored bytes of the Materials chunk.
    pub materials_bytes: u64,
    /// Stored bytes of every Image chunk.
    pub image_bytes: u64,
}

/// Sizes and derived figures of an opened file.
pub fn summary<S: ByteSource>(reader: &Reader<S>) -> Summary {
    let h = reader.header().clone();
    let levels = h.levels();
    let mut s = Summary {
        file_bytes: reader.file_len(),
        preamble_header_index_bytes: reader.data_start(),
        triangles_bytes: 0,
        key_bytes: vec![0; levels],
        faces_bytes: vec![0; levels],
        corners_bytes: vec![0; levels],
        delta_bytes: vec![0; levels],
        positions_bytes: vec![0; levels],
        delta_raw_bytes: vec![0; levels],
        bind_bytes: vec![0; levels],
        pose_bytes: 0,
        palette_bytes: vec![0; levels],
        positions_bits_per_vertex_frame: 0.0,
        delta_bytes_per_frame: 0.0,
        delta_raw_bytes_per_frame: 0.0,
        bytes_per_frame_to_level: vec![0.0; levels],
        charts_bytes: 0,
        attributes_bytes: vec![0; levels],
        materials_bytes: 0,
        image_bytes: 0,
        header: h,
    };
    for e in &reader.index().chunks {
        let b = e.band as usize;
        if e.kind == ChunkKind::Image {
            s.image_bytes += e.stored_len as u64;
            continue;
        }
        if b >= levels {
            continue;
        }
        match e.kind {
            ChunkKind::Triangles => s.triangles_bytes += e.stored_len as u64,
            ChunkKind::Key => s.key_bytes[b] += e.stored_len as u64,
            ChunkKind::Faces => s.faces_bytes[b] += e.stored_len as u64,
            ChunkKind::Corners => s.corners_bytes[b] += e.stored_len as u64,
            ChunkKind::Delta => {
                s.delta_bytes[b] += e.stored_len as u64;
                s.delta_raw_bytes[b] += e.raw_len as u64;
            }
            ChunkKind::Positions => s.positions_bytes[b] += e.stored_len as u64,
            ChunkKind::Charts => s.charts_bytes += e.stored_len as u64,
            ChunkKind::Attributes => s.attributes_bytes[b] += e.stored_len as u64,
            ChunkKind::Materials => s.materials_bytes += e.stored_len as u64,
            ChunkKind::Image => {}
            ChunkKind::Bind => s.bind_bytes[b] += e.stored_len as u64,
            ChunkKind::Pose => s.pose_bytes += e.stored_len as u64,
            ChunkKind::Palette | ChunkKind::Joints => {
                s.pose_bytes += e.stored_len as u64;
                s.palette_bytes[b] += e.stored_len as u64;
            }
        }
    }
    let frames = s.header.frame_count.max(1) as f64;
    let pos: u64 = s.positions_bytes.iter().sum();
    s.positions_bits_per_vertex_frame = pos as f64 * 8.0 / (s.header.vertex_count.max(1) as f64 * frames);
    s.delta_bytes_per_frame = s.delta_bytes.iter().sum::<u64>() as f64 / frames;
    s.delta_raw_bytes_per_frame = s.delta_raw_bytes.iter().sum::<u64>() as f64 / frames;
    // Per frame: swaps, positions, corner updates and poses, as `Reader::reads` says a client
    // stopping at each level reads them (Pose chunks of older files go to every client, Palette
    // and Joints chunks to the clients of their band and finer, and a band whose faces are
    // derived reads the swaps below it).
    let per_frame = |e: &&ChunkEntry| {
        matches!(
            e.kind,
            ChunkKind::Delta | ChunkKind::Positions | ChunkKind::Corners | ChunkKind::Pose | ChunkKind::Palette | ChunkKind::Joints
        )
    };
    for l in 0..levels {
        let bytes: u64 = reader.index().chunks.iter().filter(per_frame).filter(|e| reader.reads(e, l)).map(|e| e.stored_len as u64).sum();
        s.bytes_per_frame_to_level[l] = bytes as f64 / frames;
    }
    s
}

/// What [`verify`] checked.
#[derive(Clone, Debug, Serialize)]
pub struct VerifyReport {
    /// Index entries whose chunk was read and checked.
    pub chunks: usize,
    /// Frames replayed.
    pub frames: u32,
    /// Length of the file.
    pub bytes: u64,
}

/// Checks every chunk's checksum and structure and replays every frame at full resolution.
pub fn verify<S: ByteSource>(reader: &Reader<S>) -> Result<VerifyReport, ContainerError> {
    for e in &reader.index().chunks {
        reader.read_chunk(e)?;
    }
    let mut d = Decoder::new(reader.borrowed(), 0)?;
    let frames = reader.header().frame_count;
    for f in 0..frames {
        d.seek(f)?;
    }
    // Seeking through keyframes must agree with playing through (spot check: the last frame).
    if frames > 1 {
        let mut fresh = Decoder::new(reader.borrowed(), 0)?;
        fresh.seek(frames - 1)?;
        if fresh.replay().map(|r| &r.h) != d.replay().map(|r| &r.h) {
            return Err(ContainerError::Corrupt { what: format!("frame {}", frames - 1), detail: "keyframe and deltas disagree".into() });
        }
    }
    Ok(VerifyReport { chunks: reader.index().chunks.len(), frames, bytes: reader.file_len() })
}
