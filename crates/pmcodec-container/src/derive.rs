//! Derived topology (proto/container.md, "Faces", coding 2): a band whose keyframe Faces chunk
//! is the two bytes `0 2` sends neither faces nor corner updates up to the next keyframe; its
//! reader derives them from the input triangles and the parent maps below the band.
//!
//! Why: a band's faces and corner updates are functions of data the file already holds (Kircher
//! & Garland, "Progressive multiresolution meshes for deforming surfaces", 2005, section 4.1): a
//! triangle's level-j corners are its input corners walked up the parent maps of levels
//! 0..j-1, and a swap of node v from cluster A to cluster B at a level below j changes exactly
//! the level-j corners of the triangles under v (and so which of them are degenerate at j). A
//! level-j reader that reads the Triangles chunk and the Key and Delta chunks of the bands
//! below j computes both; the file then carries them once instead of once per band (waving
//! cloth of 2,916 vertices: Faces and Corners were 2.3 of its 3.4 bits per vertex per frame
//! beyond positions).

use crate::format::{ChunkEntry, ChunkKind};
use pmcodec_hierarchy::progressive::distinct;
use std::sync::Arc;

/// The payload of a derived Faces chunk: a 0, then coding 2 (a coded payload's leading 0 and
/// coding byte, as `topology::coded` reads them; no other Faces payload is two bytes long).
pub const DERIVED_FACES: [u8; 2] = [0, 2];

/// Whether a Faces payload says "derived".
pub fn is_derived(raw: &[u8]) -> bool {
    raw == DERIVED_FACES
}

/// Whether the index entry of a Faces chunk is a derived one: its payload is the only Faces
/// payload of two bytes, so a reader knows it before fetching it.
pub fn entry_is_derived(e: &ChunkEntry) -> bool {
    e.kind == ChunkKind::Faces && e.raw_len == DERIVED_FACES.len() as u32
}

/// Whether band `level`'s faces and corner updates are derived in the keyframe interval of
/// `frame`, from the index entries of a file (`chunks`, in file order) whose keyframes are
/// every `interval` frames (0: frame 0 only).
pub fn derives(chunks: &[ChunkEntry], interval: u32, frame: u32, level: usize) -> bool {
    if level == 0 {
        return false;
    }
    let key = if interval == 0 { 0 } else { frame - frame % interval };
    // Entries are in file order: frame 0's once-only chunks first, then frame after frame.
    let start = chunks.partition_point(|e| e.kind == ChunkKind::Triangles || e.frame < key);
    chunks[start..].iter().take_while(|e| e.frame == key).any(|e| e.band as usize == level && entry_is_derived(e))
}

/// Whether a client whose finest level is `level` reads chunk `e` of a file with entries
/// `chunks` and keyframe interval `interval`: [`ChunkKind::read_at`], and where band `level`
/// is derived ([`derives`]), the Triangles chunk and the Key and Delta chunks of the bands below
/// it, and frame 0's Key chunks below it where any interval derives it (proto/container.md,
/// "Who reads what", and "Key", coding 3).
pub fn reads(chunks: &[ChunkEntry], interval: u32, e: &ChunkEntry, level: usize) -> bool {
    if e.kind.read_at(e.band as usize, level) {
        return true;
    }
    match e.kind {
        ChunkKind::Triangles => level > 0 && chunks.iter().any(|x| x.band as usize == level && entry_is_derived(x)),
        // Frame 0's Key chunks below `level` too wherever band `level` is derived at all: a
        // later keyframe's Key chunk may code its changes from frame 0's (Key coding 3).
        ChunkKind::Key if e.frame == 0 && (e.band as usize) < level => {
            derives(chunks, interval, 0, level) || chunks.iter().any(|x| x.band as usize == level && entry_is_derived(x))
        }
        ChunkKind::Key | ChunkKind::Delta => (e.band as usize) < level && derives(chunks, interval, e.frame, level),
        _ => false,
    }
}

/// A frame's moves of some levels: (level, (node, new parent) ascending by node).
pub(crate) type LevelMoves = Vec<(usize, Vec<(u32, u32)>)>;

