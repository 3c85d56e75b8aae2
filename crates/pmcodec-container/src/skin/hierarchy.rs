//! The Joints chunk's *linked* coding (proto/container.md, "Joints", "Linked coding"): an entry
//! may name a *reference*, another palette entry decoded before it (in a skeleton, its parent),
//! and is then predicted as moving with it: its rotation relative to the reference's, and the
//! offset of its translation from the reference's seen in the reference's rotated frame, are
//! extrapolated from the previous two frames and carried by the reference's rotation of this
//! frame. A joint whose parent-relative (local) rotation holds still or turns steadily then
//! costs a bit per frame however its ancestors move, where the global palette entry changes
//! with every ancestor. This is the hierarchical skeleton coding of the MPEG-4 BBA streams that
//! FAMC builds on (Mamou, Zaharia and Prêteux, "FAMC: the MPEG-4 standard for animated mesh
//! compression", 2008): local joint rotations predicted from the previous frames.
//!
//! The decoder has no parent indices (the header carries none, and a palette also holds rigid
//! mesh nodes): the encoder chooses each entry's reference from the motion itself, the entry
//! whose relative transform changes least, which for a skeleton is mostly its parent.
//!
//! Everything here is exact integer arithmetic (i128 inside, wrapped to 64 bits where the spec
//! says so), so decoders in any language rebuild the same palette.

use super::joints::{JointPrediction, JointsFrame, Rig, fit_rig, rig_error, rig_matrix};
use super::payload::PosePrediction;
use super::{ENTRY, LINEAR_BITS, MAX_MATRIX};

/// No reference: the entry is predicted from its own previous frames.
pub const NO_REF: u32 = u32::MAX;

/// An entry's prediction: its rigid parameters, its translations, and whether it is linked
/// (predicted through its reference; its numbers then have orders of their own).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Predicted {
    pub rig: Rig,
    pub t: [i64; 3],
    pub linked: bool,
}

type Q = [i128; 4];

/// The Hamilton product `a b`.
fn qmul(a: Q, b: Q) -> Q {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]
}

fn quat(r: &Rig) -> Q {
    [r[0] as i128, r[1] as i128, r[2] as i128, r[3] as i128]
}

fn conj(q: Q) -> Q {
    [q[0], -q[1], -q[2], -q[3]]
}

fn norm2(q: Q) -> i128 {
    q.iter().map(|v| v * v).sum()
}

/// `a / d` rounded half up (`floor((2a + d) / 2d)`), `d > 0`.
fn rdiv(a: i128, d: i128) -> i128 {
    (2 * a + d).div_euclid(2 * d)
}

/// `v` rotated by quaternion `q` (`inverse`: by its conjugate): `N v / n` rounded, each
/// component wrapped to 64 bits. `|q| <= 2^25` and `|v| < 2^63` keep `N v` within 2^116.
fn rotate(q: Q, v: [i128; 3], inverse: bool) -> [i64; 3] {
    let [w, x, y, z] = if inverse { conj(q) } else { q };
    let n = norm2(q).max(1);
    let m = [
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ];
    m.map(|row| rdiv(row[0] * v[0] + row[1] * v[1] + row[2] * v[2], n) as i64)
}

fn translation(palette: &[i64], e: usize) -> [i64; 3] {
    [3, 7, 11].map(|i| palette.get(e * ENTRY + i).copied().unwrap_or(0))
}

