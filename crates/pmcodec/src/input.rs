//! Loading a deforming sequence from whatever the user names: an OBJ folder, an OBJ glob, a
//! single OBJ, or a glTF/GLB file.

use crate::{EXIT_BAD_INPUT, Exit};
use anyhow::Context;
use clap::Args;
use pmcodec_mesh::gltf_input::{AnimationSelector, GltfOptions};
use pmcodec_mesh::{InputLimits, Sequence};
use std::path::Path;

/// Options that say how to read the input.
#[derive(Args, Clone, Debug)]
pub struct InputArgs {
    /// Frame rate: of the OBJ sequence, or at which a glTF animation is sampled.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f32,
    /// glTF animation to sample, by index or name (default: the first).
    #[arg(long)]
    pub animation: Option<String>,
}

/// The input as [`load`] reads it, except that an OBJ sequence's frames after the first are
/// left to the returned reader (each read and checked as it is asked for): so that `encode`
/// parses them while it encodes. glTF input is read whole (`None`).
pub fn open(path: &Path, args: &InputArgs) -> Result<(Sequence, Option<pmcodec_mesh::obj::ObjFrames>), Exit> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if ext == "glb" || ext == "gltf" {
        return Ok((load(path, args)?, None));
    }
    let limits = InputLimits::default();
    let opened = pmcodec_mesh::obj::frame_paths(path).and_then(|paths| {
        limits.check_frames(paths.len(), &path.display().to_string())?;
        pmcodec_mesh::obj::open_obj_files(&paths, args.fps, &limits)
    });
    let (head, rest) = opened.with_context(|| format!("reading {}", path.display())).map_err(|e| Exit(EXIT_BAD_INPUT, e))?;
    Ok((head, Some(rest)))
}

/// Reads and validates the input sequence, under the default [`InputLimits`] (checked while
/// parsing; the error names the limit, the file and the line).
pub fn load(path: &Path, args: &InputArgs) -> Result<Sequence, Exit> {
    let limits = InputLimits::default();
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let seq = if ext == "glb" || ext == "gltf" {
        let animation = args.animation.as_ref().map(|a| match a.parse::<usize>() {
            Ok(i) => AnimationSelector::Index(i),
            Err(_) => AnimationSelector::Name(a.clone()),
        });
        let opts = GltfOptions { animation, frame_rate: args.fps, limits, ..Default::default() };
        pmcodec_mesh::gltf_input::load_gltf(path, &opts)
    } else {
        pmcodec_mesh::obj::load_obj_sequence_with(path, args.fps, &limits)
    };
    seq.with_context(|| format!("reading {}", path.display())).map_err(|e| Exit(EXIT_BAD_INPUT, e))
}
