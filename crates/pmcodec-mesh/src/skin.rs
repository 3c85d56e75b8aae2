//! The skin of a sequence: what poses every vertex by linear blend skinning, kept beside the
//! posed frames so that an encoder can predict positions by skinning and send only residuals
//! (the motion compensation of MPEG-4 FAMC, Mamou, Zaharia and Prêteux, "FAMC: the MPEG-4
//! standard for animated mesh compression", 2008).
//!
//! Every joint of every skin and every rigid mesh node of a glTF scene becomes one entry of a
//! single joint *palette*; each vertex has at most four influences on it, and each frame gives
//! every palette entry one 3x4 matrix. A vertex's posed position is then
//! `sum_k w_k M_k rest` for its rest (bind-space) position. Morph targets are not part of the
//! skin: a morphed vertex is predicted from its rest position and its morph shows up in the
//! residuals.

use crate::MeshError;
use crate::gltf_input::{Animation, RiggedMesh};
use glam::{Mat4, Vec3};

/// The skin of a [`crate::Sequence`]: vertex arrays parallel to its vertices, matrices per frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SequenceSkin {
    /// Number of palette entries.
    pub palette_len: u32,
    /// What each palette entry is ("skin 0 joint 3 (node 12)", "node 5"), for messages.
    pub palette_names: Vec<String>,
    /// Rest position of every vertex, in the space the palette's matrices map from.
    pub rest: Vec<Vec3>,
    /// Up to four palette entries per vertex; unused slots have weight 0.
    pub joints: Vec<[u32; 4]>,
    /// Weights matching `joints`, summing to 1 (or all 0: a vertex no joint moves, posed at
    /// the origin as glTF's formula gives).
    pub weights: Vec<[f32; 4]>,
    /// `matrices[f][k]`: palette entry k's transform in frame f, the first three rows of its
    /// 4x4 matrix, row-major (at least one set per frame; sets beyond the last frame are not
    /// read).
    pub matrices: Vec<Vec<[f32; 12]>>,
    /// What was changed or is doubtful in the input (influences dropped, a singular bind).
    pub warnings: Vec<String>,
}

/// Weights may drift this far from summing to one (exporters write 8- and 16-bit weights).
const WEIGHT_SUM_TOLERANCE: f32 = 1e-3;

impl SequenceSkin {
    /// Checks the skin against a sequence of `n` vertices and `frames` frames: lengths, palette
    /// indices, weights (finite, non-negative, summing to one) and finite matrices.
    pub fn validate(&self, n: usize, frames: usize) -> Result<(), MeshError> {
        let bad = |detail: String| Err(MeshError::Invalid(format!("skin: {detail}")));
        if self.rest.len() != n || self.joints.len() != n || self.weights.len() != n {
            return bad(format!(
                "{} rest positions, {} influence sets, {} weight sets for {n} vertices",
                self.rest.len(),
                self.joints.len(),
                self.weights.len()
            ));
        }
        // Tools that keep the first frames of a sequence truncate `frames` only, as they leave
        // `frame_names`: matrices beyond the last frame are not read.
        if self.matrices.len() < frames {
            return bad(format!("matrices for {} frames in a sequence of {frames}", self.matrices.len()));
        }
        let palette = self.palette_len as usize;
        for v in 0..n {
            if !self.rest[v].is_finite() {
                return bad(format!("vertex {v}: rest position is not finite"));
            }
            let mut sum = 0.0f32;
            for (slot, (&j, &w)) in self.joints[v].iter().zip(&self.weights[v]).enumerate() {
                if !(w.is_finite() && w >= 0.0) {
                    return bad(format!("vertex {v} influence {slot}: weight {w}"));
                }
                if w > 0.0 && j as usize >= palette {
                    return bad(format!("vertex {v} influence {slot}: joint {j} beyond the palette of {palette}"));
                }
                sum += w;
            }
            // All zero: a vertex no joint moves, which glTF's formula poses at the origin.
            if (sum - 1.0).abs() > WEIGHT_SUM_TOLERANCE && sum != 0.0 {
                return bad(format!("vertex {v}: weights sum to {sum}, not 1"));
            }
        }
        for (f, frame) in self.matrices.iter().enumerate().take(frames) {
            if frame.len() != palette {
                return bad(format!("frame {f}: {} matrices for a palette of {palette}", frame.len()));
            }
            if let Some(k) = frame.iter().position(|m| m.iter().any(|x| !x.is_finite())) {
                return bad(format!("frame {f}: the matrix of {} is not finite", self.name(k)));
            }
        }
        Ok(())
    }

    /// A palette entry's name for messages.
    pub fn name(&self, k: usize) -> String {
        self.palette_names.get(k).cloned().unwrap_or_else(|| format!("palette entry {k}"))
    }

    /// Vertex `v` posed by frame `f`'s matrices (f32, for tests and tools).
    pub fn pose_vertex(&self, f: usize, v: usize) -> Vec3 {
        let mut out = Vec3::ZERO;
        let r = self.rest[v];
        for (&j, &w) in self.joints[v].iter().zip(&self.weights[v]) {
            if w == 0.0 {
                continue;
            }
            let m = &self.matrices[f][j as usize];
            out += w * Vec3::new(
                m[0] * r.x + m[1] * r.y + m[2] * r.z + m[3],
                m[4] * r.x + m[5] * r.y + m[6] * r.z + m[7],
                m[8] * r.x + m[9] * r.y + m[10] * r.z + m[11],
            );
        }
        out
    }
}

