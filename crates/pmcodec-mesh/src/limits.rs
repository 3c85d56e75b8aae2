//! Bounds on what an input may expand to, checked while it is parsed.
//!
//! A few hundred kilobytes of zipped OBJ text or of glTF JSON can describe tens of millions of
//! vertices (a zip of two frames of ten million `v 0 0 0` lines is 233 KB), and every vertex
//! costs the encoder far more than its 12 bytes of position. The readers therefore stop at the
//! first vertex, triangle or frame past these limits, before the memory is taken, and say which
//! limit, file and line it was.

use crate::MeshError;
use serde::{Deserialize, Serialize};

/// What one input sequence may hold. Every reader checks these while it reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct InputLimits {
    /// Vertices in one frame (for glTF: vertex records read, before welding).
    pub max_vertices: usize,
    /// Triangles (after polygons are split into fans and strips into triangles).
    pub max_triangles: usize,
    /// Frames of the sequence (OBJ files, or glTF samples of the animation).
    pub max_frames: usize,
    /// Frames times vertices: the positions the sequence holds in memory.
    pub max_positions: usize,
}

impl Default for InputLimits {
    /// 4 Mi vertices, 8 Mi triangles, 100,000 frames, 64 Mi positions (768 MiB as `f32`).
    fn default() -> Self {
        InputLimits { max_vertices: 1 << 22, max_triangles: 1 << 23, max_frames: 100_000, max_positions: 1 << 26 }
    }
}

impl InputLimits {
    /// Checks a frame count known before any frame is read (the files of an OBJ sequence, the
    /// samples of an animation).
    pub fn check_frames(&self, frames: usize, at: &str) -> Result<(), MeshError> {
        if frames > self.max_frames {
            return Err(MeshError::LimitExceeded {
                at: at.to_string(),
                what: format!("{frames} frames"),
                limit: "max_frames",
                value: self.max_frames,
            });
        }
        Ok(())
    }

    /// Checks `frames` frames of `vertices` vertices each against both vertex limits.
    pub fn check_positions(&self, frames: usize, vertices: usize, at: &str) -> Result<(), MeshError> {
        self.check_frames(frames, at)?;
        if vertices > self.max_vertices {
            return Err(self.too_many_vertices(frames, self.max_vertices, at));
        }
        if frames.saturating_mul(vertices) > self.max_positions {
            return Err(self.too_many_vertices(frames, self.vertices_per_frame(frames), at));
        }
        Ok(())
    }

    /// Most vertices each of `frames` frames may have: the smaller of the vertex limit and the
    /// positions limit shared out over the frames.
    pub fn vertices_per_frame(&self, frames: usize) -> usize {
        self.max_vertices.min(self.max_positions / frames.max(1))
    }

    /// The error for a frame with more than `cap` vertices, `cap` being
    /// [`InputLimits::vertices_per_frame`]: names whichever limit made the cap.
    pub(crate) fn too_many_vertices(&self, frames: usize, cap: usize, at: &str) -> MeshError {
        if cap >= self.max_vertices {
            MeshError::LimitExceeded {
                at: at.to_string(),
                what: format!("more than {cap} vertices in a frame"),
                limit: "max_vertices",
                value: self.max_vertices,
            }
        } else {
            MeshError::LimitExceeded {
                at: at.to_string(),
                what: format!("{frames} frames of more than {cap} vertices (frames x vertices)"),
                limit: "max_positions",
                value: self.max_positions,
            }
        }
    }

    pub(crate) fn too_many_triangles(&self, at: &str) -> MeshError {
        MeshError::LimitExceeded {
            at: at.to_string(),
            what: format!("more than {} triangles", self.max_triangles),
            limit: "max_triangles",
            value: self.max_triangles,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_positions_limit_is_shared_out_over_the_frames() {
        let l = InputLimits { max_vertices: 100, max_triangles: 10, max_frames: 50, max_positions: 1000 };
        assert_eq!(l.vertices_per_frame(1), 100);
        assert_eq!(l.vertices_per_frame(20), 50);
        assert!(l.check_positions(10, 100, "x").is_ok());
        let e = l.check_positions(11, 100, "seq").unwrap_err().to_string();
        assert!(e.contains("seq") && e.contains("max_positions = 1000"), "{e}");
        let e = l.check_positions(1, 101, "seq").unwrap_err().to_string();
        assert!(e.contains("max_vertices = 100"), "{e}");
        let e = l.check_frames(51, "seq").unwrap_err().to_string();
        assert!(e.contains("51 frames") && e.contains("max_frames = 50"), "{e}");
    }
}
