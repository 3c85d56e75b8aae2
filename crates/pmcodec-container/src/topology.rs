//! Bit-coded topology chunks (proto/container.md, "Faces" and "Corners", coding 1): the same
//! faces and corner updates as the varint codings of `payload`, in adaptive Exp-Golomb codes,
//! and corner updates grouped by the transition that caused them.
//!
//! Why: a corner update is the trace, at level j, of a swap below j (Kircher & Garland,
//! "Progressive multiresolution meshes for deforming surfaces", 2005, section 4.1): an input
//! vertex v moving from cluster A to cluster B changes the level-j corner of every triangle
//! around v from A's level-j ancestor X to B's, Y. The varint coding spends a triangle id, a
//! mask and a difference, about 3 bytes, on each of those triangles (about six on a regular
//! mesh); here a *transition* names X (a gap from the previous one), Y (an index among X's
//! neighbours in the level-j mesh the reader holds) and which of the triangles around X it
//! carries (a bit each), about as much as one of them cost before. Numbers are Exp-Golomb
//! codes whose order follows the running mean of what was coded (as LOCO-I / JPEG-LS adapts
//! its Golomb parameter, Weinberger, Seroussi & Sapiro, 2000): per-frame chunks of a few dozen
//! numbers are too short for a table of their own, and varints spend a byte where a few bits do.

use crate::ContainerError;
// A context: the running sum an Exp-Golomb order is chosen from (at most 32, every number
// being below 2^32).
use crate::bits::{BitReader, Bits, Running as Context};
use crate::payload::{unzigzag, zigzag};

/// The varint a coded payload starts with after its leading 0 (a varint payload that starts
/// with a count of 0 ends there, so a 0 followed by more bytes is never a varint payload).
pub const CODING_BITS: u32 = 1;

/// Writes numbers of a [`Context`] into the shared bit stream ([`crate::bits`]).
struct BitWriter {
    bits: Bits,
}

impl BitWriter {
    fn new(bytes: Vec<u8>) -> Self {
        BitWriter { bits: Bits::after(bytes) }
    }

    fn bit(&mut self, b: bool) {
        self.bits.put(b as u64, 1);
    }

    /// `u` as an Exp-Golomb code of the context's order, then the context learns it.
    fn number(&mut self, ctx: &mut Context, u: u32) {
        self.bits.golomb(u as u64, ctx.order(32));
        ctx.update(u);
    }

    fn into_bytes(self) -> Vec<u8> {
        self.bits.out
    }
}

/// Reads the numbers [`BitWriter`] writes; errors name the chunk.
trait Numbers {
    fn flag(&mut self) -> Result<bool, ContainerError>;
    fn number(&mut self, ctx: &mut Context) -> Result<u32, ContainerError>;
}

impl Numbers for BitReader<'_> {
    fn flag(&mut self) -> Result<bool, ContainerError> {
        Ok(self.bit()? == 1)
    }

    /// An Exp-Golomb code of the context's order (at most 32 bits after its leading zeros, and
    /// a value below 2^32), then the context learns it.
    fn number(&mut self, ctx: &mut Context) -> Result<u32, ContainerError> {
        let v = self.golomb_within(ctx.order(32), 32)?;
        let u = u32::try_from(v).map_err(|_| self.corrupt("number beyond 32 bits"))?;
        ctx.update(u);
        Ok(u)
    }
}

/// Band j's Corners payload, against the corners a level-j reader holds, in its shorter coding.
pub(crate) fn corners_chunk(h: &pmcodec_hierarchy::Hierarchy, j: usize, updates: &[(u32, [u32; 3])], held: &[[u32; 3]]) -> Vec<u8> {
    crate::payload::write_corner_updates_best(updates, held, h.level_sizes[j])
}

/// The payload header of a coded chunk: a 0, then the coding.
fn coded_start() -> BitWriter {
    let mut out = Vec::new();
    crate::payload::put(&mut out, 0);
    crate::payload::put(&mut out, CODING_BITS);
    BitWriter::new(out)
}

