//! The writers of the Joints chunk's linked and compact codings (proto/container.md, "Joints",
//! "Linked coding", "Compact coding"); [`super::hierarchy`] predicts their entries and
//! [`super::joints::read_joints`] reads them.
//!
//! The compact coding is the linked one with three changes, each measured on RobotExpressive
//! and Fox before it was kept: a class whose numbers in the chunk are all 0 says so with its
//! order (31, which it then never needs) and sends none of them (the scale of an entry that
//! keeps its scale costs nothing instead of a bit per frame); a bit "all rigid" drops the
//! per-entry rigid bit where every moved entry is rigid (a skeleton's always are); and on
//! keyframes an entry without a reference is predicted from the rigid entry decoded before it
//! (in the chunk, or for its first in the nearest coarser band: [`seed`]) instead of from 0, so
//! the scale and rotation the entries of one character share are sent once per keyframe, not
//! once per entry.

use super::ENTRY;
use super::bits::{Bits, golomb_len, zigzag};
use super::hierarchy::{Link, NO_REF, Predicted, predict};
use super::joints::{JointPrediction, JointsFrame, LINKED, Rig, rig_matrix};
use super::payload::PosePrediction;

/// The first 5 bits of a chunk in the compact coding: an order the plain coding never writes
/// for quaternions (as [`LINKED`]), so files written before it read as before.
pub const COMPACT: u64 = 30;
/// A class's order in the compact coding that says its numbers in the chunk are all 0 (and
/// none is sent); real orders are then at most 30.
pub const ZERO_CLASS: u32 = 31;
/// The linked coding's number classes: the plain coding's four (quaternion, scale,
/// translation, non-rigid values), then the quaternions and translations of linked entries,
/// and pivots.
pub const LINKED_CLASSES: usize = 7;

/// The keyframe prediction of the compact coding for an entry without a reference: the rigid
/// parameters and translations of the rigid entry decoded before it in the chunk (`last`), or
/// the temporal prediction (0 on keyframes) for the chunk's first.
pub fn chained(p: Predicted, last: Option<(Rig, [i64; 3])>) -> Predicted {
    match last {
        Some((rig, t)) if !p.linked => Predicted { rig, t, linked: false, anchor: None },
        _ => p,
    }
}

/// The prediction of a keyframe's first rigid entry without a reference in the compact coding
/// of band `j`'s chunk: the last rigid entry (in ascending order) of the nearest coarser band
/// that has one, all of which a reader of band `j` has decoded this frame; `None` (from 0) when
/// no coarser band has a rigid entry.
pub fn seed(bands: &[Vec<u32>], j: usize, palette: &[i64], rig: &[Option<Rig>]) -> Option<(Rig, [i64; 3])> {
    let band = |b: &Vec<u32>| {
        b.iter().rev().find_map(|&e| {
            let e = e as usize;
            rig.get(e).copied().flatten().map(|r| (r, [3, 7, 11].map(|i| palette.get(e * ENTRY + i).copied().unwrap_or(0))))
        })
    };
    bands.iter().skip(j + 1).find_map(band)
}

/// Bits of a reference in a palette of `n` entries: `ceil(log2 n)`.
pub fn ref_bits(n: usize) -> u32 {
    (n.max(1) as u64).next_power_of_two().trailing_zeros()
}

/// Per carried entry that moved: whether rigid, and its numbers (class, difference; empty:
/// exact).
type Coded = Vec<(bool, Vec<(usize, i64)>)>;

/// The numbers of the moved entries of a linked or compact chunk.
fn code_entries(
    entries: &[u32],
    frame: &JointsFrame,
    prediction: &JointPrediction,
    link: impl Fn(usize) -> Link,
    compact: Option<Option<(Rig, [i64; 3])>>,
) -> Coded {
    let key = matches!(prediction.pose, PosePrediction::Key);
    let moved = |e: usize| key || !frame.held.get(e).copied().unwrap_or(false);
    let mut coded: Coded = Vec::with_capacity(entries.len());
    let mut last: Option<(Rig, [i64; 3])> = compact.flatten();
    for &e in entries.iter().filter(|&&e| moved(e as usize)) {
        let e = e as usize;
        let base = e * ENTRY;
        let value = |i: usize| frame.palette.get(base + i).copied().unwrap_or(0);
        let mut numbers = Vec::new();
        match frame.rig.get(e).copied().flatten() {
            Some(r) => {
                let mut p = predict(e, link(e), prediction, (&frame.palette, &frame.rig));
                if compact.is_some() && key {
                    p = chained(p, last);
                }
                let (q, t) = if p.linked { (4, 5) } else { (0, 2) };
                for i in 0..4 {
                    numbers.push((q, r[i].wrapping_sub(p.rig[i])));
                }
                numbers.push((1, r[4].wrapping_sub(p.rig[4])));
                let tp = rig_matrix(&r).map_or(p.t, |l| p.translation(&l));
                for a in 0..3 {
                    numbers.push((t, value(4 * a + 3).wrapping_sub(tp[a])));
                }
                if numbers.iter().all(|n| n.1 == 0) {
                    numbers.clear();
                }
                last = Some((r, [3, 7, 11].map(value)));
                coded.push((true, numbers));
            }
            None => {
                for i in 0..ENTRY {
                    numbers.push((3, value(i).wrapping_sub(prediction.pose.at(base + i))));
                }
                coded.push((false, numbers));
            }
        }
    }
    coded
}

