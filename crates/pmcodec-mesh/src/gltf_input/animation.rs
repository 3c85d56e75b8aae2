//! Animations: channels read from the file and sampled (STEP, LINEAR, CUBICSPLINE; glTF 2.0 §3.11, Appendix C).

use super::*;

/// One animation of the file.
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    /// Position in the file's `animations` array.
    pub index: usize,
    /// The animation's name in the file, if any.
    pub name: Option<String>,
    /// Largest keyframe time over the channels, in seconds (0 without keys).
    pub duration: f32,
    /// The channels, in file order; samplers are resolved into them.
    pub channels: Vec<Channel>,
}

impl Animation {
    /// The name, or the index for an unnamed animation: what frame names start with.
    pub fn label(&self) -> String {
        self.name.clone().unwrap_or_else(|| self.index.to_string())
    }
}

/// What an animation channel drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnimatedProperty {
    /// `translation`, 3 floats per key.
    Translation,
    /// `rotation`, a quaternion (x, y, z, w) per key.
    Rotation,
    /// `scale`, 3 floats per key.
    Scale,
    /// The morph weights of the mesh the node instantiates.
    MorphWeights,
}

/// Keyframe interpolation (glTF 2.0 §3.11, Appendix C).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// The value of the previous key, held until the next one.
    Step,
    /// Component-wise linear, spherical linear for rotations.
    Linear,
    /// Cubic Hermite with per-key in- and out-tangents.
    CubicSpline,
}

/// One animation channel: keyframes of one property of one node.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Target node, an index into the file's `nodes`.
    pub node: usize,
    /// Which of the node's properties the keys drive.
    pub property: AnimatedProperty,
    /// How values between keys are found.
    pub interpolation: Interpolation,
    /// Keyframe times in seconds, non-decreasing.
    pub times: Vec<f32>,
    /// `width` floats per keyframe, or for cubic splines three groups of `width` per keyframe:
    /// in-tangent, value, out-tangent.
    pub values: Vec<f32>,
    /// Floats per value: 3 for translation and scale, 4 for rotation (x, y, z, w), the number of
    /// morph targets for weights.
    pub width: usize,
}

pub(super) fn read_animations(file: &GltfFile, morph_targets: &[usize]) -> Result<Vec<Animation>, MeshError> {
    use json::animation::{Interpolation as JsonInterpolation, Property};
    let mut out = Vec::new();
    for (index, anim) in file.root.animations.iter().enumerate() {
        let name = anim.name.clone();
        let what = match &name {
            Some(n) => format!("animation {index} ({n:?})"),
            None => format!("animation {index}"),
        };
        let mut channels = Vec::new();
        let mut duration = 0f32;
        for (c, ch) in anim.channels.iter().enumerate() {
            let what = format!("{what} channel {c}");
            let node = ch.target.node.value();
            if node >= morph_targets.len() {
                return Err(gltf_error(format!("{what} targets node {node}, which does not exist")));
            }
            let sampler = anim
                .samplers
                .get(ch.sampler.value())
                .ok_or_else(|| gltf_error(format!("{what} uses sampler {}, which does not exist", ch.sampler.value())))?;
            let (property, width, dims) = match ch.target.path {
                Checked::Valid(Property::Translation) => (AnimatedProperty::Translation, 3, 3),
                Checked::Valid(Property::Rotation) => (AnimatedProperty::Rotation, 4, 4),
                Checked::Valid(Property::Scale) => (AnimatedProperty::Scale, 3, 3),
                Checked::Valid(Property::MorphTargetWeights) => {
                    (AnimatedProperty::MorphWeights, morph_targets.get(node).copied().unwrap_or(0), 1)
                }
                // A path this reader does not know cannot move the mesh as far as it can tell.
                Checked::Invalid => continue,
            };
            if width == 0 {
                // Weights for a node without morph targets drive nothing.
                continue;
            }
            let interpolation = match sampler.interpolation {
                Checked::Valid(JsonInterpolation::Step) => Interpolation::Step,
                Checked::Valid(JsonInterpolation::Linear) => Interpolation::Linear,
                Checked::Valid(JsonInterpolation::CubicSpline) => Interpolation::CubicSpline,
                Checked::Invalid => return Err(gltf_error(format!("{what}: unknown interpolation"))),
            };
            let times = file.read_floats(sampler.input.value(), 1, &[ComponentType::F32], &format!("{what} input"))?;
            if times.is_empty() {
                continue;
            }
            if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
                return Err(gltf_error(format!("{what}: keyframe times are not increasing finite numbers")));
            }
            // Outputs may be normalised integers (§3.11, and KHR_mesh_quantization).
            let values = file.read_floats(sampler.output.value(), dims, ANY_NUMBER, &format!("{what} output"))?;
            let per_key = if interpolation == Interpolation::CubicSpline { 3 * width } else { width };
            if values.len() < times.len() * per_key {
                return Err(gltf_error(format!("{what}: {} output values for {} keyframes of {per_key}", values.len(), times.len())));
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(gltf_error(format!("{what}: an output value is not finite")));
            }
            duration = duration.max(times.last().copied().unwrap_or(0.0));
            channels.push(Channel { node, property, interpolation, times, values, width });
        }
        out.push(Animation { index, name, duration, channels });
    }
    Ok(out)
}

