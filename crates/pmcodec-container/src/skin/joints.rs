//! The Joints chunk (proto/container.md, "Joints"): the palette entries of skinned streams are
//! (near) rigid transforms, possibly with a uniform scale, so a frame's entry is sent as an
//! integer quaternion, a scale and a translation (8 numbers) instead of twelve matrix values,
//! each predicted from the previous frames and coded with an Exp-Golomb code whose order the
//! chunk chooses per kind of number. The decoder rebuilds today's integer matrix from them by
//! exactly specified integer operations, so `lbs` runs unchanged; entries that are not rigid
//! keep the twelve values of the Palette chunk. Rotations coded as quaternions predicted from
//! the previous frames are the "skeleton motion" coding of MPEG-4 FAMC (Mamou, Zaharia and
//! Prêteux, "FAMC: the MPEG-4 standard for animated mesh compression", 2008) and of the
//! BBA/skeleton streams it builds on.

use super::bits::{BitReader, Bits, golomb_len, unzigzag, zigzag};
use super::hierarchy::{Link, NO_REF, Predicted, predict, read_before};
use super::linked::{COMPACT, LINKED_CLASSES, ZERO_CLASS, chained, ref_bits, seed, write_joints_linked};
use super::payload::PosePrediction;
use super::{ENTRY, LINEAR_BITS, MAX_MATRIX};
use crate::ContainerError;

/// An entry's rigid parameters: the quaternion (w, x, y, z) in integers of any norm, and the
/// uniform scale in 2^-8 of the palette's linear units (which are 2^-15 position quanta per
/// bind quantum): finer than the linear values, so rounding the scale costs less than
/// rounding them does.
pub type Rig = [i64; 5];

/// Fraction bits of a rigid entry's scale.
pub const SCALE_BITS: u32 = 8;
/// Bound on a scale a reader accepts (2^40 linear units, as every palette value).
pub const MAX_SCALE: i64 = 1 << 48;

/// Bound on a quaternion component a reader accepts; keeps every product in 128 bits.
pub const MAX_QUATERNION: i64 = 1 << 24;
/// Exp-Golomb orders a chunk may choose (5 bits each).
const MAX_ORDER: u32 = 31;
/// The number classes whose Exp-Golomb order a chunk states: quaternion, scale, translation,
/// and the twelve values of entries that are not rigid.
const CLASSES: usize = 4;
/// The first 5 bits of a chunk in the linked coding ([`super::hierarchy`]): an order the plain
/// coding never writes for quaternions (their differences are under 2^28, which order 27 codes
/// in fewer bits), so every file written before it reads as before.
pub const LINKED: u64 = 31;

/// The integer matrix `L` (row-major, 2^-15 position quanta per bind quantum) of the rotation
/// of quaternion `q` scaled by `s / 2^8`: `L[a][c] = floor((2 s N[a][c] + 2^8 n) / (2^9 n))`,
/// `n = |q|^2`, `N` the quaternion's rotation matrix times `n`. `None` for the zero quaternion.
pub fn rig_matrix(r: &Rig) -> Option<[i64; 9]> {
    let [w, x, y, z, s] = r.map(|v| v as i128);
    let n = w * w + x * x + y * y + z * z;
    if n == 0 {
        return None;
    }
    let num = [
        w * w + x * x - y * y - z * z,
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        w * w - x * x + y * y - z * z,
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        w * w - x * x - y * y + z * z,
    ];
    // |num| <= n < 2^51 and |s| <= 2^48: every product fits 128 bits; |L| <= |s| / 2^8 + 1.
    let one = 1i128 << SCALE_BITS;
    Some(num.map(|m| (2 * s * m + one * n).div_euclid(2 * one * n) as i64))
}

/// What a Joints chunk's values are predicted from: the palettes as for Palette chunks, and
/// each entry's rigid parameters of the previous two frames (`None` where the entry was not
/// rigid, empty before a keyframe's successor).
#[derive(Clone, Copy, Debug)]
pub struct JointPrediction<'a> {
    pub pose: PosePrediction<'a>,
    pub rig: &'a [Option<Rig>],
    pub rig_before: &'a [Option<Rig>],
    /// Each entry's link since the last keyframe (linked coding; [`Link::NONE`]: none).
    pub links: &'a [Link],
}

impl JointPrediction<'_> {
    /// Entry `e`'s predicted rigid parameters: zero on keyframes and where the entry was not
    /// rigid in the previous frame; else the previous frame's, or the linear extrapolation
    /// `2 p1 - p2` when the frame before that had them too (and follows the keyframe).
    pub fn rig_at(&self, e: usize) -> Rig {
        if matches!(self.pose, PosePrediction::Key) {
            return [0; 5];
        }
        match (self.rig.get(e).copied().flatten(), self.rig_before.get(e).copied().flatten()) {
            (Some(p), Some(q)) if matches!(self.pose, PosePrediction::Linear(..)) => {
                [0, 1, 2, 3, 4].map(|i| p[i].wrapping_mul(2).wrapping_sub(q[i]))
            }
            (Some(p), _) => p,
            _ => [0; 5],
        }
    }
}

