use std::path::PathBuf;

/// Everything that can be wrong with an input sequence. Messages name the file, frame, face or
/// vertex at fault so that a user can find it.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// Reading or writing `path` failed. (The I/O error is part of the message, not a
    /// `source`, so that error chains do not print it twice.)
    #[error("{path}: {error}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What the operating system said.
        error: std::io::Error,
    },
    /// A line of an OBJ or MTL file could not be read (`line` is 1-based; 0 for the file as a
    /// whole, such as text that is not UTF-8).
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number, 0 for the whole file.
        line: usize,
        /// What is wrong on that line.
        message: String,
    },
    /// A path, folder or glob names no input file (the text says which and why).
    #[error("no frames: {0}")]
    NoInput(String),
    /// A sequence with zero frames was handed to [`crate::Sequence::validate`].
    #[error("the sequence has no frames")]
    NoFrames,
    /// The mesh has no vertices or no triangles; `what` says which.
    #[error("the mesh is empty: {what}")]
    Empty {
        /// What is missing.
        what: String,
    },
    /// A count does not fit the format or the arrays built from it (a GLB over 4 GiB, a glTF
    /// accessor whose byte size overflows, a skin with more joints than 16-bit indices hold).
    #[error("the mesh is too large: {what}")]
    TooLarge {
        /// What is too large, with its size.
        what: String,
    },
    /// The input goes past one of the [`crate::InputLimits`]; `at` is the file and line, or
    /// the file and frame, where the reader stopped.
    #[error("{at}: {what}, past the input limit {limit} = {value}")]
    LimitExceeded {
        /// Where the reader stopped: file and line, or file and frame.
        at: String,
        /// What was being counted.
        what: String,
        /// The [`crate::InputLimits`] field that was passed.
        limit: &'static str,
        /// That field's value.
        value: usize,
    },
    /// A frame's vertex count, face count or faces differ from frame 0's: a [`crate::Sequence`]
    /// has one connectivity.
    #[error("frame {frame} does not match frame 0: {detail}")]
    FrameMismatch {
        /// The frame's name (file name or `anim@time`).
        frame: String,
        /// What differs.
        detail: String,
    },
    /// A position is NaN or infinite; every later stage assumes finite coordinates.
    #[error("frame {frame}: vertex {vertex} has a NaN or infinite coordinate")]
    NonFinite {
        /// The frame's name.
        frame: String,
        /// The vertex, 0-based.
        vertex: u32,
    },
    /// A face names a vertex that does not exist.
    #[error("face {face} uses vertex {index}, but there are only {vertex_count} vertices")]
    IndexOutOfRange {
        /// The face, 0-based.
        face: u32,
        /// The index it uses.
        index: u32,
        /// Vertices there are.
        vertex_count: u32,
    },
    /// A face uses one vertex twice: zero area, and no valid edge-collapse topology.
    #[error("face {face} repeats a corner: {corners:?}")]
    DegenerateFace {
        /// The face, 0-based.
        face: u32,
        /// Its three vertex indices.
        corners: [u32; 3],
    },
    /// The glTF document is malformed (bad JSON, an accessor out of its buffer, a missing
    /// index); the message names the file and the object.
    #[error("glTF: {0}")]
    Gltf(String),
    /// The glTF file is valid but uses what this reader does not support (a version other
    /// than 2.x, a required extension it does not know, a non-base64 data URI).
    #[error("unsupported glTF feature: {0}")]
    Unsupported(String),
    /// Anything else that makes the input or a request unusable (an appearance whose arrays
    /// disagree, a frame rate that is not positive, an output path that names no file).
    #[error("{0}")]
    Invalid(String),
    /// An animation was asked for by a name or index the file does not have.
    #[error("no animation {wanted} in the file; it has: {}", list_or_none(available))]
    NoSuchAnimation {
        /// The name or index asked for.
        wanted: String,
        /// The labels of the animations the file has.
        available: Vec<String>,
    },
}

fn list_or_none(items: &[String]) -> String {
    if items.is_empty() { "none".to_string() } else { items.join(", ") }
}
