//! The first bones: vertices clustered by their motion, one rigid bone per cluster. Seeds by
//! farthest-point sampling of vertex trajectories, then Lloyd iterations in which every cluster
//! gets its per-frame rigid transform (Horn) and every vertex moves to the bone whose
//! transforms reproduce its trajectory best: the motion-based clustering that MPEG-4 FAMC
//! segments an animation with (Mamou, Zaharia and Prêteux, "FAMC: the MPEG-4 standard for
//! animated mesh compression", 2008) and that Le and Deng initialise SSDR with ("Smooth
//! Skinning Decomposition with Rigid Bones", 2012, section 4.2), including their reseeding of
//! an empty bone at the vertex reconstructed worst. [`split`] starts a fit with more bones
//! from one with fewer (each new bone seeded at the worst-reconstructed vertex of a bone that
//! reconstructs its vertices worst), so that doubling the bone count refines the last fit
//! instead of starting again.

use super::horn::{Rigid, fit_rigid};
use super::sample::Data;
use glam::DVec3;
use rayon::prelude::*;

/// Bones a vertex is compared with at most, in the clustering and the choice of candidates:
/// those whose vertices' rest centroid is nearest its rest position. A bone far away in the
/// rest pose rarely follows a vertex better than a near one, and comparing every vertex with
/// every bone would make the cost grow with the square of the bone count.
pub const NEAR_BONES: usize = 24;

/// Every bone's rest centroid of the vertices `labels` puts on it (bones without vertices are
/// left out).
pub fn centroids(rest: &[DVec3], labels: &[u32], bones: usize) -> Vec<(u32, DVec3)> {
    let mut sum = vec![(DVec3::ZERO, 0usize); bones];
    for (p, &b) in rest.iter().zip(labels) {
        if let Some(s) = sum.get_mut(b as usize) {
            s.0 += *p;
            s.1 += 1;
        }
    }
    sum.iter().enumerate().filter(|(_, s)| s.1 > 0).map(|(b, s)| (b as u32, s.0 / s.1 as f64)).collect()
}

/// For every point, the (at most [`NEAR_BONES`]) bones whose `centroids` are nearest it,
/// nearest first (ties by bone number).
pub fn near_bones(points: &[DVec3], centroids: &[(u32, DVec3)]) -> Vec<Vec<u32>> {
    let tree = Centroids::new(centroids);
    points.par_iter().map(|p| tree.nearest(*p)).collect()
}

/// Centroids in a k-d tree (Bentley, "Multidimensional binary search trees used for
/// associative searching", 1975), for [`near_bones`]: a point compares itself with the
/// centroids of the cells that may hold one of its nearest, not with every bone's (a fit
/// compares every sampled vertex with up to 256 bones at every alternation).
struct Centroids {
    /// Finite centroids, each cell's together.
    items: Vec<(u32, DVec3)>,
    /// Centroids with a coordinate that is not finite: compared with every point.
    odd: Vec<(u32, DVec3)>,
    cells: Vec<Cell>,
}

/// A k-d tree cell: `items[start..end]`, split (when `split` is Some) at `value` on `axis` into
/// the cells `split.0` (coordinates at most `value`) and `split.1` (at least `value`).
struct Cell {
    start: usize,
    end: usize,
    axis: usize,
    value: f64,
    split: Option<(usize, usize)>,
}

/// Centroids per leaf cell at most.
const LEAF: usize = 8;

impl Centroids {
    fn new(centroids: &[(u32, DVec3)]) -> Self {
        let (items, odd): (Vec<_>, Vec<_>) = centroids.iter().partition(|c| c.1.is_finite());
        let mut tree = Centroids { items, odd, cells: Vec::new() };
        let n = tree.items.len();
        tree.build(0, n);
        tree
    }

