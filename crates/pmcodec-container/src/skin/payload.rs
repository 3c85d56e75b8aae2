//! The skin chunks' payloads (proto/container.md, "Bind" and "Pose"): unsigned LEB128 varints
//! up to 64 bits, signed values zigzag-encoded.

use super::{ENTRY, MAX_BIND, MAX_MATRIX, NodeSkin, WEIGHT_ONE};
use crate::ContainerError;

fn put64(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn zigzag64(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag64(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

/// A bounds-checked reader of 64-bit varints over one chunk.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    what: &'a str,
}

impl Cursor<'_> {
    fn corrupt(&self, detail: impl Into<String>) -> ContainerError {
        ContainerError::Corrupt { what: self.what.to_string(), detail: detail.into() }
    }

    fn get(&mut self) -> Result<u64, ContainerError> {
        let mut v: u64 = 0;
        for shift in (0..64).step_by(7) {
            let Some(&b) = self.bytes.get(self.pos) else {
                return Err(self.corrupt(format!("ends inside a number at byte {}", self.pos)));
            };
            self.pos += 1;
            if shift == 63 && b > 1 {
                return Err(self.corrupt("number beyond 64 bits"));
            }
            v |= ((b & 0x7f) as u64) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(self.corrupt("number longer than 10 bytes"))
    }

    fn finish(&self) -> Result<(), ContainerError> {
        if self.pos == self.bytes.len() { Ok(()) } else { Err(self.corrupt(format!("{} bytes left over", self.bytes.len() - self.pos))) }
    }
}

/// BIND (one band): per node in node order, its bind position as differences from the previous
/// node's (the first from zero), its influence count c (0..=4), c palette entries, and the first
/// c - 1 weights; the last weight is 65536 less the others.
pub fn write_binds(nodes: &[NodeSkin]) -> Vec<u8> {
    let mut out = Vec::with_capacity(nodes.len() * 8);
    let mut before = [0i64; 3];
    for n in nodes {
        for a in 0..3 {
            put64(&mut out, zigzag64(n.bind[a].wrapping_sub(before[a])));
        }
        before = n.bind;
        let c = n.weights.iter().take_while(|&&w| w > 0).count();
        put64(&mut out, c as u64);
        for &j in &n.joints[..c] {
            put64(&mut out, j as u64);
        }
        for &w in &n.weights[..c.saturating_sub(1)] {
            put64(&mut out, w as u64);
        }
    }
    out
}

/// Reads a BIND payload of `count` nodes over a palette of `palette` entries.
pub fn read_binds(bytes: &[u8], what: &str, count: u32, palette: u32) -> Result<Vec<NodeSkin>, ContainerError> {
    let mut c = Cursor { bytes, pos: 0, what };
    // Each node takes at least four bytes: checked before allocating.
    if (count as usize).saturating_mul(4) > bytes.len() {
        return Err(c.corrupt(format!("{count} nodes in {} bytes", bytes.len())));
    }
    let mut out = Vec::with_capacity(count as usize);
    let mut before = [0i64; 3];
    for v in 0..count {
        let mut n = NodeSkin::default();
        for a in 0..3 {
            let d = unzigzag64(c.get()?);
            n.bind[a] = before[a].wrapping_add(d);
            if n.bind[a].unsigned_abs() > MAX_BIND as u64 {
                return Err(c.corrupt(format!("node {v}: bind coordinate {} beyond the limit of {MAX_BIND}", n.bind[a])));
            }
        }
        before = n.bind;
        let k = c.get()?;
        if k > 4 {
            return Err(c.corrupt(format!("node {v}: {k} influences, more than 4")));
        }
        let k = k as usize;
        for slot in 0..k {
            let j = c.get()?;
            if j >= palette as u64 {
                return Err(c.corrupt(format!("node {v} influence {slot}: joint {j} beyond the palette of {palette}")));
            }
            n.joints[slot] = j as u32;
        }
        let mut left = WEIGHT_ONE;
        for slot in 0..k {
            let w = if slot + 1 == k { left } else { c.get()?.min(WEIGHT_ONE as u64 + 1) as i64 };
            if w <= 0 || w > left {
                return Err(c.corrupt(format!("node {v}: weights do not sum to {WEIGHT_ONE} with every one positive")));
            }
            n.weights[slot] = w;
            left -= w;
        }
        out.push(n);
    }
    c.finish()?;
    Ok(out)
}

/// What a palette value is predicted from: nothing on keyframes; the previous frame's value on
/// the frame after a keyframe; later, the previous two frames' values extrapolated linearly.
#[derive(Clone, Copy, Debug)]
pub enum PosePrediction<'a> {
    Key,
    Previous(&'a [i64]),
    Linear(&'a [i64], &'a [i64]),
}

impl PosePrediction<'_> {
    #[inline]
    pub(crate) fn at(self, i: usize) -> i64 {
        let get = |p: &[i64]| p.get(i).copied().unwrap_or(0);
        match self {
            PosePrediction::Key => 0,
            PosePrediction::Previous(p) => get(p),
            PosePrediction::Linear(p, q) => get(p).wrapping_mul(2).wrapping_sub(get(q)),
        }
    }
}

/// POSE (one frame): the bands predicted by skinning (bit j for band j), then the palette's
/// values, entry by entry, row by row (three linear values, then the translation), each as its
/// difference from its prediction.
/// Today's encoder writes Palette chunks; this writer of the older coding stays for tests of
/// the reader of files that have Pose chunks.
#[cfg(test)]
pub fn write_pose(mask: u64, palette: &[i64], prediction: PosePrediction) -> Vec<u8> {
    let mut out = Vec::with_capacity(palette.len() * 2 + 2);
    put64(&mut out, mask);
    for (i, &v) in palette.iter().enumerate() {
        put64(&mut out, zigzag64(v.wrapping_sub(prediction.at(i))));
    }
    out
}

/// Reads a POSE payload for a palette of `entries` and a file of `levels` bands into `palette`;
/// returns the band mask. `palette` is left unchanged on error.
pub fn read_pose(
    bytes: &[u8],
    what: &str,
    (entries, levels): (u32, usize),
    prediction: PosePrediction,
    palette: &mut Vec<i64>,
) -> Result<u64, ContainerError> {
    let mut c = Cursor { bytes, pos: 0, what };
    let mask = c.get()?;
    if levels < 64 && mask >> levels != 0 {
        return Err(c.corrupt(format!("band mask {mask:#x} names bands beyond the file's {levels}")));
    }
    let n = entries as usize * ENTRY;
    if n > bytes.len() {
        return Err(c.corrupt(format!("{entries} palette entries in {} bytes", bytes.len())));
    }
    let mut next = Vec::with_capacity(n);
    for i in 0..n {
        let name = if i % 4 == 3 { "translation" } else { "linear value" };
        let v = prediction.at(i).wrapping_add(unzigzag64(c.get()?));
        if v.unsigned_abs() > MAX_MATRIX as u64 {
            return Err(c.corrupt(format!("palette entry {} {name} {v} beyond the limit of {MAX_MATRIX}", i / ENTRY)));
        }
        next.push(v);
    }
    c.finish()?;
    *palette = next;
    Ok(mask)
}

impl<'a> PosePrediction<'a> {
    /// The previous frame's palette, unless this is a keyframe.
    pub(crate) fn previous(self) -> Option<&'a [i64]> {
        match self {
            PosePrediction::Key => None,
            PosePrediction::Previous(p) | PosePrediction::Linear(p, _) => Some(p),
        }
    }
}

