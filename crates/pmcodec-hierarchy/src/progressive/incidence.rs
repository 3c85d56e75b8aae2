//! A replay's triangles by level-L corner.

use super::*;
use crate::rows::compressed_rows;

/// Triangles by level-L corner: a flat list per node built at a keyframe (CSR), plus the
/// additions corner updates make until the next keyframe. Removals are not recorded: a reader
/// checks that the triangle still has that corner. (Thousands of small vectors made keyframe
/// loads, and so seeks, a tenth slower.)
#[derive(Clone, Debug, Default)]
pub(super) struct Incidence {
    pub(super) offsets: Vec<u32>,
    pub(super) list: Vec<u32>,
    pub(super) extra: std::collections::HashMap<u32, Vec<u32>>,
}

impl Incidence {
    /// Over `size` nodes, from every triangle whose corners are distinct.
    pub(super) fn new(size: usize, corners: &[[u32; 3]]) -> Self {
        let alive = |c: &[u32; 3]| c[0] != NONE && distinct(*c);
        let (offsets, list) =
            compressed_rows(size, || corners.iter().enumerate().filter(|(_, c)| alive(c)).flat_map(|(t, c)| c.map(|x| (x, t as u32))));
        Incidence { offsets, list, extra: Default::default() }
    }

    pub(super) fn add(&mut self, x: u32, t: u32) {
        self.extra.entry(x).or_default().push(t);
    }

    /// Triangles that have, or had, corner x (callers filter stale entries).
    pub(super) fn of(&self, x: u32) -> (&[u32], &[u32]) {
        let (a, b) = (self.offsets[x as usize] as usize, self.offsets[x as usize + 1] as usize);
        (&self.list[a..b], self.extra.get(&x).map_or(&[], Vec::as_slice))
    }
}
