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

/// An entry's link in the linked coding: its reference entry ([`NO_REF`]: none) and its pivot,
/// the bind point (in bind quanta) that it moves as its reference does (the joint's origin,
/// where it turns relative to its parent).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Link {
    pub reference: u32,
    pub pivot: [i64; 3],
}

impl Link {
    pub const NONE: Link = Link { reference: NO_REF, pivot: [0; 3] };
}

/// An entry's prediction: its rigid parameters, its translations when not linked, and when
/// linked (predicted through its reference; its numbers then have orders of their own) what its
/// translations are predicted from once its linear part is known ([`Predicted::translation`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Predicted {
    pub rig: Rig,
    pub t: [i64; 3],
    pub linked: bool,
    /// The reference's linear values and translations in this frame, and the pivot.
    pub anchor: Option<([i64; 9], [i64; 3], [i64; 3])>,
}

impl Predicted {
    /// The predicted translations of an entry whose linear part is `l` (row-major): linked, those
    /// that move the pivot `c` where the reference moves it, `T_A + floor((L_A - l) c / 2^13)`
    /// (exact in 128 bits, wrapped to 64); else the temporal prediction.
    pub fn translation(&self, l: &[i64; 9]) -> [i64; 3] {
        let Some((la, ta, c)) = &self.anchor else { return self.t };
        [0, 1, 2].map(|a| {
            let dot: i128 = (0..3).map(|k| (la[3 * a + k] as i128 - l[3 * a + k] as i128) * c[k] as i128).sum();
            ta[a].wrapping_add((dot >> (LINEAR_BITS - super::TRANSLATION_BITS)) as i64)
        })
    }
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

fn translation(palette: &[i64], e: usize) -> [i64; 3] {
    [3, 7, 11].map(|i| palette.get(e * ENTRY + i).copied().unwrap_or(0))
}

/// Entry `e`'s prediction: linked to `link.reference` when that entry is rigid in this frame
/// (`now`: the palette values and rigid parameters decoded so far this frame) and, after a
/// keyframe, both were rigid in the previous frame; else the temporal prediction of the plain
/// coding.
///
/// Linked, with `A` the reference's quaternion now, `B` its quaternion in the previous frame and
/// `C` the entry's there: the relative rotation `r = conj(B) C`, or `2 r1 - r2` when the frame
/// before had both rigid too, gives the quaternion `(A r) / |B|^2` (rounded, wrapped to 64
/// bits); on keyframes the reference's own quaternion and scale. The translations follow from
/// the pivot ([`Predicted::translation`]).
pub fn predict(e: usize, link: Link, prediction: &JointPrediction, now: (&[i64], &[Option<Rig>])) -> Predicted {
    let base = e * ENTRY;
    let temporal =
        Predicted { rig: prediction.rig_at(e), t: [3, 7, 11].map(|i| prediction.pose.at(base + i)), linked: false, anchor: None };
    let p = link.reference as usize;
    let Some(a) = (link.reference != NO_REF).then(|| now.1.get(p).copied().flatten()).flatten() else { return temporal };
    let la: [i64; 9] = std::array::from_fn(|i| now.0.get(p * ENTRY + 4 * (i / 3) + i % 3).copied().unwrap_or(0));
    let anchor = Some((la, translation(now.0, p), link.pivot));
    if matches!(prediction.pose, PosePrediction::Key) {
        return Predicted { rig: a, t: temporal.t, linked: true, anchor };
    }
    let get = |rigs: &[Option<Rig>], i: usize| rigs.get(i).copied().flatten();
    let (Some(b), Some(c)) = (get(prediction.rig, p), get(prediction.rig, e)) else { return temporal };
    let mut r = qmul(conj(quat(&b)), quat(&c));
    if let (PosePrediction::Linear(..), Some(b2), Some(c2)) =
        (prediction.pose, get(prediction.rig_before, p), get(prediction.rig_before, e))
    {
        let r2 = qmul(conj(quat(&b2)), quat(&c2));
        r = [0, 1, 2, 3].map(|i| 2 * r[i] - r2[i]);
    }
    let q = qmul(quat(&a), r).map(|v| rdiv(v, norm2(quat(&b)).max(1)) as i64);
    Predicted { rig: [q[0], q[1], q[2], q[3], temporal.rig[4]], t: temporal.t, linked: true, anchor }
}

/// How far (in quarter quanta, the translations' unit) a translation may be from the value it
/// stands for and still be sent as predicted: a quarter of a position quantum.
const TRANSLATION_SNAP: f64 = 0.5;

/// Frame `f`'s palette for the linked coding, entries fitted in `order` (the order a decoder
/// reads them: a reference before the entries that name it). `fixed`: the unrounded values;
/// `radius(e)`: how far from the bind origin entry e's points lie, and how far from its pivot
/// (a linked entry's translations are chosen to place its pivot exactly, so its rotation need
/// only be as fine as that distance asks); `same(e)`: its input matrix
/// is the previous frame's; `refs`: each entry's reference. Where the prediction rebuilds an
/// entry within the tolerance of [`fit_rig`] it is taken as is, so the entry costs a bit.
pub fn fit_frame(
    fixed: &[f64],
    radius: impl Fn(usize) -> (f64, f64),
    same: impl Fn(usize) -> bool,
    order: &[u32],
    links: Vec<Link>,
    held: (&JointPrediction, &[i64], bool),
) -> JointsFrame {
    let (prediction, previous, intra) = held;
    let n = fixed.len() / ENTRY;
    let mut out = JointsFrame { palette: vec![0; n * ENTRY], rig: vec![None; n], held: vec![false; n], links };
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
        let link = out.links.get(e).copied().unwrap_or(Link::NONE);
        let predicted = predict(e, link, prediction, (&out.palette, &out.rig));
        let (global, local) = radius(e);
        let radius = if predicted.anchor.is_some() { local } else { global }.max(1.0);
        let tolerance = 0.25 + 1.5 * radius / (1u64 << LINEAR_BITS) as f64;
        let snapped = (predicted.rig[..4].iter().all(|c| c.unsigned_abs() <= super::joints::MAX_QUATERNION as u64)
            && rig_error(m, &predicted.rig, radius).is_some_and(|w| w <= tolerance))
        .then_some(predicted.rig);
        let rig = snapped.or_else(|| fit_rig(m, radius, predicted.rig, tolerance));
        let linear = rig.as_ref().and_then(rig_matrix);
        let t = linear.as_ref().map(|l| predicted.translation(l));
        // A linked entry's translations place its pivot c where the input does: the input's
        // plus (L - L_q) c, so the rounding of its rotation moves a point by its distance to c.
        let target = |i: usize| match (&linear, &predicted.anchor) {
            (Some(l), Some((_, _, c))) => {
                let a = i / 4;
                m[i] + (0..3).map(|k| (m[4 * a + k] - l[3 * a + k] as f64) * c[k] as f64).sum::<f64>()
                    / (1u64 << (LINEAR_BITS - super::TRANSLATION_BITS)) as f64
            }
            _ => m[i],
        };
        for (i, slot) in out.palette[r].iter_mut().enumerate() {
            *slot = match (linear, t) {
                (Some(l), _) if i % 4 != 3 => l[3 * (i / 4) + i % 4],
                (_, Some(t)) if (target(i) - t[i / 4] as f64).abs() <= TRANSLATION_SNAP => t[i / 4],
                _ => (target(i).round() as i64).clamp(-MAX_MATRIX, MAX_MATRIX),
            };
        }
        out.rig[e] = rig;
    }
    out
}