/// Entry `e`'s prediction: linked to `reference` when that entry is rigid in this frame (`now`:
/// the palette values and rigid parameters decoded so far this frame) and, after a keyframe,
/// both were rigid in the previous frame; else the temporal prediction of the plain coding.
///
/// Linked, with `A` the reference's quaternion and `T_A` its translation now, `B`, `T_B` in the
/// previous frame and `C`, `T_C` the entry's there: the relative rotation `r = conj(B) C` and
/// offset `u = rot(conj B)(T_C - T_B)`, or `2 r1 - r2` and `2 u1 - u2` when the frame before
/// had both rigid too; the quaternion `(A r) / |B|^2` and the translation `T_A + rot(A) u`.
/// On keyframes the reference's own quaternion, scale and translation.
pub fn predict(e: usize, reference: u32, prediction: &JointPrediction, now: (&[i64], &[Option<Rig>])) -> Predicted {
    let base = e * ENTRY;
    let temporal = Predicted { rig: prediction.rig_at(e), t: [3, 7, 11].map(|i| prediction.pose.at(base + i)), linked: false };
    let p = reference as usize;
    let Some(a) = (reference != NO_REF).then(|| now.1.get(p).copied().flatten()).flatten() else { return temporal };
    let ta = translation(now.0, p);
    let (previous, before) = match prediction.pose {
        PosePrediction::Key => return Predicted { rig: a, t: ta, linked: true },
        PosePrediction::Previous(p1) => (p1, None),
        PosePrediction::Linear(p1, p2) => (p1, Some(p2)),
    };
    let get = |rigs: &[Option<Rig>], i: usize| rigs.get(i).copied().flatten();
    let (Some(b), Some(c)) = (get(prediction.rig, p), get(prediction.rig, e)) else { return temporal };
    let relative = |b: &Rig, c: &Rig, palette: &[i64]| {
        let (tb, tc) = (translation(palette, p), translation(palette, e));
        let d = [0, 1, 2].map(|i| tc[i] as i128 - tb[i] as i128);
        (qmul(conj(quat(b)), quat(c)), rotate(quat(b), d, true))
    };
    let (mut r, mut u) = relative(&b, &c, previous);
    if let (Some(p2), Some(b2), Some(c2)) = (before, get(prediction.rig_before, p), get(prediction.rig_before, e)) {
        let (r2, u2) = relative(&b2, &c2, p2);
        r = [0, 1, 2, 3].map(|i| 2 * r[i] - r2[i]);
        u = [0, 1, 2].map(|i| u[i].wrapping_mul(2).wrapping_sub(u2[i]));
    }
    let q = qmul(quat(&a), r).map(|v| rdiv(v, norm2(quat(&b)).max(1)) as i64);
    let moved = rotate(quat(&a), u.map(|v| v as i128), false);
    Predicted { rig: [q[0], q[1], q[2], q[3], temporal.rig[4]], t: [0, 1, 2].map(|i| ta[i].wrapping_add(moved[i])), linked: true }
}

/// How far (in quarter quanta, the translations' unit) a translation may be from the value it
/// stands for and still be sent as predicted: a quarter of a position quantum.
const TRANSLATION_SNAP: f64 = 1.0;

/// Frame `f`'s palette for the linked coding, entries fitted in `order` (the order a decoder
/// reads them: a reference before the entries that name it). `fixed`: the unrounded values;
/// `radius(e)`: how far from the bind origin entry e's points lie; `same(e)`: its input matrix
/// is the previous frame's; `refs`: each entry's reference. Where the prediction rebuilds an
/// entry within the tolerance of [`fit_rig`] it is taken as is, so the entry costs a bit.
pub fn fit_frame(
    fixed: &[f64],
    radius: impl Fn(usize) -> f64,
    same: impl Fn(usize) -> bool,
    order: &[u32],
    refs: Vec<u32>,
    held: (&JointPrediction, &[i64], bool),
) -> JointsFrame {
    let (prediction, previous, intra) = held;
    let n = fixed.len() / ENTRY;
    let mut out = JointsFrame { palette: vec![0; n * ENTRY], rig: vec![None; n], held: vec![false; n], refs };
    for &e in order {
        let e = e as usize;
        if e >= n {
            continue;
        }
        let r = e * ENTRY..(e + 1) * ENTRY;
        if let (false, true, Some(p)) = (intra, same(e), previous.get(r.clone())) {
            out.palette[r].copy_from_slice(p);
            out.rig[e] = prediction.rig.get(e).copied().flatten();
            out.held[e] = true;
            continue;
        }
        let m = &fixed[r.clone()];
        let radius = radius(e).max(1.0);
        let tolerance = 0.25 + 1.5 * radius / (1u64 << LINEAR_BITS) as f64;
        let reference = out.refs.get(e).copied().unwrap_or(NO_REF);
        let predicted = predict(e, reference, prediction, (&out.palette, &out.rig));
        let snapped = (predicted.rig[..4].iter().all(|c| c.unsigned_abs() <= super::joints::MAX_QUATERNION as u64)
            && rig_error(m, &predicted.rig, radius).is_some_and(|w| w <= tolerance))
        .then_some(predicted.rig);
        let rig = snapped.or_else(|| fit_rig(m, radius, predicted.rig, tolerance));
        let linear = rig.as_ref().and_then(rig_matrix);
        for (i, slot) in out.palette[r].iter_mut().enumerate() {
            *slot = match linear {
                Some(l) if i % 4 != 3 => l[3 * (i / 4) + i % 4],
                Some(_) if (m[i] - predicted.t[i / 4] as f64).abs() <= TRANSLATION_SNAP => predicted.t[i / 4],
                _ => (m[i].round() as i64).clamp(-MAX_MATRIX, MAX_MATRIX),
            };
        }
        out.rig[e] = rig;
    }
    out
}

