//! glTF 2.0 / GLB input: skinned and morph-target meshes posed by an animation and sampled at a
//! frame rate into a [`Sequence`].
//!
//! # What is read
//!
//! * **Scene.** Every mesh node of the default scene (`scene`, else the first scene, else every
//!   root node) is merged into one vertex and face set. Nodes are visited depth first in
//!   pre-order (the scene's `nodes` in order, then each node's `children` in order) and, within a
//!   node, its mesh's primitives in order. [`SourceVertex::primitive`] numbers primitives in that
//!   visiting order, so a mesh instanced by two nodes contributes its primitives twice, under two
//!   numbers; [`RiggedMesh::primitives`] says which node, mesh and primitive each number is.
//! * **Posing.** A mesh node with a skin is posed by linear blend skinning (glTF 2.0 §3.7.3): each
//!   joint matrix is the joint's world transform times its inverse bind matrix, and the skinned
//!   node's own transform is ignored, as the specification requires. Other mesh nodes get their
//!   world transform. Morph targets (§3.7.2.2) are applied first, in the mesh's space, and then
//!   the skin.
//! * **Appearance.** Each primitive's `TEXCOORD_0`/`_1`, `NORMAL` and `COLOR_0` (every component
//!   type the specification allows, normalised integers mapped to [0, 1] or [-1, 1]) become one
//!   wedge per authored vertex of [`RiggedMesh::appearance`], with the primitive's material per
//!   triangle (glTF's default material for a primitive without one). Materials keep the
//!   metallic-roughness core, texture references with `KHR_texture_transform`, alpha mode and
//!   double-sidedness; images are kept as their PNG or JPEG bytes (from a bufferView, a `data:`
//!   URI, or a file beside the glTF when it is read from a path). A primitive missing an
//!   attribute others have gets the defaults: UV (0, 0), white, its surface's own normals.
//! * **Animation.** Frames are taken at `t = i / frame_rate` for `i` in `0..=floor(duration *
//!   frame_rate)` (computed in `f32`), where the duration is the largest keyframe time of the
//!   animation's channels; a file without animations gives one frame, the rest pose. Sampling
//!   follows §3.11 and Appendix C: STEP, LINEAR (rotations by spherical interpolation on the
//!   shorter arc) and CUBICSPLINE (Hermite, tangents scaled by the key interval), clamped to the
//!   first and last key outside the keyed range.
//! * **Compressed geometry.** `KHR_draco_mesh_compression` primitives and
//!   `EXT_meshopt_compression` / `KHR_meshopt_compression` bufferViews are decoded when the file
//!   is parsed (see the `draco` and `meshopt` modules), into the same accessor and bufferView
//!   bytes an uncompressed file has: every accessor read (positions, indices, skins, morph
//!   targets, UVs, normals, colours, animation keys) sees decoded data without knowing it was
//!   compressed. Morph targets of a Draco primitive stay plain accessors, as the extension says.
//! * **Welding.** Exporters split vertices at UV and normal seams, and some write every triangle
//!   with its own three vertices, which leaves a surface in pieces. [`RiggedMesh::weld`] merges
//!   vertices that land on the same bits in every pose: same rest position, same skin influences,
//!   same morph deltas and the same transform (the same mesh node, or the same skin for
//!   skinned vertices without morph deltas). Triangles that then repeat a corner are dropped.
//!   Vertices no triangle uses are always dropped: several primitives often index different
//!   parts of one shared vertex buffer. Welding ignores UVs, normals and colours: positions
//!   weld across seams, the wedges keep their attributes and move to the merged vertex, and
//!   wedges of one vertex with equal attributes merge.
//!
//! # Hostile input
//!
//! Uploads reach this code, so nothing here trusts the file. The document is deserialised with
//! `gltf`'s JSON types but not walked with `gltf`'s convenience wrappers: those unwrap indices
//! the validator never checks (animation channel targets), underflow on accessors with
//! `count: 0`, and hit `unreachable!()` on unexpected component types. Every index, length,
//! stride and component type is checked here instead, and buffers (including GLB chunks and
//! `data:` URIs) are decoded here. A file path may only reference buffers inside its own folder.
//! Compressed data is decoded only to the sizes its accessors and views declare, checked first
//! against the input limits (Draco) or a cap on decoded bytes (meshopt); a truncated or corrupt
//! stream is an error naming its primitive or bufferView.

use crate::{InputLimits, MeshError, Sequence, SourceVertex};
use glam::{Mat4, Quat, Vec3, Vec4};
use gltf::json;
use json::accessor::{ComponentType, GenericComponentType, IndexComponentType, Type};
use json::validation::Checked;
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Component, Path, PathBuf};

