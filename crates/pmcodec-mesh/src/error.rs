use std::path::PathBuf;

/// Everything that can be wrong with an input sequence. Messages name the file, frame, face or
/// vertex at fault so that a user can find it.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// Reading or writing `path` failed. (The I/O error is part of the message, not a
    /// `source`, so that error chains do not print it twice.)
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    #[error("{path}:{line}: {message}")]
    Parse { path: PathBuf, line: usize, message: String },
    #[error("no frames: {0}")]
    NoInput(String),
    #[error("the sequence has no frames")]
    NoFrames,
    #[error("the mesh is empty: {what}")]
    Empty { what: String },
    #[error("the mesh is too large: {what}")]
    TooLarge { what: String },
    /// The input goes past one of the [`crate::InputLimits`]; `at` is the file and line, or
    /// the file and frame, where the reader stopped.
    #[error("{at}: {what}, past the input limit {limit} = {value}")]
    LimitExceeded { at: String, what: String, limit: &'static str, value: usize },
    #[error("frame {frame} does not match frame 0: {detail}")]
    FrameMismatch { frame: String, detail: String },
    #[error("frame {frame}: vertex {vertex} has a NaN or infinite coordinate")]
    NonFinite { frame: String, vertex: u32 },
    #[error("face {face} uses vertex {index}, but there are only {vertex_count} vertices")]
    IndexOutOfRange { face: u32, index: u32, vertex_count: u32 },
    #[error("face {face} repeats a corner: {corners:?}")]
    DegenerateFace { face: u32, corners: [u32; 3] },
    #[error("glTF: {0}")]
    Gltf(String),
    #[error("unsupported glTF feature: {0}")]
    Unsupported(String),
    #[error("{0}")]
    Invalid(String),
    /// An animation was asked for by a name or index the file does not have.
    #[error("no animation {wanted} in the file; it has: {}", list_or_none(available))]
    NoSuchAnimation { wanted: String, available: Vec<String> },
}

fn list_or_none(items: &[String]) -> String {
    if items.is_empty() { "none".to_string() } else { items.join(", ") }
}