    /// Makes the cell of `items[start..end]` and those below it; returns its index.
    fn build(&mut self, start: usize, end: usize) -> usize {
        let at = self.cells.len();
        self.cells.push(Cell { start, end, axis: 0, value: 0.0, split: None });
        if end - start <= LEAF {
            return at;
        }
        let part = &mut self.items[start..end];
        let (lo, hi) = part.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| (lo.min(c.1), hi.max(c.1)));
        let axis = (hi - lo).max_position();
        part.sort_unstable_by(|a, b| a.1[axis].total_cmp(&b.1[axis]).then(a.0.cmp(&b.0)));
        let mid = start + (end - start) / 2;
        let value = self.items[mid].1[axis];
        let left = self.build(start, mid);
        let right = self.build(mid, end);
        self.cells[at] = Cell { start, end, axis, value, split: Some((left, right)) };
        at
    }

    /// The (at most [`NEAR_BONES`]) bones nearest `p`, nearest first, ties by bone number.
    ///
    /// Exactly those of comparing `p` with every centroid: a cell is passed over only where
    /// no centroid in it can come before the last of a full list. Its centroids lie beyond
    /// the splitting plane, so each one's squared distance (as computed: rounding is monotone,
    /// and the squares it sums are not negative) is at least the rounded square of `p`'s
    /// distance to the plane.
    fn nearest(&self, p: DVec3) -> Vec<u32> {
        let m = NEAR_BONES.min(self.items.len() + self.odd.len());
        let mut near = Nearest { list: [(0.0, 0); NEAR_BONES], len: 0, m };
        for &(b, c) in &self.odd {
            near.offer(c.distance_squared(p), b);
        }
        if !self.items.is_empty() {
            self.visit(0, p, p.is_finite(), &mut near);
        }
        near.list[..near.len].iter().map(|s| s.1).collect()
    }

    fn visit(&self, cell: usize, p: DVec3, prune: bool, near: &mut Nearest) {
        let c = &self.cells[cell];
        let Some((left, right)) = c.split else {
            for &(b, x) in &self.items[c.start..c.end] {
                near.offer(x.distance_squared(p), b);
            }
            return;
        };
        let (first, second) = if p[c.axis] <= c.value { (left, right) } else { (right, left) };
        self.visit(first, p, prune, near);
        let gap = (c.value - p[c.axis]).abs();
        if !(prune && near.full() && gap * gap > near.list[near.m - 1].0) {
            self.visit(second, p, prune, near);
        }
    }
}

/// The `m` entries (squared distance, bone) first in the order of distance then bone number
/// among those offered, in that order.
struct Nearest {
    list: [(f64, u32); NEAR_BONES],
    len: usize,
    m: usize,
}

impl Nearest {
    fn full(&self) -> bool {
        self.len == self.m
    }

    #[inline]
    fn offer(&mut self, d: f64, b: u32) {
        let before = |a: (f64, u32), b: (f64, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).is_lt();
        let entry = (d, b);
        if self.m == 0 || (self.full() && !before(entry, self.list[self.m - 1])) {
            return;
        }
        let mut j = if self.full() {
            self.m - 1
        } else {
            self.len += 1;
            self.len - 1
        };
        while j > 0 && before(entry, self.list[j - 1]) {
            self.list[j] = self.list[j - 1];
            j -= 1;
        }
        self.list[j] = entry;
    }
}

/// One bone label per vertex and the bones' transforms per frame of the data
/// (`transforms[fi * bones + b]`, the identity in the rest frame).
pub struct Clusters {
    pub labels: Vec<u32>,
    pub transforms: Vec<Rigid>,
}

