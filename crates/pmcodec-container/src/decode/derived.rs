//! The decoder's derived topology (proto/container.md, "Faces", coding 2): a band whose faces
//! and corner updates its reader derives from the input triangles and the Key and Delta chunks
//! of the bands below it ([`crate::derive`]).

use super::Decoder;
use crate::derive::{Below, LevelMoves};
use crate::format::ChunkKind;
use crate::payload;
use crate::{ByteSource, ContainerError};

impl<S: ByteSource> Decoder<S> {
    /// The input triangles from the Triangles chunk.
    pub(super) fn read_triangles(&self) -> Result<Vec<[u32; 3]>, ContainerError> {
        let h = self.reader.header();
        let e = self
            .reader
            .index()
            .chunks
            .iter()
            .find(|e| e.kind == ChunkKind::Triangles)
            .ok_or_else(|| ContainerError::Corrupt { what: "index".into(), detail: "no triangles chunk".into() })?;
        let raw = self.reader.read_chunk(e)?;
        payload::read_triangles(&raw, "triangles chunk", h.triangle_count, h.vertex_count, self.reader.version())
    }

    /// Band j's parent map at keyframe `frame`. A Key chunk in coding 3 (the changes from
    /// frame 0's parent map, proto/container.md "Key") reads frame 0's Key chunk of the band too.
    pub(super) fn read_parents(&self, frame: u32, j: usize) -> Result<Vec<u32>, ContainerError> {
        let (sizes, version) = (&self.reader.header().level_sizes, self.reader.version());
        let raw = self.chunk(ChunkKind::Key, frame, j)?;
        let what = format!("frame {frame} band {j} keyframe");
        if frame > 0 && payload::key_from_first(&raw) {
            let first = payload::read_key(&self.chunk(ChunkKind::Key, 0, j)?, &format!("frame 0 band {j} keyframe"), sizes, j, version)?;
            return payload::read_key_from(&raw, &what, sizes, j, version, Some(&first));
        }
        payload::read_key(&raw, &what, sizes, j, version)
    }

    /// The levels below `min_level` at keyframe `frame`, for a band whose faces are derived:
    /// the input triangles and the keyframe's Key chunks of bands 0..min_level.
    pub(super) fn derive_below(&self, frame: u32) -> Result<Below, ContainerError> {
        let fine = match &self.fine {
            Some(t) => t.clone(),
            None => std::sync::Arc::new(self.read_triangles()?),
        };
        let mut parents = Vec::with_capacity(self.min_level);
        for j in 0..self.min_level {
            parents.push(self.read_parents(frame, j)?);
        }
        Ok(Below::new(fine, parents))
    }

    /// In a derived interval, frame `frame`'s moves of the levels below `min_level` (top
    /// first), after checking that the band's Corners chunk says nothing; empty otherwise.
    pub(super) fn below_moves(&self, frame: u32) -> Result<LevelMoves, ContainerError> {
        let mut moves = Vec::new();
        if self.below.is_none() {
            return Ok(moves);
        }
        let j = self.min_level;
        if self.reader.find(ChunkKind::Corners, frame, j as u32).is_some() && self.chunk(ChunkKind::Corners, frame, j)? != [0] {
            return Err(ContainerError::Corrupt {
                what: format!("frame {frame} band {j} corners"),
                detail: "corner updates in an interval whose faces are derived".into(),
            });
        }
        let sizes = &self.reader.header().level_sizes;
        for i in (0..j).rev() {
            let raw = self.chunk(ChunkKind::Delta, frame, i)?;
            moves.push((i, payload::read_delta(&raw, &format!("frame {frame} band {i} delta"), sizes, i)?));
        }
        Ok(moves)
    }
}