/// One frame's palette as a Joints chunk codes it: the values (a rigid entry's matrix rebuilt
/// by [`rig_matrix`]), each entry's rigid parameters (`None`: not rigid), whether the
/// entry is the same as in the previous frame, and each entry's link in the linked coding
/// (empty or [`Link::NONE`]: none).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JointsFrame {
    pub palette: Vec<i64>,
    pub rig: Vec<Option<Rig>>,
    pub held: Vec<bool>,
    pub links: Vec<Link>,
}

/// The coded numbers of one entry: (class, difference from the prediction).
fn entry_numbers(e: usize, frame: &JointsFrame, prediction: &JointPrediction, out: &mut Vec<(usize, i64)>) {
    let base = e * ENTRY;
    let value = |i: usize| frame.palette.get(base + i).copied().unwrap_or(0);
    match frame.rig.get(e).copied().flatten() {
        Some(r) => {
            let p = prediction.rig_at(e);
            for i in 0..4 {
                out.push((0, r[i].wrapping_sub(p[i])));
            }
            out.push((1, r[4].wrapping_sub(p[4])));
            for a in 0..3 {
                out.push((2, value(4 * a + 3).wrapping_sub(prediction.pose.at(base + 4 * a + 3))));
            }
        }
        None => {
            for i in 0..ENTRY {
                out.push((3, value(i).wrapping_sub(prediction.pose.at(base + i))));
            }
        }
    }
}

/// JOINTS (one frame, one band): the band mask as a varint, then bits: four 5-bit Exp-Golomb
/// orders (quaternion, scale, translation, general values), and per carried entry a bit
/// "moved" (not on keyframes), then for a moved entry a bit "rigid" and its numbers.
pub fn write_joints(mask: u64, entries: &[u32], frame: &JointsFrame, prediction: &JointPrediction) -> Vec<u8> {
    let key = matches!(prediction.pose, PosePrediction::Key);
    let moved = |e: usize| key || !frame.held.get(e).copied().unwrap_or(false);
    let mut numbers = Vec::new();
    for &e in entries.iter().filter(|&&e| moved(e as usize)) {
        entry_numbers(e as usize, frame, prediction, &mut numbers);
    }
    // Each class's order: the one that codes its numbers in the fewest bits.
    let orders: [u32; CLASSES] = std::array::from_fn(|c| {
        (0..=MAX_ORDER).min_by_key(|&k| numbers.iter().filter(|n| n.0 == c).map(|n| golomb_len(zigzag(n.1), k)).sum::<u64>()).unwrap_or(0)
    });
    let mut out = Vec::with_capacity(entries.len() * 8 + 4);
    put_mask(&mut out, mask);
    let mut bits = Bits::default();
    for k in orders {
        bits.put(k as u64, 5);
    }
    let mut at = 0;
    for &e in entries {
        let e = e as usize;
        if !key {
            bits.put(moved(e) as u64, 1);
        }
        if !moved(e) {
            continue;
        }
        let rigid = frame.rig.get(e).copied().flatten().is_some();
        bits.put(rigid as u64, 1);
        let count = if rigid { 8 } else { ENTRY };
        for &(class, d) in &numbers[at..at + count] {
            bits.golomb(zigzag(d), orders[class]);
        }
        at += count;
    }
    out.extend(bits.out);
    out
}