/// Clusters the vertices of `data` into `bones` rigid bones (`bones` at most the vertex count,
/// at least 1): seeds by farthest-point sampling of trajectories, then [`lloyd`].
pub fn cluster(data: &Data, bones: usize, iterations: u32) -> Clusters {
    let n = data.len();
    let frames = data.frames.len();
    // Trajectory distance over the data's frames.
    let dist = |u: usize, v: usize| -> f64 { (0..frames).map(|fi| data.at(fi, u).distance_squared(data.at(fi, v))).sum() };
    // First seed: the vertex farthest from the mean trajectory, so that the seeding does not
    // depend on the input's vertex numbering more than ties require.
    let mean: Vec<DVec3> = (0..frames).map(|fi| (0..n).map(|v| data.at(fi, v)).sum::<DVec3>() / n as f64).collect();
    let mut first = 0;
    let mut far = -1.0;
    for v in 0..n {
        let d: f64 = mean.iter().enumerate().map(|(fi, m)| data.at(fi, v).distance_squared(*m)).sum();
        if d > far {
            (far, first) = (d, v);
        }
    }
    let mut labels = vec![0u32; n];
    let mut nearest: Vec<f64> = (0..n).map(|v| dist(first, v)).collect();
    for b in 1..bones {
        let mut seed = 0;
        for v in 1..n {
            if nearest[v] > nearest[seed] {
                seed = v;
            }
        }
        for v in 0..n {
            let d = dist(seed, v);
            if d < nearest[v] {
                nearest[v] = d;
                labels[v] = b as u32;
            }
        }
    }
    lloyd(data, labels, bones, iterations)
}

/// Lloyd iterations from `labels`: every bone's rigid transform per frame fitted to its
/// vertices, every vertex moved to the bone (its own or one near it) that reproduces its
/// trajectory best; then the transforms fitted once more to the final labels.
pub fn lloyd(data: &Data, mut labels: Vec<u32>, bones: usize, iterations: u32) -> Clusters {
    let n = data.len();
    let frames = data.frames.len();
    let mut transforms = vec![Rigid::IDENTITY; frames * bones];
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); bones];
    let mut error = vec![0.0f64; n];
    for it in 0..=iterations {
        for m in members.iter_mut() {
            m.clear();
        }
        for (v, &b) in labels.iter().enumerate() {
            members[b as usize].push(v);
        }
        // A bone that lost all its vertices restarts at the vertex reconstructed worst.
        if it > 0 {
            for b in 0..bones {
                if !members[b].is_empty() {
                    continue;
                }
                let mut worst = None;
                for v in 0..n {
                    if members[labels[v] as usize].len() > 1 && worst.is_none_or(|w: usize| error[v] > error[w]) {
                        worst = Some(v);
                    }
                }
                if let Some(v) = worst {
                    let old = labels[v] as usize;
                    members[old].retain(|&u| u != v);
                    labels[v] = b as u32;
                    members[b].push(v);
                    error[v] = 0.0;
                }
            }
        }
        transforms.par_chunks_mut(bones).enumerate().filter(|(fi, _)| !data.is_rest(*fi)).for_each(|(fi, row)| {
            for (b, m) in members.iter().enumerate() {
                row[b] = fit_rigid(m.iter().map(|&v| (data.rest[v], data.at(fi, v), 1.0)));
            }
        });
        // Every vertex to the bone that reproduces its trajectory best, among its own and the
        // bones near it (its own only on the last pass, which measures the errors).
        let near = if it < iterations { near_bones(&data.rest, &centroids(&data.rest, &labels, bones)) } else { Vec::new() };
        let assigned: Vec<(f64, u32)> = (0..n)
            .into_par_iter()
            .map(|v| {
                let mut best = (f64::INFINITY, labels[v]);
                let others = near.get(v).map_or(&[][..], |x| &x[..]);
                for b in std::iter::once(labels[v] as usize).chain(others.iter().map(|&b| b as usize)) {
                    let mut e = 0.0;
                    for fi in 0..frames {
                        e += transforms[fi * bones + b].apply(data.rest[v]).distance_squared(data.at(fi, v));
                        if e >= best.0 {
                            break;
                        }
                    }
                    if e < best.0 {
                        best = (e, b as u32);
                    }
                }
                best
            })
            .collect();
        for (v, (e, b)) in assigned.into_iter().enumerate() {
            labels[v] = b;
            error[v] = e;
        }
        if it == iterations {
            break;
        }
    }
    Clusters { labels, transforms }
}

