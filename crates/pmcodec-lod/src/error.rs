use pmcodec_mesh::MeshError;

/// Everything that can go wrong making LODs. Messages say what was asked and what the input has.
#[derive(Debug, thiserror::Error)]
pub enum LodError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Eval(#[from] pmcodec_eval::EvalError),
    #[error("no triangle targets were given")]
    NoTargets,
    #[error("triangle target {target} is not below the {have} triangles of the input (targets must be smaller than the mesh and decrease)")]
    BadTarget { target: usize, have: usize },
    #[error("pose weight for {name:?} is {weight}, but weights must be finite and not negative")]
    BadPoseWeight { name: String, weight: f32 },
    #[error("pose weight names {name:?}, which is not an animation of the file (nor \"rest\" or \"morph\"); animations: {available}")]
    UnknownPose { name: String, available: String },
    #[error("every pose has weight 0: there is nothing to measure the collapse cost in")]
    NoPoses,
    #[error("the mesh has {0} vertices, more than this tool handles")]
    TooLarge(usize),
    #[error("internal error (a bug): {0}")]
    Internal(String),
    #[error("the input's vertex records do not line up with its instances: {0}")]
    BadRig(String),
    #[error("writing glTF: {0}")]
    Write(String),
}