/// The first three rows of `m`, row-major.
fn rows(m: &Mat4) -> [f32; 12] {
    let r = m.transpose().to_cols_array();
    [r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10], r[11]]
}

/// The skin of `rig` posed by `animation` at `times` (what [`RiggedMesh::to_sequence`] samples),
/// or `None` when no mesh of the scene is skinned (rigid and morph-only scenes stream as they
/// did). Every (skin, joint) pair and every unskinned mesh node is one palette entry.
pub fn sequence_skin(rig: &RiggedMesh, animation: Option<&Animation>, times: &[f32]) -> Option<SequenceSkin> {
    if rig.instances.iter().all(|i| i.skin.is_none()) {
        return None;
    }
    let n = rig.vertex_count();
    let mut skin = SequenceSkin {
        rest: rig.positions.clone(),
        joints: vec![[0; 4]; n],
        weights: vec![[0.0; 4]; n],
        warnings: rig.warnings.clone(),
        ..Default::default()
    };
    // Palette: the joints of every skin, then the unskinned mesh nodes.
    let mut skin_base = Vec::with_capacity(rig.skins.len());
    for (s, sk) in rig.skins.iter().enumerate() {
        skin_base.push(skin.palette_names.len() as u32);
        for (k, &node) in sk.joints.iter().enumerate() {
            skin.palette_names.push(format!("skin {s} joint {k} (node {node})"));
            let det = sk.inverse_bind_matrices.get(k).map_or(1.0, Mat4::determinant);
            if !(det.is_finite() && det.abs() > 1e-12) {
                skin.warnings.push(format!(
                    "skin {s} joint {k} (node {node}): the inverse bind matrix is not invertible (determinant {det}); \
                     its vertices are still posed as glTF says, but have no bind pose"
                ));
            }
        }
    }
    let mut rigid = Vec::new();
    for inst in &rig.instances {
        let entry = match inst.skin.and_then(|s| skin_base.get(s)) {
            Some(&base) => {
                for v in inst.vertices.clone() {
                    let (Some(js), Some(ws)) = (rig.joints.get(v), rig.weights.get(v)) else { break };
                    skin.joints[v] = js.map(|j| base + j as u32);
                    skin.weights[v] = *ws;
                }
                continue;
            }
            None => skin.palette_names.len() as u32,
        };
        skin.palette_names.push(format!("node {}", inst.node));
        rigid.push(inst.node);
        for v in inst.vertices.clone().filter(|&v| v < n) {
            skin.joints[v] = [entry, 0, 0, 0];
            skin.weights[v] = [1.0, 0.0, 0.0, 0.0];
        }
    }
    skin.palette_len = skin.palette_names.len() as u32;
    for &t in times {
        let pose = rig.pose_transforms(animation, t);
        let mut frame: Vec<[f32; 12]> = Vec::with_capacity(skin.palette_len as usize);
        for (s, sk) in rig.skins.iter().enumerate() {
            for k in 0..sk.joints.len() {
                frame.push(rows(pose.joints.get(s).and_then(|j| j.get(k)).unwrap_or(&Mat4::IDENTITY)));
            }
        }
        frame.extend(rigid.iter().map(|&node| rows(pose.world.get(node).unwrap_or(&Mat4::IDENTITY))));
        skin.matrices.push(frame);
    }
    Some(skin)
}

/// A tube along +Y on two joints, the lower half on the first, the upper half on the second
/// and a blend between, whose second joint bends about the middle and swings over `frames`
/// frames: every frame is exactly its linear blend skinning (tests of skinned streams).
pub fn bending_tube(segments: u32, rings: u32, frames: u32) -> crate::Sequence {
    let mut seq = crate::samples::twisting_tube(segments, rings, 1);
    let rest = seq.frames[0].clone();
    let (lo, hi) = crate::bounds_of(&rest).unwrap_or_default();
    let middle = (lo.y + hi.y) / 2.0;
    let span = (hi.y - lo.y).max(f32::MIN_POSITIVE);
    let n = rest.len();
    let mut skin = SequenceSkin {
        palette_len: 2,
        palette_names: vec!["lower".into(), "upper".into()],
        rest: rest.clone(),
        joints: vec![[0, 1, 0, 0]; n],
        weights: Vec::with_capacity(n),
        ..Default::default()
    };
    for p in &rest {
        // Linear from all-lower a fifth of the length below the middle to all-upper above it.
        let t = ((p.y - middle) / (0.4 * span) + 0.5).clamp(0.0, 1.0);
        skin.weights.push([1.0 - t, t, 0.0, 0.0]);
    }
    let pivot = Mat4::from_translation(Vec3::new(0.0, middle, 0.0));
    seq.frames.clear();
    seq.frame_names.clear();
    for f in 0..frames.max(1) {
        let phase = f as f32 / frames.max(1) as f32 * std::f32::consts::TAU;
        let bend = Mat4::from_rotation_z(0.9 * phase.sin()) * Mat4::from_rotation_y(0.5 * phase);
        let upper = pivot * bend * pivot.inverse();
        skin.matrices.push(vec![rows(&Mat4::IDENTITY), rows(&upper)]);
        seq.frame_names.push(format!("bend{f}"));
    }
    seq.frames = (0..skin.matrices.len()).map(|f| (0..n).map(|v| skin.pose_vertex(f, v)).collect()).collect();
    seq.skin = Some(skin);
    seq
}