/// Labels for `to` bones from a fit with `from` (`labels`, each vertex's main bone, and
/// `error`, each vertex's squared error under the fit): the `to - from` bones whose vertices
/// are reconstructed worst (summed error, ties by number) are split in two, like the
/// farthest-point seeding of [`cluster`] with two seeds: the bone's worst-reconstructed vertex
/// seeds the new bone, its best-reconstructed one stays, and every vertex of the bone follows
/// the seed whose trajectory is nearer its own. Lloyd iterations then settle the rest (Le and
/// Deng's reseeding at the worst vertex, applied to many bones at once).
pub fn split(data: &Data, labels: &[u32], error: &[f64], from: usize, to: usize) -> Vec<u32> {
    let n = data.len();
    let frames = data.frames.len();
    let dist = |u: usize, v: usize| -> f64 { (0..frames).map(|fi| data.at(fi, u).distance_squared(data.at(fi, v))).sum() };
    let mut bone_error = vec![(0.0f64, 0usize); from];
    for v in 0..n {
        let b = &mut bone_error[labels[v] as usize];
        b.0 += error[v];
        b.1 += 1;
    }
    // Bones with at least two vertices can split, worst first.
    let mut order: Vec<usize> = (0..from).filter(|&b| bone_error[b].1 >= 2).collect();
    order.sort_by(|&a, &b| bone_error[b].0.total_cmp(&bone_error[a].0).then(a.cmp(&b)));
    order.truncate(to - from);
    let mut new_of = vec![u32::MAX; from];
    for (j, &b) in order.iter().enumerate() {
        new_of[b] = (from + j) as u32;
    }
    // Each split bone's worst and best vertex (first in index order among equals).
    let (mut worst, mut best) = (vec![usize::MAX; from], vec![usize::MAX; from]);
    for v in 0..n {
        let b = labels[v] as usize;
        if new_of[b] == u32::MAX {
            continue;
        }
        if worst[b] == usize::MAX || error[v] > error[worst[b]] {
            worst[b] = v;
        }
        if best[b] == usize::MAX || error[v] < error[best[b]] {
            best[b] = v;
        }
    }
    let mut out = labels.to_vec();
    for v in 0..n {
        let b = labels[v] as usize;
        if new_of[b] != u32::MAX && (v == worst[b] || (v != best[b] && dist(v, worst[b]) < dist(v, best[b]))) {
            out[v] = new_of[b];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_bones_are_the_nearest_in_order_ties_by_number() {
        // Centroids on a coarse grid (many equal distances) and points between them.
        let grid = |i: u32| DVec3::new((i % 5) as f64, (i / 5 % 5) as f64, (i / 25) as f64);
        for count in [0, 1, 7, NEAR_BONES, NEAR_BONES + 1, 60, 125, 256] {
            let mut centroids: Vec<(u32, DVec3)> = (0..count as u32).rev().map(|b| (b * 3, grid(b * 7 % 125))).collect();
            if count == 60 {
                // Centroids that are not finite rank last (NaN after infinity), as in a sort.
                centroids.extend([(1000, DVec3::new(f64::NAN, 0.0, 0.0)), (1001, DVec3::splat(f64::INFINITY))]);
            }
            let mut points: Vec<DVec3> = (0..50).map(|i| grid(i * 11 % 125) * 0.5 + DVec3::splat(0.25 * (i % 3) as f64)).collect();
            // And points anywhere (a fixed linear congruential sequence), far ones too.
            let mut x = 12345u64;
            let mut next = || {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (x >> 11) as f64 / (1u64 << 53) as f64 * 12.0 - 4.0
            };
            points.extend((0..200).map(|_| DVec3::new(next(), next(), next())));
            let got = near_bones(&points, &centroids);
            for (p, near) in points.iter().zip(&got) {
                let mut all: Vec<(f64, u32)> = centroids.iter().map(|&(b, c)| (c.distance_squared(*p), b)).collect();
                all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let want: Vec<u32> = all.iter().take(NEAR_BONES).map(|s| s.1).collect();
                assert_eq!(near, &want, "{count} centroids, point {p}");
            }
        }
    }
}