/// Each carried entry's reference for the frames `frames` (a keyframe and those up to the next):
/// the entry decoded before it (`before(p, e)`) whose relative transform the linked
/// prediction would follow with the smallest estimated cost over those frames, or none when
/// the entry's own temporal prediction costs less. `frames` gives each frame's unrounded
/// values (a palette of `n` entries); `carried` lists the entries in reading order.
pub fn choose_refs(
    frames: &[Vec<f64>],
    n: usize,
    carried: &[u32],
    radius: impl Fn(usize) -> f64,
    before: impl Fn(usize, usize) -> bool,
) -> Vec<u32> {
    use glam::{DMat4, DVec4};
    // Each entry as the affine map from bind quanta to position quanta.
    let affine = |m: &[f64]| {
        let lin = (1u64 << LINEAR_BITS) as f64;
        let col = |c: usize| DVec4::new(m[c] / lin, m[4 + c] / lin, m[8 + c] / lin, 0.0);
        DMat4::from_cols(col(0), col(1), col(2), DVec4::new(m[3] / 4.0, m[7] / 4.0, m[11] / 4.0, 1.0))
    };
    let maps: Vec<Vec<DMat4>> = frames.iter().map(|f| f.chunks_exact(ENTRY).take(n).map(affine).collect()).collect();
    // The estimated bits of coding matrices `ms` (one per frame) by extrapolating the previous
    // two: the second difference moves a point at `radius` (scaled by `scale` to position
    // quanta) by `err`; under a quarter quantum it is sent as predicted.
    let cost = |ms: &[DMat4], radius: f64, scale: &[f64]| -> f64 {
        let mut bits = 0.0;
        for f in 1..ms.len() {
            let d = if f >= 2 { ms[f] - ms[f - 1] * 2.0 + ms[f - 2] } else { ms[f] - ms[f - 1] };
            let lin = (0..3).map(|c| d.col(c).truncate().abs().element_sum()).fold(0.0, f64::max);
            let err = (lin * radius + d.col(3).truncate().abs().element_sum()) * scale[f];
            bits += if err <= 0.25 { 1.0 } else { 1.0 + 8.0 * (1.0 + err * 4.0).log2() };
        }
        bits
    };
    let ones = vec![1.0; maps.len()];
    let mut refs = vec![NO_REF; n];
    for &e in carried {
        let e = e as usize;
        if e >= n {
            continue;
        }
        let radius = radius(e).max(1.0);
        let own: Vec<DMat4> = maps.iter().map(|f| f[e]).collect();
        let mut best = (cost(&own, radius, &ones), NO_REF);
        for &p in carried {
            let p = p as usize;
            if p == e || p >= n || !before(p, e) {
                continue;
            }
            let mut rel = Vec::with_capacity(maps.len());
            let mut scale = Vec::with_capacity(maps.len());
            for f in &maps {
                let a = f[p];
                let det = a.determinant();
                if !(det.is_finite() && det.abs() > 1e-12) {
                    break;
                }
                rel.push(a.inverse() * f[e]);
                scale.push(det.abs().cbrt());
            }
            if rel.len() < maps.len() {
                continue;
            }
            let c = cost(&rel, radius, &scale);
            if c < best.0 {
                best = (c, p as u32);
            }
        }
        refs[e] = best.1;
    }
    refs
}

/// Whether entry `p` is read before entry `e` by every client that reads `e`, given the entries
/// each band carries: `p` is carried by a coarser band than `e`'s, or by the same band with a
/// smaller index (chunks are read top band first, entries in ascending order).
pub fn read_before(bands: &[Vec<u32>], p: u32, e: u32) -> bool {
    let band_of = |x: u32| bands.iter().position(|b| b.binary_search(&x).is_ok());
    match (band_of(p), band_of(e)) {
        (Some(bp), Some(be)) => bp > be || (bp == be && p < e),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hamilton_product_composes_rotations_and_conjugates_invert() {
        let a: Q = [3, 1, -2, 5];
        let b: Q = [-1, 4, 2, 2];
        let ab = qmul(a, b);
        // |ab|^2 = |a|^2 |b|^2, and conj(a) (a b) = |a|^2 b.
        assert_eq!(norm2(ab), norm2(a) * norm2(b));
        assert_eq!(qmul(conj(a), ab), b.map(|v| v * norm2(a)));
        // Rotating by q and back by its conjugate returns the vector up to rounding.
        let q: Q = [9000, 1200, -3000, 500];
        let v = [12345i128, -678, 9999];
        let there = rotate(q, v, false);
        let back = rotate(q, there.map(|x| x as i128), true);
        for i in 0..3 {
            assert!((back[i] as i128 - v[i]).abs() <= 2, "{back:?} {v:?}");
        }
        assert_eq!(rdiv(7, 2), 4);
        assert_eq!(rdiv(-7, 2), -3);
        assert_eq!(rdiv(-5, 3), -2);
    }
}
