//! The example poses the collapse cost is measured in, and per-vertex importance.
//!
//! Mohr & Gleicher ("Deformation Sensitive Decimation", 2003, section 4) sum one quadric per
//! example pose so that a collapse is cheap only if it is cheap in every pose. Our examples are:
//! the rest pose, frames sampled evenly from every animation of the file, and every morph target
//! alone at full weight (Berner & Rieger, "Surface Simplification Guided by Morph-Targets", 2006,
//! simplify against the targets). Each pose's quadrics are multiplied by the weight of its source
//! (`rest`, `morph`, or the animation's name), 1 unless the user says otherwise.
//!
//! Per-vertex importance (Berner & Rieger 2006): a vertex's displacement is the summed distance,
//! over the sampled poses, between where it really is and where the single transform that dominates it
//! would put it (its heaviest joint, or its node for rigid parts), without morphing. Rigidly
//! carried vertices get 0 however far the character walks; vertices in skin-blending zones
//! (elbows, knees) and under morph targets (mouth corners) get large values. Berner & Rieger map
//! displacement tertiles to weights 0.33 / 0.66 / 1.0; the smooth variant is
//! `1/3 + 2/3 * d / max d`. Ties go to the lower class, so the many rigid vertices with d = 0 all
//! weigh 0.33 (the paper's vertices never tie; this is our choice).

use crate::LodError;
use crate::attrs::VertexAttrs;
use glam::Mat4;
use pmcodec_mesh::gltf_input::{Animation, RiggedMesh};
use std::collections::HashMap;

/// Weights of the pose sources. Names not listed weigh `default`.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseWeights {
    /// The rest pose (no animation, default morph weights).
    pub rest: f32,
    /// Each morph target alone at full weight.
    pub morph: f32,
    /// Animations not named in `animations`.
    pub default: f32,
    /// By animation name (or `#index` for an unnamed one).
    pub animations: HashMap<String, f32>,
}

impl Default for PoseWeights {
    fn default() -> Self {
        PoseWeights { rest: 1.0, morph: 1.0, default: 1.0, animations: HashMap::new() }
    }
}

impl PoseWeights {
    /// Parses `name=weight` items (`rest`, `morph`, an animation name, or `*` for the default).
    pub fn parse(items: &[String]) -> Result<Self, LodError> {
        let mut w = PoseWeights::default();
        for item in items {
            let (name, value) = item.rsplit_once('=').ok_or_else(|| LodError::BadPoseWeight { name: item.clone(), weight: f32::NAN })?;
            let weight: f32 = value.trim().parse().map_err(|_| LodError::BadPoseWeight { name: name.to_string(), weight: f32::NAN })?;
            match name.trim() {
                "rest" => w.rest = weight,
                "morph" => w.morph = weight,
                "*" => w.default = weight,
                other => {
                    w.animations.insert(other.to_string(), weight);
                }
            }
        }
        Ok(w)
    }

    fn check(&self, rig: &RiggedMesh) -> Result<(), LodError> {
        let all = [("rest", self.rest), ("morph", self.morph), ("*", self.default)];
        for (name, weight) in all.iter().map(|(n, w)| (n.to_string(), *w)).chain(self.animations.clone()) {
            if !(weight >= 0.0) || !weight.is_finite() {
                return Err(LodError::BadPoseWeight { name, weight });
            }
        }
        for name in self.animations.keys() {
            if !rig.animations.iter().any(|a| &animation_key(a) == name) {
                return Err(LodError::UnknownPose {
                    name: name.clone(),
                    available: rig.animations.iter().map(animation_key).collect::<Vec<_>>().join(", "),
                });
            }
        }
        Ok(())
    }

    fn of_animation(&self, a: &Animation) -> f32 {
        self.animations.get(&animation_key(a)).copied().unwrap_or(self.default)
    }
}

/// How an animation is named in pose weights: its name, or `#index`.
pub fn animation_key(a: &Animation) -> String {
    a.name.clone().unwrap_or_else(|| format!("#{}", a.index))
}

/// Per-vertex importance (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VertexWeighting {
    /// Every vertex weighs 1.
    None,
    /// Berner & Rieger: 0.33 / 0.66 / 1.0 by displacement tertile.
    #[default]
    Tertiles,
    /// 1/3 + 2/3 * d / max d.
    Smooth,
}

/// Which poses the collapse cost sums over.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseOptions {
    /// Frames sampled evenly over each animation (first and last key included).
    pub per_animation: usize,
    /// User weights per pose (by animation name or `#index`, `rest`, `morph`).
    pub weights: PoseWeights,
    /// Per-vertex importance from morph-target displacement (Berner & Rieger).
    pub vertex_weighting: VertexWeighting,
}

impl Default for PoseOptions {
    fn default() -> Self {
        PoseOptions { per_animation: 16, weights: PoseWeights::default(), vertex_weighting: VertexWeighting::Tertiles }
    }
}

/// Everything needed to pose any vertex record in one example pose.
#[derive(Clone, Debug)]
pub struct Pose {
    /// `rest`, `morph <instance>/<target>`, or `<animation>@<time>`.
    pub label: String,
    /// Multiplies this pose's quadrics.
    pub weight: f64,
    /// Per skin, its joint matrices (joint world transform times inverse bind matrix).
    pub joints: Vec<Vec<Mat4>>,
    /// World transform of every node.
    pub world: Vec<Mat4>,
    /// Morph weights of every instance of the rig.
    pub morph: Vec<Vec<f32>>,
}