/// Whether entry `e` of `palette` has the same twelve values in `previous`.
fn unchanged(palette: &[i64], previous: &[i64], e: usize) -> bool {
    let r = e * ENTRY..(e + 1) * ENTRY;
    matches!((palette.get(r.clone()), previous.get(r)), (Some(a), Some(b)) if a == b)
}

/// PALETTE (one frame, one band): the band mask (bit j: band j is predicted by skinning), then
/// the values of the band's `entries` (proto/container.md, "Palette"). On keyframes each
/// entry's twelve values as they are; on other frames a bit per entry, least significant bit
/// first, set when the entry changed since the previous frame (joints that hold still, and
/// rigid parts that never move, cost a bit a frame), then each changed entry's twelve values
/// as differences from their prediction.
pub fn write_palette(mask: u64, entries: &[u32], palette: &[i64], prediction: PosePrediction) -> Vec<u8> {
    let mut out = Vec::with_capacity(entries.len() * ENTRY + entries.len() / 8 + 2);
    put64(&mut out, mask);
    let moved: Vec<bool> = match prediction.previous() {
        None => vec![true; entries.len()],
        Some(p) => entries.iter().map(|&e| !unchanged(palette, p, e as usize)).collect(),
    };
    if prediction.previous().is_some() {
        for bits in moved.chunks(8) {
            out.push(bits.iter().enumerate().fold(0u8, |b, (i, &m)| b | (m as u8) << i));
        }
    }
    for (&e, _) in entries.iter().zip(&moved).filter(|p| *p.1) {
        for i in e as usize * ENTRY..(e as usize + 1) * ENTRY {
            let v = palette.get(i).copied().unwrap_or(0);
            put64(&mut out, zigzag64(v.wrapping_sub(prediction.at(i))));
        }
    }
    out
}