/// A level-L reader's view of the levels below L in a derived interval: the parent maps of
/// levels 0..L-1 and every triangle's level-L corners, kept as the encoder keeps them (the
/// corners of triangles that are not alive included), so that each frame's corner updates are
/// exactly those a Corners chunk would carry.
#[derive(Clone)]
pub(crate) struct Below {
    triangles: Arc<Vec<[u32; 3]>>,
    /// `parents[i]` is the parent map of level i, i < L.
    parents: Vec<Vec<u32>>,
    corners: Vec<[u32; 3]>,
}

impl Below {
    /// The state of a keyframe: `parents` are its Key chunks of bands 0..L-1 (read and checked
    /// by the caller: every parent below the next level's size, every triangle corner below
    /// the vertex count).
    pub(crate) fn new(triangles: Arc<Vec<[u32; 3]>>, parents: Vec<Vec<u32>>) -> Self {
        let mut b = Below { triangles, parents, corners: Vec::new() };
        b.corners = b.triangles.iter().map(|t| b.walk(*t)).collect();
        b
    }

    /// The input triangles it derives from (kept by the decoder for the next keyframe).
    pub(crate) fn triangles(&self) -> Arc<Vec<[u32; 3]>> {
        self.triangles.clone()
    }

    /// A triangle's level-L corners: its input corners walked up the parent maps.
    fn walk(&self, t: [u32; 3]) -> [u32; 3] {
        t.map(|mut v| {
            for p in &self.parents {
                v = p.get(v as usize).copied().unwrap_or(v);
            }
            v
        })
    }

    /// The keyframe's faces: every triangle alive at L with its level-L corners, ascending.
    pub(crate) fn faces(&self) -> Vec<(u32, [u32; 3])> {
        self.corners.iter().enumerate().filter(|(_, c)| distinct(**c)).map(|(t, c)| (t as u32, *c)).collect()
    }

    /// Applies a frame's moves of the levels below L (`(level, moves)`, moves as the Delta
    /// chunks give them, checked in range by the caller) and returns the corner updates at L:
    /// the triangles whose level-L corners changed and that were or became alive there,
    /// ascending (the encoder's rule, `pmcodec_hierarchy::progressive::Encoder`).
    pub(crate) fn apply(&mut self, moves: &[(usize, Vec<(u32, u32)>)]) -> Vec<(u32, [u32; 3])> {
        let mut any = false;
        for (j, band) in moves {
            if let Some(p) = self.parents.get_mut(*j) {
                for &(v, to) in band {
                    if let Some(x) = p.get_mut(v as usize) {
                        any |= *x != to;
                        *x = to;
                    }
                }
            }
        }
        let mut updates = Vec::new();
        if !any {
            return updates;
        }
        for t in 0..self.corners.len() {
            let now = self.walk(self.triangles[t]);
            let before = self.corners[t];
            if now != before && (distinct(now) || distinct(before)) {
                updates.push((t as u32, now));
            }
            self.corners[t] = now;
        }
        updates
    }
}

/// Which bands of which keyframe intervals the encoder derives (see [`crate::EncodeOptions`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DerivedTopology {
    /// Every band's faces and corner updates sent (files before the derived coding).
    Never,
    /// Every band derived: the smallest file (a level-L reader reads the Key and Delta chunks
    /// of the bands below L and the Triangles chunk instead of its Faces and Corners).
    #[default]
    Always,
    /// A band derived in a keyframe interval where what its reader reads instead (the Key and
    /// Delta chunks below it) takes no more bytes than its Faces and Corners chunks.
    WhenCheaper,
}

/// Index entry bytes a chunk costs beside its own (tag, length, CRC; about 7).
const ENTRY: u64 = 7;