/// Whether `bytes` is a coded payload (a leading 0 followed by more bytes), and then where
/// its bit stream starts; a coding other than [`CODING_BITS`] is corrupt.
pub fn coded(bytes: &[u8], what: &str) -> Result<Option<usize>, ContainerError> {
    if bytes.len() < 2 || bytes[0] != 0 {
        return Ok(None);
    }
    // The coding is a one-byte varint: any other byte (another coding, or a longer varint) is
    // corrupt.
    if u32::from(bytes[1]) != CODING_BITS {
        return Err(ContainerError::Corrupt {
            what: what.to_string(),
            detail: format!("topology coding byte {} (1: bit-coded)", bytes[1]),
        });
    }
    Ok(Some(2))
}

/// How many recently used nodes a coded Faces chunk keeps to refer back to.
const RECENT: usize = 16;

/// The nodes a Faces chunk used last, most recent first (at most [`RECENT`], distinct).
fn touch(recent: &mut Vec<u32>, c: u32) {
    if let Some(p) = recent.iter().position(|&x| x == c) {
        recent.remove(p);
    }
    recent.insert(0, c);
    recent.truncate(RECENT);
}

/// FACES, coding 1: the count, then per face the triangle's gap from the face before (as an
/// ascending list) and its three corners, each either one of the [`RECENT`] nodes used last
/// (its place in that list, most recent first, plus one) or 0 and its zigzag difference from
/// the same corner of the face before. Faces in input order walk across the surface, so most
/// corners are nodes a face just before used (a regular mesh has about two faces per node).
pub fn write_faces(faces: &[(u32, [u32; 3])]) -> Vec<u8> {
    let mut w = coded_start();
    let (mut count, mut gap, mut hit, mut corner) = (Context::new(), Context::new(), Context::new(), [Context::new(); 3]);
    w.number(&mut count, faces.len() as u32);
    let (mut prev, mut last, mut recent) = (None::<u32>, [0u32; 3], Vec::with_capacity(RECENT));
    for &(t, c) in faces {
        w.number(&mut gap, prev.map_or(t, |p| t - p - 1));
        prev = Some(t);
        for i in 0..3 {
            match recent.iter().position(|&x| x == c[i]) {
                Some(p) => w.number(&mut hit, p as u32 + 1),
                None => {
                    w.number(&mut hit, 0);
                    w.number(&mut corner[i], zigzag(c[i].wrapping_sub(last[i]) as i32));
                }
            }
            touch(&mut recent, c[i]);
        }
        last = c;
    }
    w.into_bytes()
}

/// Reads [`write_faces`]'s bit stream from `start`: faces ascending, corners below `size`.
pub fn read_faces(bytes: &[u8], start: usize, what: &str, size: u32, triangles: u32) -> Result<Vec<(u32, [u32; 3])>, ContainerError> {
    let mut r = BitReader { bytes: &bytes[start..], bit: 0, what };
    let (mut count, mut gap, mut hit, mut corner) = (Context::new(), Context::new(), Context::new(), [Context::new(); 3]);
    let m = r.number(&mut count)?;
    // Each face takes at least 4 bits: refuse a count the stream cannot hold before sizing.
    if m > triangles || m as usize > (bytes.len() - start) * 2 {
        return Err(r.corrupt(format!("{m} faces in {} bytes for {triangles} triangles", bytes.len() - start)));
    }
    let mut faces = Vec::with_capacity(m as usize);
    let (mut prev, mut last, mut recent) = (None::<u32>, [0u32; 3], Vec::with_capacity(RECENT));
    for _ in 0..m {
        let d = r.number(&mut gap)? as u64;
        let t = prev.map_or(d, |p| p as u64 + d + 1);
        if t >= triangles as u64 {
            return Err(r.corrupt(format!("triangle {t} out of range (< {triangles})")));
        }
        prev = Some(t as u32);
        let mut c = [0u32; 3];
        for i in 0..3 {
            c[i] = match r.number(&mut hit)? {
                0 => last[i].wrapping_add(unzigzag(r.number(&mut corner[i])?) as u32),
                u => *recent.get(u as usize - 1).ok_or_else(|| r.corrupt(format!("recent node {u} of {}", recent.len())))?,
            };
            if c[i] >= size {
                return Err(r.corrupt(format!("corner {} out of range (< {size})", c[i])));
            }
            touch(&mut recent, c[i]);
        }
        last = c;
        faces.push((t as u32, c));
    }
    r.finish()?;
    Ok(faces)
}