impl Channel {
    /// The channel's value at time `t` (`width` floats), per glTF 2.0 Appendix C: clamped to
    /// the first and last keys, STEP holds the earlier key, LINEAR interpolates (rotations by
    /// slerp on the shorter arc), CUBICSPLINE evaluates the Hermite curve with tangents scaled
    /// by the key interval. Rotations come out normalised.
    pub fn sample(&self, t: f32) -> Vec<f32> {
        let w = self.width;
        let cubic = self.interpolation == Interpolation::CubicSpline;
        // part: 0 in-tangent, 1 value, 2 out-tangent (cubic); only the value otherwise.
        let part = |k: usize, part: usize| -> &[f32] {
            let start = if cubic { (3 * k + part) * w } else { k * w };
            self.values.get(start..start + w).unwrap_or_default()
        };
        let value = |k: usize| part(k, 1);
        let mut out = vec![0.0f32; w];
        let (Some(&first), Some(&last)) = (self.times.first(), self.times.last()) else { return out };
        let n = self.times.len();
        if t <= first || n == 1 {
            fill(&mut out, value(0));
        } else if t >= last {
            fill(&mut out, value(n - 1));
        } else {
            // first < t < last, so 1 <= partition point <= n - 1 (saturating only for NaN).
            let k = self.times.partition_point(|&x| x <= t).saturating_sub(1);
            let (t0, t1) = (self.times.get(k).copied().unwrap_or(first), self.times.get(k + 1).copied().unwrap_or(last));
            let dt = t1 - t0;
            let u = if dt > 0.0 { (t - t0) / dt } else { 1.0 };
            match self.interpolation {
                Interpolation::Step => fill(&mut out, value(k)),
                Interpolation::Linear if self.property == AnimatedProperty::Rotation => {
                    if let (&[ax, ay, az, aw], &[bx, by, bz, bw]) = (value(k), value(k + 1)) {
                        let q = slerp(Quat::from_xyzw(ax, ay, az, aw), Quat::from_xyzw(bx, by, bz, bw), u);
                        fill(&mut out, &q.to_array());
                    }
                }
                Interpolation::Linear => {
                    for ((o, a), b) in out.iter_mut().zip(value(k)).zip(value(k + 1)) {
                        *o = a + (b - a) * u;
                    }
                }
                Interpolation::CubicSpline => {
                    let (u2, u3) = (u * u, u * u * u);
                    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
                    let h10 = u3 - 2.0 * u2 + u;
                    let h01 = -2.0 * u3 + 3.0 * u2;
                    let h11 = u3 - u2;
                    let (p0, m0, p1, m1) = (value(k), part(k, 2), value(k + 1), part(k + 1, 0));
                    for (i, o) in out.iter_mut().enumerate() {
                        let at = |s: &[f32]| s.get(i).copied().unwrap_or(0.0);
                        *o = h00 * at(p0) + h10 * dt * at(m0) + h01 * at(p1) + h11 * dt * at(m1);
                    }
                }
            }
        }
        if let (AnimatedProperty::Rotation, &[x, y, z, w]) = (self.property, out.as_slice()) {
            fill(&mut out, &unit_quat(Quat::from_xyzw(x, y, z, w)).to_array());
        }
        out
    }
}

pub(super) fn fill(out: &mut [f32], from: &[f32]) {
    out.iter_mut().zip(from).for_each(|(o, v)| *o = *v);
}

/// Spherical interpolation on the shorter arc; nearly equal rotations fall back to normalised
/// linear interpolation, where slerp's division by sin(angle) loses precision.
pub(super) fn slerp(a: Quat, b: Quat, u: f32) -> Quat {
    let a = Vec4::from(unit_quat(a));
    let mut b = Vec4::from(unit_quat(b));
    let mut d = a.dot(b);
    if d < 0.0 {
        b = -b;
        d = -d;
    }
    let mixed = if d > 0.9995 {
        a + (b - a) * u
    } else {
        let angle = d.min(1.0).acos();
        let s = angle.sin();
        a * (((1.0 - u) * angle).sin() / s) + b * ((u * angle).sin() / s)
    };
    unit_quat(Quat::from_vec4(mixed))
}
