//! Deforming-mesh sequences: one triangle connectivity, many frames of positions.
//!
//! This crate is the input and output edge of pmcodec. It reads OBJ sequences ([`obj`]) and
//! animated glTF/GLB files ([`gltf_input`]), validates them ([`Sequence::validate`]), and writes
//! single frames as OBJ or GLB ([`mod@write`]). Everything downstream (the hierarchy, the container,
//! the server) works on [`Sequence`] and [`TriMesh`] and never touches files itself.

#![warn(missing_docs)]
// `!(x > 0.0)` is written on purpose: it is also true for NaN, which these checks must reject.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod appearance;
pub mod binmesh;
mod error;
pub mod glb;
pub mod gltf_input;
mod limits;
pub mod obj;
pub mod rig_glb;
pub mod samples;
pub mod skin;
pub mod skin_fit;
pub mod write;

pub use appearance::Appearance;
pub use error::MeshError;
use glam::Vec3;
pub use limits::InputLimits;
pub use skin::SequenceSkin;

/// An indexed triangle mesh: the unit every writer and every measurement works on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, in the input's units.
    pub positions: Vec<Vec3>,
    /// Counter-clockwise triangles indexing `positions`.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Axis-aligned bounding box `(min, max)`; `None` for a mesh without vertices.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        bounds_of(&self.positions)
    }

    /// Length of the bounding-box diagonal (0 for an empty mesh).
    pub fn diagonal(&self) -> f32 {
        self.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length())
    }
}

/// Axis-aligned bounding box of a point set.
pub fn bounds_of(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
}

/// Where a vertex of a merged [`Sequence`] came from in its source file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SourceVertex {
    /// Index of the glTF primitive (in the order the mesh lists them); 0 for OBJ input.
    pub primitive: u32,
    /// Vertex index inside that primitive (or the OBJ file).
    pub index: u32,
}

/// A deforming triangle mesh: every frame has the same vertices and the same faces.
#[derive(Clone, Debug, Default)]
pub struct Sequence {
    /// Shared connectivity, counter-clockwise triangles indexing into each frame.
    pub triangles: Vec<[u32; 3]>,
    /// `frames[f][v]` is the position of vertex `v` in frame `f`.
    pub frames: Vec<Vec<Vec3>>,
    /// Playback rate in frames per second.
    pub frame_rate: f32,
    /// For each vertex, where it came from. Empty when the vertices are the source's own, in order.
    pub source: Vec<SourceVertex>,
    /// Per-vertex importance from the input itself (for example morph-target displacement,
    /// Berner & Rieger); empty when the input has none.
    pub morph_displacement: Vec<f32>,
    /// Human-readable names of the frames (file names for OBJ, `anim@time` for glTF).
    pub frame_names: Vec<String>,
    /// Texture coordinates, colours, input normals and materials, the same in every frame;
    /// `None` for a bare surface. Its `corner_wedges` are parallel to `triangles`.
    pub appearance: Option<Appearance>,
    /// The skin that poses every frame (joint palette, influences, rest positions, matrices
    /// per frame); `None` when the input is not skinned.
    pub skin: Option<SequenceSkin>,
}

impl Sequence {
    /// Vertices per frame (0 for a sequence without frames).
    pub fn vertex_count(&self) -> usize {
        self.frames.first().map_or(0, Vec::len)
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// Frame `f` as an indexed mesh (copies positions and faces).
    pub fn frame_mesh(&self, f: usize) -> Option<TriMesh> {
        Some(TriMesh { positions: self.frames.get(f)?.clone(), triangles: self.triangles.clone() })
    }

    /// Checks everything the rest of pmcodec relies on: at least one frame, at least one
    /// triangle, every frame of the same length, finite positions, indices in range, and no
    /// triangle that repeats a corner. The error names the first offending frame, vertex or face.
    pub fn validate(&self) -> Result<(), MeshError> {
        if self.frames.is_empty() {
            return Err(MeshError::NoFrames);
        }
        let n = self.frames[0].len();
        if n == 0 {
            return Err(MeshError::Empty { what: "no vertices".into() });
        }
        if self.triangles.is_empty() {
            return Err(MeshError::Empty { what: "no triangles".into() });
        }
        if n > u32::MAX as usize / 2 {
            return Err(MeshError::TooLarge { what: format!("{n} vertices") });
        }
        for (f, frame) in self.frames.iter().enumerate() {
            if frame.len() != n {
                return Err(MeshError::FrameMismatch {
                    frame: self.frame_label(f),
                    detail: format!("{} vertices where frame 0 has {n}", frame.len()),
                });
            }
            if let Some(v) = frame.iter().position(|p| !p.is_finite()) {
                return Err(MeshError::NonFinite { frame: self.frame_label(f), vertex: v as u32 });
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::IndexOutOfRange { face: t as u32, index: i, vertex_count: n as u32 });
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(MeshError::DegenerateFace { face: t as u32, corners: *tri });
            }
        }
        if !(self.frame_rate.is_finite() && self.frame_rate > 0.0) {
            return Err(MeshError::Invalid(format!("frame rate {} is not a positive number", self.frame_rate)));
        }
        if !self.morph_displacement.is_empty() && self.morph_displacement.len() != n {
            return Err(MeshError::Invalid(format!("{} morph displacement weights for {n} vertices", self.morph_displacement.len())));
        }
        if let Some(skin) = &self.skin {
            skin.validate(n, self.frames.len())?;
        }
        if let Some(appearance) = &self.appearance {
            appearance.validate(n, &self.triangles)?;
        }
        Ok(())
    }

    /// Bounding box over all frames.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.frames.iter().filter_map(|f| bounds_of(f)).reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    }

    fn frame_label(&self, f: usize) -> String {
        match self.frame_names.get(f) {
            Some(name) => format!("{f} ({name})"),
            None => f.to_string(),
        }
    }
}