/// KEY, coding 1: the count, then each parent either one of the [`RECENT`] parents used last
/// (its place, most recent first, plus one) or 0 and its zigzag difference from the node
/// before's (from 0 for the first). Nodes near in id order often share their cluster or lie
/// next to recent ones, whatever order the ids follow (a subdivided mesh numbers its edge
/// vertices after the old ones).
pub fn write_key(parent: &[u32]) -> Vec<u8> {
    let mut w = coded_start();
    let (mut count, mut hit, mut diff) = (Context::new(), Context::new(), Context::new());
    w.number(&mut count, parent.len() as u32);
    let (mut last, mut recent) = (0u32, Vec::with_capacity(RECENT));
    for &p in parent {
        match recent.iter().position(|&x| x == p) {
            Some(i) => w.number(&mut hit, i as u32 + 1),
            None => {
                w.number(&mut hit, 0);
                w.number(&mut diff, zigzag(p.wrapping_sub(last) as i32));
            }
        }
        touch(&mut recent, p);
        last = p;
    }
    w.into_bytes()
}

/// Reads [`write_key`]'s bit stream from `start`: exactly `expected` parents below `limit`.
pub fn read_key(bytes: &[u8], start: usize, what: &str, expected: u32, limit: u32) -> Result<Vec<u32>, ContainerError> {
    let mut r = BitReader { bytes: &bytes[start..], bit: 0, what };
    let (mut count, mut hit, mut diff) = (Context::new(), Context::new(), Context::new());
    let n = r.number(&mut count)?;
    // Each parent takes at least a bit.
    if n != expected || n as usize > (bytes.len() - start) * 8 {
        return Err(r.corrupt(format!("{n} parents for {expected} nodes in {} bytes", bytes.len() - start)));
    }
    let mut parent = Vec::with_capacity(n as usize);
    let (mut last, mut recent) = (0u32, Vec::with_capacity(RECENT));
    for _ in 0..n {
        let p = match r.number(&mut hit)? {
            0 => last.wrapping_add(unzigzag(r.number(&mut diff)?) as u32),
            u => *recent.get(u as usize - 1).ok_or_else(|| r.corrupt(format!("recent parent {u} of {}", recent.len())))?,
        };
        if p >= limit {
            return Err(r.corrupt(format!("parent {p} out of range (< {limit})")));
        }
        touch(&mut recent, p);
        parent.push(p);
        last = p;
    }
    r.finish()?;
    Ok(parent)
}

/// DELTA, coding 1: the count, then per move the node's gap from the move before (as an
/// ascending list) and its new parent as the zigzag difference from the move before's (from 0
/// for the first): nodes near in id order lie near each other, and so do their clusters.
pub fn write_delta(moves: &[(u32, u32)]) -> Vec<u8> {
    let mut w = coded_start();
    let (mut count, mut gap, mut diff) = (Context::new(), Context::new(), Context::new());
    w.number(&mut count, moves.len() as u32);
    let (mut prev, mut last) = (None::<u32>, 0u32);
    for &(v, to) in moves {
        w.number(&mut gap, prev.map_or(v, |p| v - p - 1));
        prev = Some(v);
        w.number(&mut diff, zigzag(to.wrapping_sub(last) as i32));
        last = to;
    }
    w.into_bytes()
}

/// Reads [`write_delta`]'s bit stream from `start`: at most `nodes` moves, nodes ascending
/// below `nodes`, parents below `parents`.
pub fn read_delta(bytes: &[u8], start: usize, what: &str, nodes: u32, parents: u32) -> Result<Vec<(u32, u32)>, ContainerError> {
    let mut r = BitReader { bytes: &bytes[start..], bit: 0, what };
    let (mut count, mut gap, mut diff) = (Context::new(), Context::new(), Context::new());
    let n = r.number(&mut count)?;
    // Each move takes at least 2 bits.
    if n > nodes || n as usize > (bytes.len() - start) * 4 {
        return Err(r.corrupt(format!("{n} moves in {} bytes for {nodes} nodes", bytes.len() - start)));
    }
    let mut moves = Vec::with_capacity(n as usize);
    let (mut prev, mut last) = (None::<u64>, 0u32);
    for _ in 0..n {
        let d = r.number(&mut gap)? as u64;
        let v = prev.map_or(d, |p| p + d + 1);
        if v >= nodes as u64 {
            return Err(r.corrupt(format!("node {v} out of range (< {nodes})")));
        }
        prev = Some(v);
        let to = last.wrapping_add(unzigzag(r.number(&mut diff)?) as u32);
        if to >= parents {
            return Err(r.corrupt(format!("parent {to} out of range (< {parents})")));
        }
        last = to;
        moves.push((v as u32, to));
    }
    r.finish()?;
    Ok(moves)
}