mod animation;
#[cfg(test)]
mod compressed_tests;
mod draco;
mod file;
mod looks;
mod looks_raw;
mod meshopt;
mod rigged;
mod sampler;
mod scene;
#[cfg(test)]
mod tests;

use self::animation::*;
pub use self::animation::{AnimatedProperty, Animation, Channel, Interpolation};
use self::draco::*;
use self::file::*;
use self::looks::*;
use self::meshopt::*;
pub use self::rigged::*;
pub use self::sampler::FrameSampler;
use self::scene::*;

// ------------------------------------------------------------------------------------------------
// Public options and entry points
// ------------------------------------------------------------------------------------------------

/// Which animation of a file to sample.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AnimationSelector {
    /// The animation at this position in the file's `animations` array.
    Index(usize),
    /// The first animation with exactly this name.
    Name(String),
}

/// How to read a glTF file into a [`Sequence`].
#[derive(Clone, Debug, PartialEq)]
pub struct GltfOptions {
    /// The animation to sample; `None` takes the first. A file without animations gives one
    /// frame, the rest pose, unless an animation is asked for, which is then an error.
    pub animation: Option<AnimationSelector>,
    /// Frames per second at which the animation is sampled (default 30).
    pub frame_rate: f32,
    /// Merge vertices that coincide in every pose so that the surface is connected (default on;
    /// see [`RiggedMesh::weld`]).
    pub weld: bool,
    /// What the file may expand to: vertices and triangles are checked as each primitive is
    /// read, frames and frames times vertices before the animation is sampled.
    pub limits: InputLimits,
}

impl Default for GltfOptions {
    fn default() -> Self {
        GltfOptions { animation: None, frame_rate: 30.0, weld: true, limits: InputLimits::default() }
    }
}

/// An animation as listed by [`list_animations`].
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationInfo {
    /// Position in the file's `animations` array.
    pub index: usize,
    /// The animation's name, if it has one.
    pub name: Option<String>,
    /// Largest keyframe time over its channels, in seconds.
    pub duration: f32,
}

/// Reads a `.glb` or `.gltf` file and samples the chosen animation.
///
/// External buffers of a `.gltf` are read from the file's folder (never from outside it).
pub fn load_gltf(path: &Path, opts: &GltfOptions) -> Result<Sequence, MeshError> {
    let file = GltfFile::open(path, &opts.limits)?;
    file_to_sequence(&file, opts).map_err(|e| at_path(path, e))
}

/// Reads a GLB, or a `.gltf` whose buffers are embedded as `data:` URIs, from memory (uploads).
/// A `.gltf` that references external files can only be read from a path.
pub fn load_gltf_bytes(bytes: &[u8], opts: &GltfOptions) -> Result<Sequence, MeshError> {
    file_to_sequence(&GltfFile::parse(bytes, None, &opts.limits)?, opts)
}

/// Every animation of a file, in file order, with its duration.
pub fn list_animations(path: &Path) -> Result<Vec<AnimationInfo>, MeshError> {
    let file = GltfFile::open(path, &InputLimits::default())?;
    animation_infos(&file).map_err(|e| at_path(path, e))
}

/// [`list_animations`] for a file in memory.
pub fn list_animations_bytes(bytes: &[u8]) -> Result<Vec<AnimationInfo>, MeshError> {
    animation_infos(&GltfFile::parse(bytes, None, &InputLimits::default())?)
}

fn animation_infos(file: &GltfFile) -> Result<Vec<AnimationInfo>, MeshError> {
    let targets = morph_target_counts(&file.root);
    Ok(read_animations(file, &targets)?.into_iter().map(|a| AnimationInfo { index: a.index, name: a.name, duration: a.duration }).collect())
}

fn file_to_sequence(file: &GltfFile, opts: &GltfOptions) -> Result<Sequence, MeshError> {
    let mut rig = RiggedMesh::from_file(file, &opts.limits)?;
    if opts.weld {
        rig.weld();
    }
    let animation = match &opts.animation {
        Some(selector) => Some(rig.find_animation(selector)?),
        None => (!rig.animations.is_empty()).then_some(0),
    };
    rig.to_sequence_with(animation, opts.frame_rate, &opts.limits)
}

/// Names the file in messages about its content (I/O errors name it already).
fn at_path(path: &Path, e: MeshError) -> MeshError {
    match e {
        MeshError::Gltf(m) => MeshError::Gltf(format!("{}: {m}", path.display())),
        e => e,
    }
}

fn gltf_error(message: impl Into<String>) -> MeshError {
    MeshError::Gltf(message.into())
}