/// JOINTS in the linked coding (proto/container.md, "Joints", "Linked coding"), or with
/// `compact` in the compact coding: the band mask, then bits: 5 bits [`LINKED`] (compact:
/// [`COMPACT`] and the bit "all rigid"); on keyframes each carried entry's reference (a bit,
/// and when set the entry in `ceil(log2 P)` bits, and its pivot); per carried entry a bit
/// "moved" (not on keyframes), then for a moved entry a bit "rigid" (compact: unless all are),
/// for a rigid one a bit "exact" (its numbers all 0), then its numbers, each class's 5-bit
/// Exp-Golomb order before its first number (compact: [`ZERO_CLASS`] where all are 0, and then
/// none of them). `compact`: `None` for the linked coding, else the compact coding with the
/// keyframe prediction of its first entry without a reference ([`seed`]).
pub fn write_joints_linked(
    mask: u64,
    entries: &[u32],
    frame: &JointsFrame,
    prediction: &JointPrediction,
    compact: Option<Option<(Rig, [i64; 3])>>,
) -> Vec<u8> {
    let seeded = compact;
    let compact = compact.is_some();
    let key = matches!(prediction.pose, PosePrediction::Key);
    let links = if key { frame.links.as_slice() } else { prediction.links };
    let link = |e: usize| links.get(e).copied().unwrap_or(Link::NONE);
    let moved = |e: usize| key || !frame.held.get(e).copied().unwrap_or(false);
    let coded = code_entries(entries, frame, prediction, link, seeded);
    // Keyframes: each carried entry's pivot, when it has a reference.
    let pivots: Vec<(usize, i64)> = if key {
        entries.iter().map(|&e| link(e as usize)).filter(|l| l.reference != NO_REF).flat_map(|l| l.pivot.map(|c| (6, c))).collect()
    } else {
        Vec::new()
    };
    let top = if compact { ZERO_CLASS - 1 } else { 31 };
    let orders: [u32; LINKED_CLASSES] = std::array::from_fn(|c| {
        let class = || coded.iter().flat_map(|x| &x.1).chain(&pivots).filter(|n| n.0 == c);
        if compact && class().all(|n| n.1 == 0) {
            return ZERO_CLASS;
        }
        (0..=top).min_by_key(|&k| class().map(|n| golomb_len(zigzag(n.1), k)).sum::<u64>()).unwrap_or(0)
    });
    let all_rigid = compact && coded.iter().all(|x| x.0);
    let mut sent = [false; LINKED_CLASSES];
    let mut bits = Bits::default();
    let mut number = |bits: &mut Bits, class: usize, d: i64| {
        if !sent[class] {
            sent[class] = true;
            bits.put(orders[class] as u64, 5);
        }
        if orders[class] != ZERO_CLASS || !compact {
            bits.golomb(zigzag(d), orders[class]);
        }
    };
    bits.put(if compact { COMPACT } else { LINKED }, 5);
    if compact {
        bits.put(all_rigid as u64, 1);
    }
    if key {
        let width = ref_bits(frame.palette.len() / ENTRY);
        for &e in entries {
            let l = link(e as usize);
            bits.put((l.reference != NO_REF) as u64, 1);
            if l.reference != NO_REF {
                bits.put(l.reference as u64, width);
                for c in l.pivot {
                    number(&mut bits, 6, c);
                }
            }
        }
    }
    let mut next = coded.iter();
    for &e in entries {
        if !key {
            bits.put(moved(e as usize) as u64, 1);
        }
        if !moved(e as usize) {
            continue;
        }
        let Some((rigid, numbers)) = next.next() else { break };
        if !all_rigid {
            bits.put(*rigid as u64, 1);
        }
        if *rigid {
            bits.put(numbers.is_empty() as u64, 1);
        }
        for &(class, d) in numbers {
            number(&mut bits, class, d);
        }
    }
    let mut out = Vec::with_capacity(entries.len() * 4 + 4);
    super::joints::put_mask(&mut out, mask);
    out.extend(bits.out);
    out
}