/// The level-j mesh the reader holds: for each node, the triangles alive at j with a corner
/// there (ascending), in compressed rows; a node's neighbours (the other corners of those
/// triangles, ascending, distinct) are gathered only for the nodes a chunk names, since a
/// frame's transitions touch a few nodes of the level and rows for all of them cost the
/// encoder a seventh of its time.
struct Held<'a> {
    before: &'a [[u32; 3]],
    tri_start: Vec<u32>,
    tris: Vec<u32>,
}

fn alive(c: &[u32; 3]) -> bool {
    c[0] != c[1] && c[1] != c[2] && c[0] != c[2]
}

impl<'a> Held<'a> {
    /// Rows for every node, or (`wanted`) only for the nodes marked: the writer knows which
    /// nodes its transitions leave, a reader does not.
    fn new(before: &'a [[u32; 3]], size: u32, wanted: Option<&[bool]>) -> Self {
        let n = size as usize;
        let usable = |c: &[u32; 3]| alive(c) && c.iter().all(|&x| x < size);
        let kept = |x: u32| wanted.is_none_or(|w| w[x as usize]);
        let mut tri_start = vec![0u32; n + 1];
        for c in before.iter().filter(|c| usable(c)) {
            for &x in c.iter().filter(|&&x| kept(x)) {
                tri_start[x as usize + 1] += 1;
            }
        }
        for i in 0..n {
            tri_start[i + 1] += tri_start[i];
        }
        let mut fill = tri_start.clone();
        let mut tris = vec![0u32; tri_start[n] as usize];
        for (t, c) in before.iter().enumerate().filter(|(_, c)| usable(c)) {
            for &x in c.iter().filter(|&&x| kept(x)) {
                tris[fill[x as usize] as usize] = t as u32;
                fill[x as usize] += 1;
            }
        }
        Held { before, tri_start, tris }
    }

    fn triangles(&self, x: u32) -> &[u32] {
        &self.tris[self.tri_start[x as usize] as usize..self.tri_start[x as usize + 1] as usize]
    }

    /// Node `x`'s neighbours, ascending and distinct, into `row`.
    fn neighbours<'r>(&self, x: u32, row: &'r mut Vec<u32>) -> &'r [u32] {
        row.clear();
        for &t in self.triangles(x) {
            row.extend(self.before[t as usize].iter().copied().filter(|&y| y != x));
        }
        row.sort_unstable();
        row.dedup();
        row
    }
}

/// CORNERS, coding 1. The updates of triangles alive at j before the frame (as the reader
/// holds them, `before`) go as *transitions* `(X, Y, which)`: corner X of the triangles
/// `which` (a bit for each triangle alive at j with corner X, ascending) becomes Y; the other
/// updates (triangles not alive before) as a list of their own, ascending, each corner a zigzag
/// difference from the same corner of the one before (from 0 for the first): a reader holds a
/// triangle that is not alive as it last heard of it or not at all (`NONE`), so its held
/// corners are no reference.
/// `updates` is ascending by triangle, as `payload::write_corner_updates` takes it.
pub fn write_corner_updates(updates: &[(u32, [u32; 3])], before: &[[u32; 3]], size: u32) -> Vec<u8> {
    // (X, Y) -> triangles, in (X, Y) order.
    let mut transitions: std::collections::BTreeMap<(u32, u32), Vec<u32>> = std::collections::BTreeMap::new();
    let mut others = Vec::new();
    for &(t, c) in updates {
        match before.get(t as usize) {
            Some(b) if alive(b) && b.iter().all(|&x| x < size) => {
                for i in (0..3).filter(|&i| c[i] != b[i]) {
                    transitions.entry((b[i], c[i])).or_default().push(t);
                }
            }
            _ => others.push((t, c)),
        }
    }
    let mut wanted = vec![false; size as usize];
    for &(x, _) in transitions.keys() {
        wanted[x as usize] = true;
    }
    let held = Held::new(before, size, Some(&wanted));
    let mut row = Vec::new();
    let mut w = coded_start();
    let (mut count, mut gap, mut to, mut diff) = (Context::new(), Context::new(), Context::new(), Context::new());
    w.number(&mut count, transitions.len() as u32);
    let mut last_x = 0u32;
    for (&(x, y), tris) in &transitions {
        w.number(&mut gap, x - last_x);
        last_x = x;
        let nb = held.neighbours(x, &mut row);
        match nb.binary_search(&y) {
            Ok(i) => w.number(&mut to, i as u32),
            Err(_) => w.number(&mut to, (nb.len() as u32).wrapping_add(zigzag(y.wrapping_sub(x) as i32))),
        }
        for t in held.triangles(x) {
            w.bit(tris.binary_search(t).is_ok());
        }
    }
    w.number(&mut count, others.len() as u32);
    let (mut prev, mut last) = (None::<u32>, [0u32; 3]);
    for &(t, c) in &others {
        w.number(&mut gap, prev.map_or(t, |p| t - p - 1));
        prev = Some(t);
        for i in 0..3 {
            w.number(&mut diff, zigzag(c[i].wrapping_sub(last[i]) as i32));
        }
        last = c;
    }
    w.into_bytes()
}