/// Most poses a run may use: the per-pose quadrics cost vertices * poses * 80 bytes.
pub const MAX_POSES: usize = 1024;

/// The transforms of `animation` at time `t` (the rest pose for `None`), posed by the same
/// code as [`RiggedMesh::pose`] ([`RiggedMesh::pose_transforms`]).
pub fn pose_at(rig: &RiggedMesh, animation: Option<&Animation>, t: f32) -> Pose {
    let p = rig.pose_transforms(animation, t);
    let label = match animation {
        Some(a) => format!("{}@{t:.3}", animation_key(a)),
        None => "rest".to_string(),
    };
    Pose { label, weight: 1.0, joints: p.joints, world: p.world, morph: p.morph }
}

/// The example poses of a rig: rest, every morph target alone at full weight, and
/// `per_animation` frames of every animation, each with its source's weight. Poses of weight 0
/// are left out.
pub fn sample_poses(rig: &RiggedMesh, opts: &PoseOptions) -> Result<Vec<Pose>, LodError> {
    opts.weights.check(rig)?;
    let w = &opts.weights;
    let mut out = Vec::new();
    let rest = pose_at(rig, None, 0.0);
    if w.rest > 0.0 {
        out.push(Pose { weight: w.rest as f64, ..rest.clone() });
    }
    if w.morph > 0.0 {
        for (i, inst) in rig.instances.iter().enumerate() {
            for k in 0..inst.morph_targets.len() {
                let mut p = rest.clone();
                p.morph[i] = (0..inst.morph_targets.len()).map(|j| if j == k { 1.0 } else { 0.0 }).collect();
                p.label = format!("morph {i}/{k}");
                p.weight = w.morph as f64;
                out.push(p);
            }
        }
    }
    let per = opts.per_animation.max(1);
    for a in &rig.animations {
        let weight = w.of_animation(a);
        if weight <= 0.0 {
            continue;
        }
        for k in 0..per {
            let t = if per == 1 { 0.0 } else { a.duration.max(0.0) * k as f32 / (per - 1) as f32 };
            let mut p = pose_at(rig, Some(a), t);
            p.weight = weight as f64;
            out.push(p);
        }
    }
    if out.is_empty() {
        return Err(LodError::NoPoses);
    }
    if out.len() > MAX_POSES {
        out = (0..MAX_POSES).map(|i| out[i * out.len() / MAX_POSES].clone()).collect();
    }
    Ok(out)
}

/// Displacement of every vertex over the poses (see the module documentation).
pub fn displacement(attrs: &VertexAttrs, poses: &[Pose]) -> Vec<f64> {
    (0..attrs.len())
        .map(|v| {
            poses
                .iter()
                .map(|pose| {
                    let real = attrs.posed(v, pose);
                    let rigid = attrs.dominant(v, pose).transform_point3(attrs.rest[v]);
                    (real - rigid).length() as f64
                })
                .filter(|d| d.is_finite())
                .sum()
        })
        .collect()
}

/// Importance weights from displacements.
pub fn importance(d: &[f64], mode: VertexWeighting) -> Vec<f64> {
    match mode {
        VertexWeighting::None => vec![1.0; d.len()],
        VertexWeighting::Smooth => {
            let max = d.iter().copied().fold(0.0, f64::max);
            d.iter().map(|&x| if max > 0.0 { 1.0 / 3.0 + 2.0 / 3.0 * x / max } else { 1.0 }).collect()
        }
        VertexWeighting::Tertiles => {
            let mut sorted = d.to_vec();
            sorted.sort_unstable_by(f64::total_cmp);
            let Some(&last) = sorted.last() else { return Vec::new() };
            let n = sorted.len();
            let t1 = sorted[(n - 1) / 3];
            let t2 = sorted[(2 * n - 1) / 3];
            d.iter()
                .map(|&x| {
                    if x <= t1 && t1 < last {
                        0.33
                    } else if x <= t2 && t2 < last {
                        0.66
                    } else {
                        1.0
                    }
                })
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tertiles_and_ties() {
        let w = importance(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0], VertexWeighting::Tertiles);
        assert_eq!(w, vec![0.33, 0.33, 0.66, 0.66, 1.0, 1.0]);
        let w = importance(&[0.0, 0.0, 0.0, 0.0, 2.0, 5.0], VertexWeighting::Tertiles);
        assert_eq!(w, vec![0.33, 0.33, 0.33, 0.33, 1.0, 1.0]);
        let s = importance(&[0.0, 2.0], VertexWeighting::Smooth);
        assert!((s[0] - 1.0 / 3.0).abs() < 1e-12 && (s[1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn parse_weights() {
        let w = PoseWeights::parse(&["rest=2".into(), "Run=0.5".into(), "*=0".into()]).unwrap();
        assert_eq!((w.rest, w.default), (2.0, 0.0));
        assert_eq!(w.animations.get("Run"), Some(&0.5));
        assert!(PoseWeights::parse(&["Run".into()]).is_err());
        assert!(PoseWeights::parse(&["Run=x".into()]).is_err());
    }
}