/// Reads a PALETTE payload carrying `entries` (ascending, each below `palette.len() / 12`) for
/// a file of `levels` bands into `palette`; returns the band mask. Entries it does not carry
/// are left as they are.
pub fn read_palette(
    bytes: &[u8],
    what: &str,
    entries: &[u32],
    levels: usize,
    prediction: PosePrediction,
    palette: &mut [i64],
) -> Result<u64, ContainerError> {
    let mut c = Cursor { bytes, pos: 0, what };
    let mask = c.get()?;
    if levels < 64 && mask >> levels != 0 {
        return Err(c.corrupt(format!("band mask {mask:#x} names bands beyond the file's {levels}")));
    }
    let previous = prediction.previous();
    let mut moved = vec![true; entries.len()];
    if previous.is_some() {
        let n = entries.len().div_ceil(8);
        let Some(bits) = bytes.get(c.pos..c.pos + n) else {
            return Err(c.corrupt(format!("ends inside the bits of its {} entries", entries.len())));
        };
        for (k, m) in moved.iter_mut().enumerate() {
            *m = bits[k / 8] >> (k % 8) & 1 == 1;
        }
        if !entries.len().is_multiple_of(8) && bits[n - 1] >> (entries.len() % 8) != 0 {
            return Err(c.corrupt(format!("bits set beyond its {} entries", entries.len())));
        }
        c.pos += n;
    }
    // Each value takes at least a byte: checked before reading on.
    if moved.iter().filter(|&&m| m).count() * ENTRY > bytes.len() - c.pos {
        return Err(c.corrupt(format!("{} entries' values in {} bytes", moved.iter().filter(|&&m| m).count(), bytes.len() - c.pos)));
    }
    for (&e, &m) in entries.iter().zip(&moved) {
        for i in e as usize * ENTRY..(e as usize + 1) * ENTRY {
            let v = match previous {
                Some(p) if !m => p.get(i).copied().unwrap_or(0),
                _ => prediction.at(i).wrapping_add(unzigzag64(c.get()?)),
            };
            if v.unsigned_abs() > MAX_MATRIX as u64 {
                let name = if i % 4 == 3 { "translation" } else { "linear value" };
                return Err(c.corrupt(format!("palette entry {e} {name} {v} beyond the limit of {MAX_MATRIX}")));
            }
            let Some(slot) = palette.get_mut(i) else {
                return Err(c.corrupt(format!("palette entry {e} beyond the palette of {}", palette.len() / ENTRY)));
            };
            *slot = v;
        }
    }
    c.finish()?;
    Ok(mask)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binds_and_poses_round_trip_and_damage_is_named() {
        let nodes = vec![
            NodeSkin { bind: [5, -7, 1 << 20], joints: [2, 0, 0, 0], weights: [WEIGHT_ONE, 0, 0, 0] },
            NodeSkin { bind: [-3, 0, 9], joints: [1, 3, 0, 0], weights: [40000, WEIGHT_ONE - 40000, 0, 0] },
            NodeSkin::default(),
        ];
        let bytes = write_binds(&nodes);
        assert_eq!(read_binds(&bytes, "b", 3, 4).expect("binds"), nodes);
        let e = read_binds(&bytes, "band 2 bind", 3, 3).expect_err("joint 3").to_string();
        assert!(e.contains("band 2 bind") && e.contains("joint 3 beyond the palette of 3"), "{e}");
        let palette: Vec<i64> = (0..24).map(|i| i * 1000 - 7).collect();
        let moved: Vec<i64> = palette.iter().map(|v| v + 3).collect();
        let again: Vec<i64> = moved.iter().map(|v| v + 5).collect();
        let mut got = Vec::new();
        let key = PosePrediction::Key;
        assert_eq!(read_pose(&write_pose(0b101, &palette, key), "p", (2, 3), key, &mut got).expect("pose"), 0b101);
        assert_eq!(got, palette);
        let one = PosePrediction::Previous(&palette);
        assert_eq!(read_pose(&write_pose(1, &moved, one), "p", (2, 3), one, &mut got).expect("pose"), 1);
        assert_eq!(got, moved);
        let two = PosePrediction::Linear(&moved, &palette);
        let bytes = write_pose(1, &again, two);
        // Linear extrapolation leaves 2 where the previous frame leaves 5.
        assert!(bytes[1..].iter().all(|&b| b == 4), "{bytes:?}");
        assert_eq!(read_pose(&bytes, "p", (2, 3), two, &mut got).expect("pose"), 1);
        assert_eq!(got, again);
        let e = read_pose(&write_pose(0b1000, &palette, key), "frame 4 pose", (2, 3), key, &mut got).expect_err("mask").to_string();
        assert!(e.contains("frame 4 pose") && e.contains("beyond the file's 3"), "{e}");
        assert_eq!(got, again, "unchanged on error");
    }

    #[test]
    fn palettes_carry_their_entries_and_send_moved_ones_only() {
        // Ten entries; a band carries entries 1, 4 and 9 of them.
        let entries = [1u32, 4, 9];
        let key: Vec<i64> = (0..10 * ENTRY as i64).map(|i| i * 37 - 500).collect();
        let bytes = write_palette(0b11, &entries, &key, PosePrediction::Key);
        let mut got = vec![0i64; key.len()];
        assert_eq!(read_palette(&bytes, "p", &entries, 2, PosePrediction::Key, &mut got).expect("key"), 0b11);
        for e in 0..10 {
            let r = e * ENTRY..(e + 1) * ENTRY;
            let expected: &[i64] = if entries.contains(&(e as u32)) { &key[r.clone()] } else { &[0; ENTRY] };
            assert_eq!(&got[r], expected, "entry {e}");
        }
        // Entry 4 moves by 3 in every value; 1 and 9 hold still: one byte of bits, 12 values.
        let mut next = key.clone();
        next[4 * ENTRY..5 * ENTRY].iter_mut().for_each(|v| *v += 3);
        let one = PosePrediction::Previous(&key);
        let bytes = write_palette(1, &entries, &next, one);
        assert_eq!(bytes.len(), 1 + 1 + ENTRY, "{bytes:?}");
        assert_eq!(bytes[1], 0b010);
        let mut out = vec![0i64; key.len()];
        assert_eq!(read_palette(&bytes, "p", &entries, 2, one, &mut out).expect("inter"), 1);
        for &e in &entries {
            let r = e as usize * ENTRY..(e as usize + 1) * ENTRY;
            assert_eq!(out[r.clone()], next[r], "entry {e}");
        }
        // Damage: bits beyond the entries, too few values, a mask naming a band not there.
        let mut bad = bytes.clone();
        bad[1] |= 0x10;
        let e = read_palette(&bad, "frame 5 band 1 palette", &entries, 2, one, &mut out).expect_err("bits").to_string();
        assert!(e.contains("frame 5 band 1 palette") && e.contains("bits set beyond its 3 entries"), "{e}");
        let e = read_palette(&bytes[..6], "p", &entries, 2, one, &mut out).expect_err("short").to_string();
        assert!(e.contains("1 entries' values in 4 bytes"), "{e}");
        let keyed = write_palette(0b11, &entries, &key, PosePrediction::Key);
        let e = read_palette(&keyed, "p", &entries, 1, PosePrediction::Key, &mut out).expect_err("mask").to_string();
        assert!(e.contains("band mask 0x3 names bands beyond the file's 1"), "{e}");
    }
}
