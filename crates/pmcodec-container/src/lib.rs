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

pub mod appearance;
mod decode;
mod encode;
pub mod format;
pub mod payload;
pub mod predict;
pub mod rans;
mod read;
pub mod skin;
#[cfg(feature = "test-support")]
pub mod testing;

pub use decode::Decoder;
pub use encode::{
    EncodeOptions, EncodeReport, PaletteCoding, QuantizationChoice, SkinPlacement, StreamError, encode, encode_stream, encode_until,
    encode_with_report, write_file,
};
pub use format::{ChunkEntry, ChunkKind, Header, Index, Motion, VertexOrder};
pub use pmcodec_hierarchy::{CutTarget, Distance};
pub use predict::coarse_shift;
pub use read::{ByteSource, FileSource, Reader};

use serde::Serialize;

/// Everything that can go wrong reading or writing a container. Messages name the region or
/// chunk at fault ("frame 12 band 3 positions: checksum mismatch").
#[derive(Debug, thiserror::Error)]
pub enum ContainerError {
    #[error("I/O: {0}")]
    Io(String),
    #[error("not a .pmc file (bad magic number)")]
    BadMagic,
    #[error("container version {0} is not supported (this build reads versions {o} to {v})", o = format::OLDEST_READABLE, v = format::VERSION)]
    UnsupportedVersion(u16),
    #[error("{what}: the file ends before it does")]
    Truncated { what: String },
    #[error("{what}: checksum mismatch")]
    Checksum { what: String },
    #[error("{what}: {detail}")]
    Corrupt { what: String, detail: String },
    #[error("invalid input: {0}")]
    Mesh(#[from] pmcodec_mesh::MeshError),
    #[error("building the hierarchy: {0}")]
    Build(#[from] pmcodec_hierarchy::BuildError),
    #[error("{what}: {source}")]
    Delta { what: String, source: pmcodec_hierarchy::progressive::DeltaError },
    #[error("invalid options: {0}")]
    Options(String),
    #[error("{bytes} bytes after the end of the container (its last chunk ends before the file does)")]
    TrailingBytes { bytes: u64 },
    #[error("encoding cancelled")]
    Cancelled,
    #[error("frame {frame} is beyond the {frames} frames of the file")]
    NoSuchFrame { frame: u32, frames: u32 },
}

/// Byte counts of a file by chunk kind and band, and the figures derived from them.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub header: Header,
    pub file_bytes: u64,
    pub preamble_header_index_bytes: u64,
    pub triangles_bytes: u64,
    /// Per band (index = level): stored bytes of key, delta (swaps), positions, faces and
    /// corners chunks.
    pub key_bytes: Vec<u64>,
    pub faces_bytes: Vec<u64>,
    pub corners_bytes: Vec<u64>,
    pub delta_bytes: Vec<u64>,
    pub positions_bytes: Vec<u64>,
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
    pub delta_raw_bytes_per_frame: f64,
    /// Bytes a client stopping at each level reads per frame (swaps and positions of bands >=
    /// level, and the corner updates of its own level).
    pub bytes_per_frame_to_level: Vec<f64>,
    /// Appearance (version 6), stored bytes: the charts, the attribute table per band, the
    /// materials, and the images.
    pub charts_bytes: u64,
    pub attributes_bytes: Vec<u64>,
    pub materials_bytes: u64,
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
    // Pose chunks (older files) go to every client; Palette chunks to the clients of their
    // band and finer.
    let read_by_all = s.pose_bytes - s.palette_bytes.iter().sum::<u64>();
    for l in 0..levels {
        let palettes: u64 = s.palette_bytes[l..].iter().sum();
        s.bytes_per_frame_to_level[l] = (s.delta_bytes[l..].iter().sum::<u64>()
            + s.positions_bytes[l..].iter().sum::<u64>()
            + s.corners_bytes[l]
            + read_by_all
            + palettes) as f64
            / frames;
    }
    s
}

/// What [`verify`] checked.
#[derive(Clone, Debug, Serialize)]
pub struct VerifyReport {
    pub chunks: usize,
    pub frames: u32,
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