/// Reads [`write_corner_updates`]'s bit stream from `start` against the corners the reader
/// holds: the updated triangles, ascending, with their new corners (below `size`).
pub fn read_corner_updates(
    bytes: &[u8],
    start: usize,
    what: &str,
    size: u32,
    before: &[[u32; 3]],
) -> Result<Vec<(u32, [u32; 3])>, ContainerError> {
    let mut r = BitReader { bytes: &bytes[start..], bit: 0, what };
    let triangles = before.len() as u64;
    let stream_bits = ((bytes.len() - start) * 8) as u64;
    let (mut count, mut gap, mut to, mut diff) = (Context::new(), Context::new(), Context::new(), Context::new());
    let n = r.number(&mut count)? as u64;
    // A transition takes at least 3 bits, a triangle of the second list 4.
    if n * 3 > stream_bits {
        return Err(r.corrupt(format!("{n} transitions in {} bytes", bytes.len() - start)));
    }
    let held = Held::new(before, size, None);
    let mut row = Vec::new();
    let mut new: std::collections::BTreeMap<u32, [u32; 3]> = std::collections::BTreeMap::new();
    let mut last_x = 0u64;
    for _ in 0..n {
        let x = last_x + r.number(&mut gap)? as u64;
        if x >= size as u64 {
            return Err(r.corrupt(format!("transition from node {x} out of range (< {size})")));
        }
        last_x = x;
        let x = x as u32;
        let nb = held.neighbours(x, &mut row);
        let u = r.number(&mut to)?;
        let y = match nb.get(u as usize) {
            Some(&y) => y,
            None => x.wrapping_add(unzigzag(u - nb.len() as u32) as u32),
        };
        if y >= size || y == x {
            return Err(r.corrupt(format!("transition from node {x} to {y} (< {size}, another node)")));
        }
        let mut any = false;
        for &t in held.triangles(x) {
            if !r.flag()? {
                continue;
            }
            any = true;
            let b = before[t as usize];
            let c = new.entry(t).or_insert(b);
            let i = (0..3).find(|&i| b[i] == x).unwrap_or(0);
            if c[i] != b[i] {
                return Err(r.corrupt(format!("triangle {t}: corner {i} changed twice")));
            }
            c[i] = y;
        }
        if !any {
            return Err(r.corrupt(format!("transition from node {x} to {y} carries no triangle")));
        }
    }
    let m = r.number(&mut count)? as u64;
    if m > triangles || m * 4 > stream_bits {
        return Err(r.corrupt(format!("{m} updates of triangles not alive in {} bytes", bytes.len() - start)));
    }
    let (mut prev, mut last) = (None::<u64>, [0u32; 3]);
    for _ in 0..m {
        let d = r.number(&mut gap)? as u64;
        let t = prev.map_or(d, |p| p + d + 1);
        if t >= triangles {
            return Err(r.corrupt(format!("triangle {t} out of range (< {triangles})")));
        }
        prev = Some(t);
        let b = before[t as usize];
        if alive(&b) && b.iter().all(|&x| x < size) {
            return Err(r.corrupt(format!("triangle {t} was alive: its update belongs to a transition")));
        }
        let mut c = [0u32; 3];
        for i in 0..3 {
            c[i] = last[i].wrapping_add(unzigzag(r.number(&mut diff)?) as u32);
            if c[i] >= size {
                return Err(r.corrupt(format!("corner {} out of range (< {size})", c[i])));
            }
        }
        last = c;
        new.insert(t as u32, c);
    }
    r.finish()?;
    Ok(new.into_iter().collect())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn numbers_round_trip_through_adaptive_orders() {
        let values = [0u32, 1, 5, 0, 0, 1000, 3, u32::MAX, 7, 0, 2, 1 << 31, 9];
        let mut w = BitWriter::new(Vec::new());
        let mut c = Context::new();
        for &v in &values {
            w.number(&mut c, v);
        }
        let bytes = w.into_bytes();
        let mut r = BitReader { bytes: &bytes, bit: 0, what: "t" };
        let mut c = Context::new();
        for &v in &values {
            assert_eq!(r.number(&mut c).unwrap(), v);
        }
        r.finish().unwrap();
    }

    #[test]
    fn faces_round_trip_and_refuse_damage() {
        let faces = vec![(0, [0, 1, 2]), (3, [1, 2, 3]), (4, [9, 1, 0]), (70, [2, 3, 4])];
        let bytes = write_faces(&faces);
        let start = coded(&bytes, "t").unwrap().unwrap();
        assert_eq!(read_faces(&bytes, start, "t", 10, 71).unwrap(), faces);
        assert!(read_faces(&bytes, start, "t", 9, 71).is_err(), "corner 9 out of range");
        assert!(read_faces(&bytes, start, "t", 10, 70).is_err(), "triangle 70 out of range");
        let mut long = bytes.clone();
        long.push(0);
        assert!(read_faces(&long, start, "t", 10, 71).is_err(), "byte after the stream");
        assert!(coded(&[0, 2, 0], "t").is_err(), "unknown coding");
        assert_eq!(coded(&[0], "t").unwrap(), None, "an empty varint payload");
    }

    #[test]
    fn keys_and_deltas_round_trip_and_refuse_damage() {
        let parent = vec![0, 0, 1, 1, 1, 3, 2, 2, 0];
        let bytes = write_key(&parent);
        let start = coded(&bytes, "t").unwrap().unwrap();
        assert_eq!(read_key(&bytes, start, "t", 9, 4).unwrap(), parent);
        assert!(read_key(&bytes, start, "t", 9, 3).is_err(), "parent 3 out of range");
        assert!(read_key(&bytes, start, "t", 8, 4).is_err(), "9 parents for 8 nodes");
        let moves = vec![(2, 5), (3, 4), (40, 0)];
        let bytes = write_delta(&moves);
        assert_eq!(read_delta(&bytes, start, "t", 41, 6).unwrap(), moves);
        assert!(read_delta(&bytes, start, "t", 40, 6).is_err(), "node 40 out of range");
        assert!(read_delta(&bytes, start, "t", 41, 5).is_err(), "parent 5 out of range");
        for cut in start..bytes.len() {
            assert!(read_delta(&bytes[..cut], start, "t", 41, 6).is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn corner_updates_round_trip_as_transitions() {
        // A strip of 6 triangles over nodes 0..8, one never told of, one degenerate.
        let before = vec![[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4], [4, 5, 6], [u32::MAX; 3], [6, 6, 7]];
        // Node 2's corner becomes 7 in two triangles (one of them dies), node 4 becomes 6 in
        // one, triangle 2 changes two corners, the unknown and the degenerate come to life.
        let updates = vec![(0, [0, 1, 7]), (2, [7, 3, 6]), (5, [1, 2, 3]), (6, [6, 5, 7])];
        let bytes = write_corner_updates(&updates, &before, 8);
        let start = coded(&bytes, "t").unwrap().unwrap();
        assert_eq!(read_corner_updates(&bytes, start, "t", 8, &before).unwrap(), updates);
        assert!(read_corner_updates(&bytes, start, "t", 7, &before).is_err(), "node 7 out of range");
        // Every truncation is refused, never a panic.
        for cut in start..bytes.len() {
            let _ = read_corner_updates(&bytes[..cut], start, "t", 8, &before);
        }
    }
}