/// Rewrites the chunks of each keyframe interval and band `j >= 1` that `policy` derives: the
/// Faces chunk becomes [`DERIVED_FACES`] and the interval's Corners chunks are
/// left out (files with the sparse flag) or emptied. `chunks` are in file order; `stored`
/// compresses a payload as the encoder stores it.
pub(crate) fn choose(
    chunks: &mut Vec<(ChunkEntry, Vec<u8>)>,
    policy: DerivedTopology,
    keyframe_before: impl Fn(u32) -> u32,
    sparse: bool,
    stored: impl Fn(&[u8]) -> Result<Vec<u8>, crate::ContainerError>,
) -> Result<(), crate::ContainerError> {
    if policy == DerivedTopology::Never {
        return Ok(());
    }
    // Per (keyframe, band): bytes of the Faces and Corners chunks, and of the Key and Delta
    // chunks of that band (a band-j reader that derives reads those of the bands below j).
    use std::collections::BTreeMap;
    let mut sent: BTreeMap<(u32, u32), u64> = BTreeMap::new();
    let mut below: BTreeMap<(u32, u32), u64> = BTreeMap::new();
    let mut bands = 0u32;
    for (e, bytes) in chunks.iter() {
        let k = keyframe_before(e.frame);
        let cost = bytes.len() as u64 + ENTRY;
        match e.kind {
            ChunkKind::Faces | ChunkKind::Corners => *sent.entry((k, e.band)).or_default() += cost,
            // A reader that starts at the keyframe skips its Delta chunk.
            ChunkKind::Key => *below.entry((k, e.band)).or_default() += cost,
            ChunkKind::Delta if e.frame != k => *below.entry((k, e.band)).or_default() += cost,
            _ => {}
        }
        bands = bands.max(e.band + 1);
    }
    let derive = |k: u32, j: u32| match policy {
        DerivedTopology::Never => false,
        DerivedTopology::Always => true,
        DerivedTopology::WhenCheaper => {
            let instead: u64 = (0..j).map(|i| below.get(&(k, i)).copied().unwrap_or(0)).sum::<u64>() + 2 + ENTRY;
            instead <= sent.get(&(k, j)).copied().unwrap_or(0)
        }
    };
    let derived: std::collections::BTreeSet<(u32, u32)> =
        chunks.iter().filter(|(e, _)| e.kind == ChunkKind::Faces && derive(e.frame, e.band)).map(|(e, _)| (e.frame, e.band)).collect();
    let (empty, faces) = (stored(&[0])?, stored(&DERIVED_FACES)?);
    let mut out = Vec::with_capacity(chunks.len());
    for (mut e, bytes) in chunks.drain(..) {
        if !derived.contains(&(keyframe_before(e.frame), e.band)) {
            out.push((e, bytes));
            continue;
        }
        match e.kind {
            ChunkKind::Faces => {
                e.raw_len = DERIVED_FACES.len() as u32;
                e.stored_len = faces.len() as u32;
                e.crc32 = crc32fast::hash(&faces);
                out.push((e, faces.clone()));
            }
            ChunkKind::Corners if sparse => {}
            ChunkKind::Corners => {
                e.raw_len = 1;
                e.stored_len = empty.len() as u32;
                e.crc32 = crc32fast::hash(&empty);
                out.push((e, empty.clone()));
            }
            _ => out.push((e, bytes)),
        }
    }
    *chunks = out;
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn below_follows_moves_as_the_encoder_rule() {
        // A strip of 4 triangles over 6 vertices; level 1 pairs them, level 2 has two nodes.
        let tris = Arc::new(vec![[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4]]);
        let parents = vec![vec![0, 0, 1, 1, 2, 2], vec![0, 0, 1]];
        let mut b = Below::new(tris, parents);
        // Level-2 corners: [0,0,0], [0,0,0], [0,0,1], [0,1,1]: none alive.
        assert!(b.faces().is_empty());
        // Vertex 3 moves to cluster 2 (level-2 node 1) and level-1 node 1 to level-2 node 1:
        // triangles 0..3 at level 2 become [0,0,1], [0,1,1], [1,1,1], [1,1,1].
        let updates = b.apply(&[(0, vec![(3, 2)]), (1, vec![(1, 1)])]);
        // Nothing alive before or after: no updates, whatever changed.
        assert!(updates.is_empty());
        let mut b = Below::new(Arc::new(vec![[0, 1, 2], [1, 3, 2]]), vec![vec![0, 1, 2, 2]]);
        assert_eq!(b.faces(), vec![(0, [0, 1, 2])]);
        // Vertex 3 joins node 0: triangle 1 comes alive, triangle 0 keeps its corners.
        assert_eq!(b.apply(&[(0, vec![(3, 0)])]), vec![(1, [1, 0, 2])]);
        // Vertex 2 joins node 1: both die (a repeated corner), both are updated.
        assert_eq!(b.apply(&[(0, vec![(2, 1)])]), vec![(0, [0, 1, 1]), (1, [1, 0, 1])]);
    }
}