/// Writes the band mask as a varint.
pub(super) fn put_mask(out: &mut Vec<u8>, mask: u64) {
    let mut v = mask;
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// The shortest of the plain, the linked and the compact coding of a frame's chunk for
/// `entries`. On keyframes the plain coding is left out whenever an entry of the chunk has a
/// reference, since only a keyframe's chunk sends references (the frames up to the next
/// keyframe use them).
/// `(bands, j)`: each band's entries and the chunk's band.
pub fn write_joints_best(mask: u64, (bands, j): (&[Vec<u32>], usize), frame: &JointsFrame, prediction: &JointPrediction) -> Vec<u8> {
    let entries: &[u32] = bands.get(j).map(Vec::as_slice).unwrap_or_default();
    let linked = write_joints_linked(mask, entries, frame, prediction, None);
    let compact = write_joints_linked(mask, entries, frame, prediction, Some(seed(bands, j, &frame.palette, &frame.rig)));
    let mut best = if compact.len() < linked.len() { compact } else { linked };
    let any = matches!(prediction.pose, PosePrediction::Key)
        && entries.iter().any(|&e| frame.links.get(e as usize).is_some_and(|l| l.reference != NO_REF));
    if !any {
        let plain = write_joints(mask, entries, frame, prediction);
        if plain.len() <= best.len() {
            best = plain;
        }
    }
    best
}

/// A Joints payload's band mask (a varint of at most 64 bits naming bands below `levels`) and
/// the byte after it; the error says what is wrong, for the caller to name the chunk.
fn read_band_mask(bytes: &[u8], levels: usize) -> Result<(u64, usize), String> {
    let mut mask: u64 = 0;
    let mut pos = 0;
    for shift in (0..64).step_by(7) {
        let Some(&b) = bytes.get(pos) else { return Err("ends inside its band mask".into()) };
        pos += 1;
        if shift == 63 && b > 1 {
            return Err("band mask beyond 64 bits".into());
        }
        mask |= ((b & 0x7f) as u64) << shift;
        if b & 0x80 == 0 {
            break;
        }
        if shift == 63 {
            return Err("band mask longer than 10 bytes".into());
        }
    }
    if levels < 64 && mask >> levels != 0 {
        return Err(format!("band mask {mask:#x} names bands beyond the file's {levels}"));
    }
    Ok((mask, pos))
}

/// A link's pivot (three signed numbers read by `signed`), each within the bind limit.
fn read_pivot(
    r: &mut BitReader,
    e: u32,
    mut signed: impl FnMut(&mut BitReader) -> Result<i64, ContainerError>,
) -> Result<[i64; 3], ContainerError> {
    let mut pivot = [0i64; 3];
    for c in &mut pivot {
        *c = signed(r)?;
        if c.unsigned_abs() > super::MAX_BIND as u64 {
            return Err(r.corrupt(format!("palette entry {e}: pivot coordinate {c} beyond the limit of {}", super::MAX_BIND)));
        }
    }
    Ok(pivot)
}

/// The orders of a chunk's number classes as a reader learns them, and whether a class's
/// order may say that its numbers are all 0 (the compact coding's [`ZERO_CLASS`]).
struct Orders {
    known: [Option<u32>; LINKED_CLASSES],
    compact: bool,
}

impl Orders {
    /// The next signed number of `class`, its order read before its first number.
    fn signed(&mut self, r: &mut BitReader, class: usize) -> Result<i64, ContainerError> {
        let k = match self.known[class] {
            Some(k) => k,
            None => {
                let k = r.get(5)? as u32;
                self.known[class] = Some(k);
                k
            }
        };
        if self.compact && k == ZERO_CLASS {
            return Ok(0);
        }
        r.golomb(k).map(unzigzag)
    }
}

/// A rigid entry's twelve values and parameters from its prediction `p`, reading its numbers
/// unless `exact`.
fn read_rigid(r: &mut BitReader, e: usize, p: &Predicted, exact: bool, orders: &mut Orders) -> Result<([i64; ENTRY], Rig), ContainerError> {
    let (qc, tc) = if p.linked { (4, 5) } else { (0, 2) };
    let mut q = p.rig;
    if !exact {
        for i in 0..5 {
            q[i] = p.rig[i].wrapping_add(orders.signed(r, if i < 4 { qc } else { 1 })?);
        }
    }
    if q[..4].iter().any(|c| c.unsigned_abs() > MAX_QUATERNION as u64) {
        return Err(r.corrupt(format!("palette entry {e}: quaternion {:?} beyond the limit of {MAX_QUATERNION}", &q[..4])));
    }
    if q[4].unsigned_abs() > MAX_SCALE as u64 {
        return Err(r.corrupt(format!("palette entry {e}: scale {} beyond the limit of {MAX_SCALE}", q[4])));
    }
    let Some(m) = rig_matrix(&q) else { return Err(r.corrupt(format!("palette entry {e}: the zero quaternion"))) };
    let mut t = p.translation(&m);
    if !exact {
        for v in &mut t {
            *v = v.wrapping_add(orders.signed(r, tc)?);
        }
    }
    let mut values = [0i64; ENTRY];
    for a in 0..3 {
        values[4 * a..4 * a + 3].copy_from_slice(&m[3 * a..3 * a + 3]);
        values[4 * a + 3] = t[a];
    }
    Ok((values, q))
}

/// Reads a JOINTS payload of band `j` (carrying `bands[j]`, `bands` the entries each band
/// carries) for a file of `levels` bands into the frame's `palette`, `rig` and `links` (entries
/// it does not carry left as they are; entries of coarser bands already read); returns the
/// band mask. Reads every coding: the plain one, the linked one when its first 5 bits are
/// [`LINKED`], the compact one when they are [`COMPACT`].
pub fn read_joints(
    bytes: &[u8],
    what: &str,
    (bands, j): (&[Vec<u32>], usize),
    levels: usize,
    prediction: &JointPrediction,
    (palette, rig, links): (&mut [i64], &mut [Option<Rig>], &mut [Link]),
) -> Result<u64, ContainerError> {
    let corrupt = |detail: String| ContainerError::Corrupt { what: what.to_string(), detail };
    let entries: &[u32] = bands.get(j).map(Vec::as_slice).unwrap_or_default();
    let (mask, pos) = read_band_mask(bytes, levels).map_err(corrupt)?;
    let mut r = BitReader { bytes: &bytes[pos..], bit: 0, what };
    let key = matches!(prediction.pose, PosePrediction::Key);
    let n = palette.len() / ENTRY;
    for &e in entries {
        let e = e as usize;
        if e >= n || rig.len() <= e || links.len() <= e {
            return Err(corrupt(format!("palette entry {e} beyond the palette of {n}")));
        }
        // A keyframe's links come with its chunks (none in the plain coding); other frames keep
        // the keyframe's.
        links[e] = if key { Link::NONE } else { prediction.links.get(e).copied().unwrap_or(Link::NONE) };
    }
    let first = r.get(5)?;
    let compact = first == COMPACT;
    let linked = first == LINKED || compact;
    // Orders: the plain coding's four up front; the linked codings' each before its first number.
    let mut orders = Orders { known: [None; LINKED_CLASSES], compact };
    if !linked {
        orders.known[0] = Some(first as u32);
        for k in &mut orders.known[1..CLASSES] {
            *k = Some(r.get(5)? as u32);
        }
    }
    let all_rigid = compact && r.bit()? == 1;
    let previous = prediction.pose.previous();
    if linked && key {
        let width = ref_bits(n);
        for &e in entries {
            if r.bit()? == 1 {
                let p = r.get(width)?;
                if p as usize >= n || p == e as u64 || !read_before(bands, p as u32, e) {
                    return Err(corrupt(format!("palette entry {e}: reference {p} is not an entry read before it")));
                }
                let pivot = read_pivot(&mut r, e, |r| orders.signed(r, 6))?;
                links[e as usize] = Link { reference: p as u32, pivot };
            }
        }
    }
    // The compact coding's keyframe prediction of an entry without a reference.
    let mut last = if compact && key { seed(bands, j, &*palette, &*rig) } else { None };
    for &e in entries {
        let e = e as usize;
        let base = e * ENTRY;
        let moved = key || r.bit()? == 1;
        if !moved {
            for i in base..base + ENTRY {
                palette[i] = previous.and_then(|p| p.get(i)).copied().unwrap_or(0);
            }
            rig[e] = prediction.rig.get(e).copied().flatten();
            continue;
        }
        let values = if all_rigid || r.bit()? == 1 {
            let (mut p, exact) = if linked {
                (predict(e, links[e], prediction, (&*palette, &*rig)), r.bit()? == 1)
            } else {
                let t = [3, 7, 11].map(|i| prediction.pose.at(base + i));
                (Predicted { rig: prediction.rig_at(e), t, linked: false, anchor: None }, false)
            };
            if compact && key {
                p = chained(p, last);
            }
            let (values, q) = read_rigid(&mut r, e, &p, exact, &mut orders)?;
            rig[e] = Some(q);
            last = Some((q, [values[3], values[7], values[11]]));
            values
        } else {
            let mut values = [0i64; ENTRY];
            for (i, v) in values.iter_mut().enumerate() {
                *v = prediction.pose.at(base + i).wrapping_add(orders.signed(&mut r, 3)?);
            }
            rig[e] = None;
            values
        };
        for (i, &v) in values.iter().enumerate() {
            if v.unsigned_abs() > MAX_MATRIX as u64 {
                let name = if i % 4 == 3 { "translation" } else { "linear value" };
                return Err(corrupt(format!("palette entry {e} {name} {v} beyond the limit of {MAX_MATRIX}")));
            }
        }
        palette[base..base + ENTRY].copy_from_slice(&values);
    }
    r.finish()?;
    Ok(mask)
}

/// The largest move of a bind point within `radius` (per row, the L1 norm of the error times
/// the radius), in position quanta, of the linear part `rig` rebuilds against the unrounded
/// entry `m`; `None` for the zero quaternion.
pub fn rig_error(m: &[f64], rig: &Rig, radius: f64) -> Option<f64> {
    let l = |a: usize, c: usize| m.get(4 * a + c).copied().unwrap_or(0.0);
    let rebuilt = rig_matrix(rig)?;
    let row = (0..3).map(|a| (0..3).map(|c| (rebuilt[3 * a + c] as f64 - l(a, c)).abs()).sum::<f64>()).fold(0.0, f64::max);
    Some(row * radius / (1u64 << LINEAR_BITS) as f64)
}

/// The encoder's choice for one entry of one frame from its unrounded fixed-point values `m`
/// (ENTRY values, the palette's units): its rigid parameters when a rotation and uniform scale
/// rebuild its linear part within `tolerance` position quanta on every bind point of norm up to
/// `radius` bind quanta, else `None`. The quaternion takes the sign nearer `predicted`, and its
/// norm follows the prediction's (kept within [2^b, 2^(b+1)], `b` chosen so that a rotation
/// error of its rounding moves a point at `radius` by under a quarter quantum), so a steady
/// rotation leaves differences in its direction only.
pub fn fit_rig(m: &[f64], radius: f64, predicted: Rig, tolerance: f64) -> Option<Rig> {
    let l = |a: usize, c: usize| m.get(4 * a + c).copied().unwrap_or(0.0);
    let det = l(0, 0) * (l(1, 1) * l(2, 2) - l(1, 2) * l(2, 1)) - l(0, 1) * (l(1, 0) * l(2, 2) - l(1, 2) * l(2, 0))
        + l(0, 2) * (l(1, 0) * l(2, 1) - l(1, 1) * l(2, 0));
    let s = det.cbrt();
    if !(s.is_finite() && s.abs() >= 1.0) {
        return None;
    }
    let r = |a: usize, c: usize| l(a, c) / s;
    // The quaternion of rotation r (Shepperd's method: the largest of the four diagonal sums).
    let t = [r(0, 0) + r(1, 1) + r(2, 2), r(0, 0) - r(1, 1) - r(2, 2), r(1, 1) - r(0, 0) - r(2, 2), r(2, 2) - r(0, 0) - r(1, 1)];
    let big = (0..4).max_by(|&a, &b| t[a].total_cmp(&t[b])).unwrap_or(0);
    let h = (1.0 + t[big]).max(1e-300).sqrt() * 2.0;
    let q = match big {
        0 => [h / 4.0, (r(2, 1) - r(1, 2)) / h, (r(0, 2) - r(2, 0)) / h, (r(1, 0) - r(0, 1)) / h],
        1 => [(r(2, 1) - r(1, 2)) / h, h / 4.0, (r(0, 1) + r(1, 0)) / h, (r(0, 2) + r(2, 0)) / h],
        2 => [(r(0, 2) - r(2, 0)) / h, (r(0, 1) + r(1, 0)) / h, h / 4.0, (r(1, 2) + r(2, 1)) / h],
        _ => [(r(1, 0) - r(0, 1)) / h, (r(0, 2) + r(2, 0)) / h, (r(1, 2) + r(2, 1)) / h, h / 4.0],
    };
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    // Rounding each component moves the rotation by about 2 / 2^b radians; a bind point at
    // `radius` moves by |s| radius 2 / 2^(b + 15) quanta: under a quarter quantum.
    let need = (8.0 * s.abs() * radius.max(1.0) / (1u64 << LINEAR_BITS) as f64).log2().ceil().clamp(4.0, 22.0);
    let (lo, hi) = (need.exp2(), (need + 1.0).exp2());
    let p_norm = predicted[..4].iter().map(|&v| (v as f64).powi(2)).sum::<f64>().sqrt();
    let rho = if p_norm > 0.0 { p_norm.clamp(lo, hi) } else { lo };
    let dot: f64 = q.iter().zip(&predicted[..4]).map(|(a, &b)| a * b as f64).sum();
    let sign = if dot < 0.0 || (dot == 0.0 && q[0] < 0.0) { -1.0 } else { 1.0 };
    let qi = q.map(|v| (v / norm * rho * sign).round() as i64);
    let worst = |rig: &Rig| rig_error(m, rig, radius);
    // The predicted scale where it does (a constant scale then costs nothing: the input's own
    // scale varies in its last bits from frame to frame), else the scale rounded.
    let held = [qi[0], qi[1], qi[2], qi[3], predicted[4]];
    if predicted[4] != 0 && worst(&held).is_some_and(|w| w <= tolerance) {
        return Some(held);
    }
    let rig = [qi[0], qi[1], qi[2], qi[3], (s * (1u64 << SCALE_BITS) as f64).round() as i64];
    if rig[4].unsigned_abs() > MAX_SCALE as u64 {
        return None;
    }
    worst(&rig).filter(|&w| w <= tolerance).map(|_| rig)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotation(axis: [f64; 3], angle: f64, scale: f64, t: [f64; 3]) -> Vec<f64> {
        let n = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
        let [x, y, z] = axis.map(|v| v / n * (angle / 2.0).sin());
        let w = (angle / 2.0).cos();
        let r = [
            [w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ];
        let mut m = Vec::new();
        for a in 0..3 {
            m.extend(r[a].map(|v| v * scale));
            m.push(t[a]);
        }
        m
    }

    #[test]
    fn rigid_entries_rebuild_within_the_tolerance_and_sheared_ones_are_refused() {
        for (i, angle) in [0.0, 0.3, 1.7, 3.1, -2.5].into_iter().enumerate() {
            let scale = [16384.0, 9000.5, 30000.0, 2.0e5, 20000.0][i];
            let m = rotation([1.0, -2.0, 0.5 + i as f64], angle, scale, [5.0, -7.0, 1e5]);
            // A quarter quantum beyond what rounding the twelve values moves a point by.
            let radius = 40000.0;
            let tolerance = 0.25 + 1.5 * radius / 32768.0;
            let rig = fit_rig(&m, radius, [0; 5], tolerance).unwrap_or_else(|| panic!("angle {angle} scale {scale}: not rigid"));
            let l = rig_matrix(&rig).expect("matrix");
            for a in 0..3 {
                let err: f64 = (0..3).map(|c| (l[3 * a + c] as f64 - m[4 * a + c]).abs()).sum();
                assert!(err * radius / 32768.0 <= tolerance, "angle {angle} row {a}: {err}");
            }
        }
        let mut sheared = rotation([0.0, 0.0, 1.0], 0.4, 16384.0, [0.0; 3]);
        sheared[1] += 800.0;
        assert_eq!(fit_rig(&sheared, 40000.0, [0; 5], 2.1), None);
    }

    #[test]
    fn joints_round_trip_and_damage_is_named() {
        let entries = [0u32, 2, 3];
        let mut frames = Vec::new();
        for f in 0..4 {
            let mut frame = JointsFrame { palette: vec![0; 4 * ENTRY], rig: vec![None; 4], held: vec![false; 4], links: Vec::new() };
            for &e in &entries {
                let e = e as usize;
                let m = rotation([1.0, e as f64, 2.0], 0.1 * f as f64 + e as f64, 16000.0, [100.0 * f as f64, -3.0, 7.0 * e as f64]);
                let rig = if e == 3 {
                    None
                } else {
                    fit_rig(
                        &m,
                        30000.0,
                        frames.last().map_or([0; 5], |p: &JointsFrame| p.rig[e].unwrap_or([0; 5])),
                        0.25 + 1.5 * 30000.0 / 32768.0,
                    )
                };
                let values: Vec<i64> = match rig {
                    Some(r) => {
                        let l = rig_matrix(&r).expect("matrix");
                        (0..ENTRY).map(|i| if i % 4 == 3 { m[i].round() as i64 } else { l[3 * (i / 4) + i % 4] }).collect()
                    }
                    None => m.iter().map(|v| v.round() as i64).collect(),
                };
                frame.palette[e * ENTRY..(e + 1) * ENTRY].copy_from_slice(&values);
                frame.rig[e] = rig;
            }
            if f == 3 {
                // Entry 2 holds still in the last frame.
                let before: &JointsFrame = &frames[2];
                frame.palette[2 * ENTRY..3 * ENTRY].copy_from_slice(&before.palette[2 * ENTRY..3 * ENTRY]);
                frame.rig[2] = before.rig[2];
                frame.held[2] = true;
            }
            frames.push(frame);
        }
        // Entries 0 and 2 are rigid in every frame (3 is sent as twelve values); a constant
        // scale is held from frame to frame, so it costs nothing after the first.
        assert!(frames.iter().all(|f| f.rig[0].is_some() && f.rig[2].is_some() && f.rig[3].is_none()));
        let scale = |f: usize| frames[f].rig[0].map(|r: Rig| r[4]);
        assert!(scale(0).is_some() && (1..4).all(|f| scale(f) == scale(0)), "{:?}", (0..4).map(scale).collect::<Vec<_>>());
        let (mut palette, mut rig, mut links) = (vec![0i64; 4 * ENTRY], vec![None; 4], vec![Link::NONE; 4]);
        let bands = [vec![], entries.to_vec()];
        let (mut held, mut before): (Vec<i64>, Vec<i64>) = (Vec::new(), Vec::new());
        let (mut held_rig, mut before_rig): (Vec<Option<Rig>>, Vec<Option<Rig>>) = (Vec::new(), Vec::new());
        for (f, frame) in frames.iter().enumerate() {
            let pose = match f {
                0 => PosePrediction::Key,
                1 => PosePrediction::Previous(&held),
                _ => PosePrediction::Linear(&held, &before),
            };
            let p = JointPrediction { pose, rig: &held_rig, rig_before: &before_rig, links: &[] };
            let bytes = write_joints(0b10, &entries, frame, &p);
            assert_eq!(read_joints(&bytes, "j", (&bands, 1), 2, &p, (&mut palette, &mut rig, &mut links)).expect("joints"), 0b10);
            assert_eq!(palette, frame.palette, "frame {f}");
            assert_eq!(rig, frame.rig, "frame {f}");
            if f == 3 {
                let e = read_joints(
                    &bytes[..bytes.len() - 1],
                    "frame 3 band 1 joints",
                    (&bands, 1),
                    2,
                    &p,
                    (&mut palette, &mut rig, &mut links),
                )
                .expect_err("short")
                .to_string();
                assert!(e.contains("frame 3 band 1 joints") && e.contains("ends inside its bits"), "{e}");
                let mut long = bytes.clone();
                long.push(0);
                let e = read_joints(&long, "j", (&bands, 1), 2, &p, (&mut palette, &mut rig, &mut links)).expect_err("long").to_string();
                assert!(e.contains("1 bytes left over"), "{e}");
                let e = read_joints(&bytes, "j", (&bands, 1), 1, &p, (&mut palette, &mut rig, &mut links)).expect_err("mask").to_string();
                assert!(e.contains("band mask 0x2 names bands beyond the file's 1"), "{e}");
            }
            before = std::mem::replace(&mut held, frame.palette.clone());
            before_rig = std::mem::replace(&mut held_rig, frame.rig.clone());
        }
        // A zero quaternion is refused by name.
        let zero = JointsFrame { palette: vec![0; ENTRY], rig: vec![Some([0, 0, 0, 0, 100])], held: vec![false], links: Vec::new() };
        let key = JointPrediction { pose: PosePrediction::Key, rig: &[], rig_before: &[], links: &[] };
        let bytes = write_joints(0, &[0], &zero, &key);
        let e = read_joints(&bytes, "j", (&[vec![0]], 0), 1, &key, (&mut palette[..ENTRY], &mut rig[..1], &mut links[..1]))
            .expect_err("zero")
            .to_string();
        assert!(e.contains("palette entry 0: the zero quaternion"), "{e}");
    }
    #[test]
    fn linked_chunks_round_trip_and_bad_links_are_refused() {
        use crate::skin::hierarchy::fit_frame;
        // A chain of three joints, entry 0 the root (the top band), 1 and 2 in band 0, each
        // turning about its own pivot relative to its parent; entry 2 holds still relative to 1.
        let bands = vec![vec![1u32, 2], vec![0u32]];
        let order = [0u32, 1, 2];
        let pivots = [[0i64, 0, 0], [0, 4000, 0], [0, 8000, 0]];
        let links = vec![Link::NONE, Link { reference: 0, pivot: pivots[1] }, Link { reference: 1, pivot: pivots[2] }];
        let compose = |a: &[f64], b: &[f64]| -> Vec<f64> {
            // (a b) for 3x4 affine maps in the palette's fixed point.
            let mut out = vec![0.0; ENTRY];
            for r in 0..3 {
                for c in 0..4 {
                    // Linear parts in 2^-15, translations in quarter units: T = T_a + L_a T_b / 2^15.
                    let v: f64 = (0..3).map(|k| a[4 * r + k] * b[4 * k + c] / 32768.0).sum();
                    out[4 * r + c] = if c == 3 { a[4 * r + 3] + v } else { v };
                }
            }
            out
        };
        let about = |pivot: [i64; 3], angle: f64| -> Vec<f64> {
            // A rotation about the bind point `pivot` (bind quanta to bind quanta): L = 2^15 R,
            // T = 4 (p - R p).
            let mut m = rotation([0.3, 0.2, 1.0], angle, 32768.0, [0.0; 3]);
            for a in 0..3 {
                let rp: f64 = (0..3).map(|k| m[4 * a + k] / 32768.0 * pivot[k] as f64).sum();
                m[4 * a + 3] = 4.0 * (pivot[a] as f64 - rp);
            }
            m
        };
        let (mut held, mut held_rig, mut held_links): (Vec<i64>, Vec<Option<Rig>>, Vec<Link>) = (Vec::new(), Vec::new(), Vec::new());
        let (mut before, mut before_rig): (Vec<i64>, Vec<Option<Rig>>) = (Vec::new(), Vec::new());
        for f in 0..6 {
            let t = f as f64 * 0.1;
            let root = rotation([0.0, 1.0, 0.2], 0.5 * t, 30000.0, [400.0 * t, 20.0, -5.0]);
            let one = compose(&root, &about(pivots[1], 0.8 * t + 0.2));
            let two = compose(&one, &about(pivots[2], 0.4));
            let fixed: Vec<f64> = [root, one, two].concat();
            let key = f % 4 == 0;
            let pose = match f % 4 {
                0 => PosePrediction::Key,
                1 => PosePrediction::Previous(&held),
                _ => PosePrediction::Linear(&held, &before),
            };
            let p = JointPrediction { pose, rig: &held_rig, rig_before: &before_rig, links: &held_links };
            let frame_links = if key { links.clone() } else { held_links.clone() };
            let frame = fit_frame(&fixed, |_| (12000.0, 4500.0), |_| false, &order, frame_links, (&p, &held, key));
            assert!(frame.rig.iter().all(Option::is_some), "frame {f}: every entry rigid");
            let (mut palette, mut rig, mut got) = (vec![0i64; 3 * ENTRY], vec![None; 3], vec![Link::NONE; 3]);
            let top = write_joints_linked(0b11, &bands[1], &frame, &p, None);
            let low = write_joints_linked(0b11, &bands[0], &frame, &p, None);
            assert_eq!(top[1] & 31, LINKED as u8, "the tag");
            read_joints(&top, "top", (&bands, 1), 2, &p, (&mut palette, &mut rig, &mut got)).expect("top band");
            read_joints(&low, "low", (&bands, 0), 2, &p, (&mut palette, &mut rig, &mut got)).expect("band 0");
            assert_eq!(palette, frame.palette, "frame {f}");
            assert_eq!(rig, frame.rig, "frame {f}");
            assert_eq!(got, frame.links, "frame {f}");
            // The compact coding rebuilds the same frame, never in more bytes here (its scales
            // are a zero class, every entry is rigid), and says so in its first 5 bits.
            let (mut palette2, mut rig2, mut got2) = (vec![0i64; 3 * ENTRY], vec![None; 3], vec![Link::NONE; 3]);
            for (j, linked) in [(1, &top), (0, &low)] {
                let compact = write_joints_linked(0b11, &bands[j], &frame, &p, Some(seed(&bands, j, &frame.palette, &frame.rig)));
                assert_eq!(compact[1] & 31, crate::skin::linked::COMPACT as u8, "the compact tag");
                assert!(compact.len() <= linked.len(), "frame {f} band {j}: {} > {}", compact.len(), linked.len());
                read_joints(&compact, "c", (&bands, j), 2, &p, (&mut palette2, &mut rig2, &mut got2)).expect("compact");
            }
            assert_eq!((palette2, rig2, got2), (frame.palette.clone(), frame.rig.clone(), frame.links.clone()), "frame {f} compact");
            // The joint that holds still relative to its parent is sent as its prediction (its
            // flags alone) once the frames after the keyframe show its motion.
            if !key {
                let predicted = crate::skin::hierarchy::predict(2, frame.links[2], &p, (&frame.palette, &frame.rig));
                assert!(predicted.linked && frame.rig[2] == Some(predicted.rig), "frame {f}: {predicted:?} for {:?}", frame.rig[2]);
                let l = rig_matrix(&predicted.rig).expect("matrix");
                // Its translations follow from the pivot, within the rounding of the input's.
                let (t, sent) = (predicted.translation(&l), [3, 7, 11].map(|i| frame.palette[2 * ENTRY + i]));
                assert!((0..3).all(|a| (t[a] - sent[a]).abs() <= 1), "frame {f}: {t:?} for {sent:?}");
            }
            if key {
                // A reference not read before its entry (2 after 1 in the same band) is refused.
                let mut bad = frame.clone();
                bad.links[1] = Link { reference: 2, pivot: [0; 3] };
                let raw = write_joints_linked(0b11, &bands[0], &bad, &p, None);
                let e = read_joints(&raw, "b", (&bands, 0), 2, &p, (&mut palette, &mut rig, &mut got)).expect_err("order").to_string();
                assert!(e.contains("palette entry 1: reference 2 is not an entry read before it"), "{e}");
                bad.links[1] = Link { reference: 0, pivot: [0, 1 << 31, 0] };
                let raw = write_joints_linked(0b11, &bands[0], &bad, &p, None);
                let e = read_joints(&raw, "b", (&bands, 0), 2, &p, (&mut palette, &mut rig, &mut got)).expect_err("pivot").to_string();
                assert!(e.contains("pivot coordinate 2147483648 beyond the limit"), "{e}");
                let e = read_joints(&low[..low.len() - 1], "cut", (&bands, 0), 2, &p, (&mut palette, &mut rig, &mut got))
                    .expect_err("short")
                    .to_string();
                assert!(e.contains("cut: ends inside its bits"), "{e}");
            }
            before = std::mem::replace(&mut held, frame.palette.clone());
            before_rig = std::mem::replace(&mut held_rig, frame.rig.clone());
            held_links = frame.links.clone();
            if key {
                before.clear();
                before_rig.clear();
            }
        }
    }

    #[test]
    fn the_plain_coding_never_writes_the_linked_tag() {
        // The largest quaternion differences there are (one component from -2^24 to 2^24 and
        // back) still take an order below 31.
        let big = JointsFrame {
            palette: vec![0; ENTRY],
            rig: vec![Some([1 << 24, -(1 << 24), 1 << 24, -(1 << 24), 1 << 30])],
            held: vec![false],
            links: Vec::new(),
        };
        let before = [Some([-(1 << 24), 1 << 24, -(1 << 24), 1 << 24, 0])];
        let p = JointPrediction { pose: PosePrediction::Linear(&[0; ENTRY], &[0; ENTRY]), rig: &before, rig_before: &before, links: &[] };
        let raw = write_joints(0, &[0], &big, &p);
        assert_ne!(raw[1] & 31, LINKED as u8);
        assert!(raw[1] & 31 < 29, "order {}", raw[1] & 31);
    }
}