/// Each carried entry's link for the frames `frames` (a keyframe and those up to the next): the
/// entry decoded before it (`before(p, e)`) that the linked prediction would follow at the
/// smallest estimated cost over those frames, with the pivot that best stays where the
/// reference moves it (least squares), or none when the entry's own temporal prediction costs
/// less. `frames` gives each frame's unrounded values (a palette of `n` entries); `carried`
/// lists the entries in reading order.
pub fn choose_links(
    frames: &[Vec<f64>],
    n: usize,
    carried: &[u32],
    radius: impl Fn(usize) -> f64,
    before: impl Fn(usize, usize) -> bool,
) -> Vec<Link> {
    use glam::{DMat3, DMat4, DVec3, DVec4};
    // Each entry as the affine map from bind quanta to position quanta.
    let affine = |m: &[f64]| {
        let lin = (1u64 << LINEAR_BITS) as f64;
        let col = |c: usize| DVec4::new(m[c] / lin, m[4 + c] / lin, m[8 + c] / lin, 0.0);
        DMat4::from_cols(col(0), col(1), col(2), DVec4::new(m[3] / 4.0, m[7] / 4.0, m[11] / 4.0, 1.0))
    };
    let maps: Vec<Vec<DMat4>> = frames.iter().map(|f| f.chunks_exact(ENTRY).take(n).map(affine).collect()).collect();
    // Each entry's inverse per frame, and the cube root of its determinant's size (the scale
    // of its position quanta), where it is invertible: what every entry linked to it reads,
    // made once (the 168 fitted bones of the horse inverted each of them 167 times a frame).
    let inverses: Vec<Vec<Option<(DMat4, f64)>>> = maps
        .iter()
        .map(|f| {
            f.iter()
                .map(|a| {
                    let det = a.determinant();
                    (det.is_finite() && det.abs() > 1e-12).then(|| (a.inverse(), det.abs().cbrt()))
                })
                .collect()
        })
        .collect();
    // Estimated bits of a number whose prediction misses by `err` position quanta (under a
    // quarter quantum the entry is sent as predicted).
    let bits = |err: f64| (1.0 + err * 4.0).log2();
    // The second (after the keyframe, first) difference of `ms`'s linear parts, as the move of a
    // point at `radius` in position quanta (`scale`: position quanta per unit of `ms`).
    let turn = |ms: &[DMat4], f: usize, radius: f64, scale: f64| -> (f64, DMat4) {
        let d = if f >= 2 { ms[f] - ms[f - 1] * 2.0 + ms[f - 2] } else { ms[f] - ms[f - 1] };
        ((0..3).map(|c| d.col(c).truncate().abs().element_sum()).fold(0.0, f64::max) * radius * scale, d)
    };
    let mut links = vec![Link::NONE; n];
    for &e in carried {
        let e = e as usize;
        if e >= n {
            continue;
        }
        let radius = radius(e).max(1.0);
        let own: Vec<DMat4> = maps.iter().map(|f| f[e]).collect();
        let own_cost: f64 = (1..own.len())
            .map(|f| {
                let (lin, d) = turn(&own, f, radius, 1.0);
                let t = d.col(3).truncate().abs().max_element();
                if lin <= 0.25 && t <= 0.25 { 1.0 } else { 2.0 + 4.0 * bits(lin) + 3.0 * bits(t) }
            })
            .sum();
        let mut best = (own_cost, Link::NONE);
        for &p in carried {
            let p = p as usize;
            if p == e || p >= n || !before(p, e) {
                continue;
            }
            // The pivot c: (sum D^T D + lambda) c = -sum D^T d, D and d the differences of the two
            // entries' linear parts and translations (a little pull to 0 where the joint turns
            // about one axis only, along which c is free).
            let (mut ata, mut atb) = (DMat3::ZERO, DVec3::ZERO);
            for f in &maps {
                let d = f[e] - f[p];
                let dl = DMat3::from_cols(d.col(0).truncate(), d.col(1).truncate(), d.col(2).truncate());
                ata += dl.transpose() * dl;
                atb -= dl.transpose() * d.col(3).truncate();
            }
            let lambda = 1e-9 * (ata.x_axis.x + ata.y_axis.y + ata.z_axis.z) + 1e-12;
            let c = (ata + DMat3::from_diagonal(DVec3::splat(lambda))).inverse() * atb;
            if !c.is_finite() || c.abs().max_element() >= super::MAX_BIND as f64 {
                continue;
            }
            let c = c.round();
            let mut rel = Vec::with_capacity(maps.len());
            let mut cost = 0.0;
            for (k, f) in maps.iter().enumerate() {
                let a = f[p];
                let Some((inverse, scale)) = inverses[k][p] else {
                    break;
                };
                rel.push(inverse * f[e]);
                if k > 0 {
                    let (lin, _) = turn(&rel, k, radius, scale);
                    let t = ((f[e] - a) * c.extend(1.0)).truncate().abs().max_element();
                    cost += if lin <= 0.25 && t <= 0.25 { 1.0 } else { 2.0 + 4.0 * bits(lin) + 3.0 * bits(t) };
                }
            }
            if rel.len() < maps.len() {
                continue;
            }
            // The link itself: a reference and a pivot once per keyframe.
            cost += 50.0;
            if cost < best.0 {
                best = (cost, Link { reference: p as u32, pivot: [c.x as i64, c.y as i64, c.z as i64] });
            }
        }
        links[e] = best.1;
    }
    links
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
        assert_eq!(rdiv(7, 2), 4);
        assert_eq!(rdiv(-7, 2), -3);
        assert_eq!(rdiv(-5, 3), -2);
    }
}
