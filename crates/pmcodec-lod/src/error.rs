use pmcodec_mesh::MeshError;

/// Everything that can go wrong making LODs. Messages say what was asked and what the input has.
#[derive(Debug, thiserror::Error)]
pub enum LodError {
    /// Reading or validating the input glTF failed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Sampling the surfaces for the error measurement failed.
    #[error(transparent)]
    Eval(#[from] pmcodec_eval::EvalError),
    /// [`crate::build_chain`] was called with an empty target list.
    #[error("no triangle targets were given")]
    NoTargets,
    /// A triangle target is not smaller than the input's count or the one before it.
    #[error("triangle target {target} is not below the {have} triangles of the input (targets must be smaller than the mesh and decrease)")]
    BadTarget {
        /// The target, in triangles.
        target: usize,
        /// Triangles of the input or of the previous target.
        have: usize,
    },
    /// A user pose weight is negative, NaN or infinite.
    #[error("pose weight for {name:?} is {weight}, but weights must be finite and not negative")]
    BadPoseWeight {
        /// The pose's name.
        name: String,
        /// The weight given.
        weight: f32,
    },
    /// A user pose weight names no animation, nor `rest` or `morph`.
    #[error("pose weight names {name:?}, which is not an animation of the file (nor \"rest\" or \"morph\"); animations: {available}")]
    UnknownPose {
        /// The name given.
        name: String,
        /// The file's animation keys, comma-separated.
        available: String,
    },
    /// Every pose got weight 0, so the multi-pose quadrics would all be zero.
    #[error("every pose has weight 0: there is nothing to measure the collapse cost in")]
    NoPoses,
    /// The welded rig has half the u32 range of vertices or more: the simplifier's 32-bit vertex
    /// ids would run out.
    #[error("the mesh has {0} vertices, more than this tool handles")]
    TooLarge(usize),
    /// An invariant of the simplifier or the chain broke; a bug to report, not bad input.
    #[error("internal error (a bug): {0}")]
    Internal(String),
    /// A [`pmcodec_mesh::gltf_input::RiggedMesh`] built by hand is inconsistent (triangles, joints,
    /// weights, instances or skins out of range).
    #[error("the input's vertex records do not line up with its instances: {0}")]
    BadRig(String),
    /// The GLB writer met a rig it cannot express (a missing skin, a singular node transform) or
    /// a GLB over 4 GiB.
    #[error("writing glTF: {0}")]
    Write(String),
}
