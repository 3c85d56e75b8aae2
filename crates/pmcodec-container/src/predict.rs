//! Prediction of quantized node positions, shared by encoder and decoder (proto/container.md,
//! "Positions, band j"). Neighbour means are integer arithmetic (64-bit sums, a floor
//! division), 32-bit wrapping for the rest. The level-0 affine motion fit is IEEE double
//! arithmetic in an order the spec fixes, without fused multiply-adds, so a decoder in any
//! language that follows it gets the same bits.

use crate::format::{Header, Motion, VertexOrder};

/// For each input vertex, its *lower neighbours*: the distinct vertices that share an input
/// triangle with it and are decoded before it in band 0's [`VertexOrder`], in compressed rows
/// in decoding order. And its *stencil*, which the affine motions read: its lower neighbours
/// and the lower neighbours of the last (most recently decoded) of them, distinct, in decoding
/// order. In input order (versions 3 and 4) "decoded before" is "smaller".
#[derive(Clone, Debug, Default)]
pub struct LowerNeighbours {
    /// Band 0's vertices in decoding order.
    sequence: Vec<u32>,
    offsets: Vec<u32>,
    items: Vec<u32>,
    stencil_offsets: Vec<u32>,
    stencil_items: Vec<u32>,
}

/// The input triangles' edges as rows by vertex: for each `a`, the distinct `b` sharing a
/// triangle with it, ascending, dropping degenerate and out-of-range corners (only broken input
/// has them). Returns (offsets, items).
fn neighbour_rows(n: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let pairs = || {
        triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[0]), (t[1], t[2]), (t[2], t[1]), (t[2], t[0]), (t[0], t[2])])
            .filter(move |&(a, b)| a != b && (a as usize) < n && (b as usize) < n)
    };
    let (offsets, mut items) = pmcodec_hierarchy::rows::compressed_rows(n, pairs);
    // Sort and de-duplicate each row, closing the gaps.
    let mut out = vec![0u32; n + 1];
    let mut w = 0usize;
    for v in 0..n {
        let (lo, hi) = (offsets[v] as usize, offsets[v + 1] as usize);
        items[lo..hi].sort_unstable();
        let start = w;
        for i in lo..hi {
            if w == start || items[w - 1] != items[i] {
                items[w] = items[i];
                w += 1;
            }
        }
        out[v + 1] = w as u32;
    }
    items.truncate(w);
    (out, items)
}

/// Breadth-first order over the input triangles' edges (proto/container.md, "Band 0 order"):
/// from the smallest vertex not yet reached, first in first out, each vertex's neighbours
/// taken in ascending order; a vertex on no triangle comes in its turn as a start.
fn breadth_first(n: usize, offsets: &[u32], items: &[u32]) -> Vec<u32> {
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for start in 0..n {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        // `order` is the queue: what lies after `head` is waiting.
        let mut head = order.len();
        order.push(start as u32);
        while head < order.len() {
            let v = order[head] as usize;
            head += 1;
            for &u in &items[offsets[v] as usize..offsets[v + 1] as usize] {
                if !seen[u as usize] {
                    seen[u as usize] = true;
                    order.push(u);
                }
            }
        }
    }
    order
}

impl LowerNeighbours {
    /// The rows and stencils for `n` vertices of `triangles`, decoded in `order`.
    pub fn new(n: usize, triangles: &[[u32; 3]], order: VertexOrder) -> Self {
        let (all_offsets, all) = neighbour_rows(n, triangles);
        let sequence: Vec<u32> = match order {
            VertexOrder::Input => (0..n as u32).collect(),
            VertexOrder::BreadthFirst => breadth_first(n, &all_offsets, &all),
        };
        let mut rank = vec![0u32; n];
        for (k, &v) in sequence.iter().enumerate() {
            rank[v as usize] = k as u32;
        }
        // Each row's neighbours decoded before it, in decoding order.
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut items = Vec::with_capacity(all.len() / 2);
        for v in 0..n {
            let start = items.len();
            items.extend(all[all_offsets[v] as usize..all_offsets[v + 1] as usize].iter().filter(|&&u| rank[u as usize] < rank[v]));
            items[start..].sort_unstable_by_key(|&u| rank[u as usize]);
            offsets.push(items.len() as u32);
        }
        let mut lower = LowerNeighbours { sequence, offsets, items, stencil_offsets: vec![0], stencil_items: Vec::new() };
        lower.build_stencils(n, &rank);
        lower
    }

    /// Band 0's vertices in decoding order.
    #[inline]
    pub fn sequence(&self) -> &[u32] {
        &self.sequence
    }

    /// Stencil rows: `row(v)` and `row(u)` for u the last of `row(v)`, merged, in decoding
    /// order, distinct. (Adding every lower neighbour's row, 6.7 vertices instead of 4.5, saves
    /// no bits on the horse and 0.2 on samba, for half again the work.)
    fn build_stencils(&mut self, n: usize, rank: &[u32]) {
        let mut mark = vec![u32::MAX; n];
        let mut row: Vec<u32> = Vec::new();
        self.stencil_offsets = Vec::with_capacity(n + 1);
        self.stencil_offsets.push(0);
        self.stencil_items = Vec::with_capacity(self.items.len() * 3);
        for v in 0..n {
            row.clear();
            // The last lower neighbour is the one decoded most recently: its own row lies
            // where v's neighbourhood continues.
            let last = self.row(v).last().copied();
            for &u in self.row(v) {
                let extra: &[u32] = if Some(u) == last { self.row(u as usize) } else { &[] };
                for w in std::iter::once(u).chain(extra.iter().copied()) {
                    if mark[w as usize] != v as u32 {
                        mark[w as usize] = v as u32;
                        row.push(w);
                    }
                }
            }
            row.sort_unstable_by_key(|&w| rank[w as usize]);
            self.stencil_items.extend_from_slice(&row);
            self.stencil_offsets.push(self.stencil_items.len() as u32);
        }
    }

    /// The range of `v`'s stencil in the flat stencil arrays (empty for an unknown vertex).
    #[inline]
    fn stencil_range(&self, v: usize) -> std::ops::Range<usize> {
        match (self.stencil_offsets.get(v), self.stencil_offsets.get(v + 1)) {
            (Some(&a), Some(&b)) => a as usize..b as usize,
            _ => 0..0,
        }
    }

    /// The stencil of vertex `v` (input numbering), in decoding order; empty for a vertex out of range.
    #[inline]
    pub fn stencil(&self, v: usize) -> &[u32] {
        match (self.stencil_offsets.get(v), self.stencil_offsets.get(v + 1)) {
            (Some(&a), Some(&b)) => &self.stencil_items[a as usize..b as usize],
            _ => &[],
        }
    }

    /// The lower neighbours of vertex `v` (input numbering), in decoding order; empty for a vertex out of range.
    #[inline]
    pub fn row(&self, v: usize) -> &[u32] {
        match (self.offsets.get(v), self.offsets.get(v + 1)) {
            (Some(&a), Some(&b)) => &self.items[a as usize..b as usize],
            _ => &[],
        }
    }
}

/// `round(sum / count)` with halves rounded up: `floor((2 sum + count) / (2 count))`.
#[inline(always)]
fn mean(sum: i64, count: i64) -> i64 {
    // The same value through 32-bit division when it fits (always, on valid files): 64-bit
    // division is several times slower on common CPUs and this runs three times per vertex.
    // Small counts are spelled out so that the compiler divides by constants (a multiply).
    let n = 2 * sum + count;
    match i32::try_from(n) {
        Ok(n) => {
            (match count {
                1 => n.div_euclid(2),
                2 => n.div_euclid(4),
                3 => n.div_euclid(6),
                4 => n.div_euclid(8),
                5 => n.div_euclid(10),
                6 => n.div_euclid(12),
                c => n.div_euclid(2 * c as i32),
            }) as i64
        }
        Err(_) => n.div_euclid(2 * count),
    }
}

/// Running motion of the nodes of a band decoded so far, per parent: on inter frames a node
/// whose siblings (same parent, smaller index) are decoded moves as their mean does. That is
/// better than the parent's motion, which carries the parent's coarser quantization.
#[derive(Clone, Debug, Default)]
pub struct Siblings {
    sum: Vec<[i64; 3]>,
    count: Vec<u32>,
}

impl Siblings {
    /// Clears the sums for a band whose parents number `parents`.
    pub fn reset(&mut self, parents: usize) {
        self.sum.clear();
        self.sum.resize(parents, [0; 3]);
        self.count.clear();
        self.count.resize(parents, 0);
    }

    /// Records the decoded node `q` (previous position `prev`) under its parent's local id.
    #[inline(always)]
    pub fn add(&mut self, parent: usize, q: [i32; 3], prev: [i32; 3]) {
        if let (Some(s), Some(c)) = (self.sum.get_mut(parent), self.count.get_mut(parent)) {
            for a in 0..3 {
                s[a] += q[a] as i64 - prev[a] as i64;
            }
            *c += 1;
        }
    }
}

/// What band 0 moves by on inter frames, with what it was prepared from.
#[derive(Clone, Copy, Debug)]
pub enum Band0Motion<'a> {
    /// The lower neighbours' mean motion.
    Mean,
    /// Version 4's affine motion, fitted on the previous frame.
    Affine(&'a AffineFits),
    /// The stencil's motions weighted as the keyframe's geometry gives.
    KeyframeAffine(&'a StencilWeights),
}

impl<'a> Band0Motion<'a> {
    /// What a band moves by, as encoder and decoder both choose it: the header's `motion` for
    /// band 0 on inter frames (`inter_band_0`; the affine fits prepared from `previous`, the
    /// first `n0` nodes), the mean motion everywhere else (where band 0's is not read).
    pub fn select(
        motion: Motion,
        inter_band_0: bool,
        lower: &LowerNeighbours,
        previous: &[[i32; 3]],
        n0: usize,
        fits: &'a mut AffineFits,
        weights: &'a StencilWeights,
    ) -> Self {
        match motion {
            _ if !inter_band_0 => Band0Motion::Mean,
            Motion::Mean => Band0Motion::Mean,
            Motion::Affine => {
                fits.prepare(lower, previous, n0);
                Band0Motion::Affine(fits)
            }
            Motion::KeyframeAffine => Band0Motion::KeyframeAffine(weights),
        }
    }
}

/// The prediction of node `v` (global id `g`) of band `j`. `before` is the global id of the
/// node decoded just before it in the band (None for the first). `parent` is its parent as
/// (global id, local id at level j+1) in the current frame's hierarchy (None for the top band),
/// `lower` the level-0 lower neighbours and `motion` band 0's motion on inter frames,
/// `siblings` the motion of the band's decoded nodes (inter frames), `intra` for keyframes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn predict(
    j: usize,
    v: usize,
    g: usize,
    before: Option<usize>,
    parent: Option<(usize, usize)>,
    lower: &LowerNeighbours,
    motion: Band0Motion,
    siblings: &Siblings,
    intra: bool,
    cur: &[[i32; 3]],
    prev: &[[i32; 3]],
) -> [i32; 3] {
    if j == 0 {
        let row = lower.row(v);
        if !row.is_empty() {
            let c = row.len() as i64;
            let mut s = [0i64; 3];
            if intra {
                for &u in row {
                    let q = cur[u as usize];
                    for a in 0..3 {
                        s[a] += q[a] as i64;
                    }
                }
                return [mean(s[0], c) as i32, mean(s[1], c) as i32, mean(s[2], c) as i32];
            }
            let fitted = match motion {
                Band0Motion::Mean => None,
                Band0Motion::Affine(f) => f.predict(lower.stencil(v), v, cur, prev),
                Band0Motion::KeyframeAffine(w) => w.predict(lower, v, cur, prev),
            };
            if let Some(q) = fitted {
                return q;
            }
            for &u in row {
                let (q, p) = (cur[u as usize], prev[u as usize]);
                for a in 0..3 {
                    s[a] += q[a] as i64 - p[a] as i64;
                }
            }
            let p = prev[g];
            return [(p[0] as i64 + mean(s[0], c)) as i32, (p[1] as i64 + mean(s[1], c)) as i32, (p[2] as i64 + mean(s[2], c)) as i32];
        }
    }
    if let (false, Some((_, local))) = (intra, parent)
        && let (Some(&c), Some(s)) = (siblings.count.get(local), siblings.sum.get(local))
        && c > 0
    {
        let (p, c) = (prev[g], c as i64);
        return [(p[0] as i64 + mean(s[0], c)) as i32, (p[1] as i64 + mean(s[1], c)) as i32, (p[2] as i64 + mean(s[2], c)) as i32];
    }
    let parent = parent.map(|(p, _)| p);
    let mut out = [0i32; 3];
    for a in 0..3 {
        out[a] = match (intra, parent) {
            (true, Some(p)) => cur[p][a],
            (true, None) => before.and_then(|b| cur.get(b)).map_or(0, |q| q[a]),
            (false, Some(p)) => prev[g][a].wrapping_add(cur[p][a].wrapping_sub(prev[p][a])),
            (false, None) => prev[g][a],
        };
    }
    out
}

/// The part of one vertex's affine fit that depends on the previous frame only.
#[derive(Clone, Copy, Debug, Default)]
struct Fit {
    /// `adj(M) sa`: the fit's solve, times `det`.
    z: [f64; 3],
    /// `sa . z`.
    k: f64,
    /// The regularization added to both diagonals.
    t: f64,
    det: f64,
    /// `1 / (det m)`.
    inv: f64,
}

/// Band 0 on inter frames: vertex v moves by the affine map that best carries its stencil from
/// the previous frame to this one (least squares, regularized toward a translation so that a
/// flat or tiny stencil stays well posed). Limbs of a galloping horse or a dancer rotate from
/// frame to frame; a mean of the neighbours' motion misses the rotation by its angle times the
/// neighbours' distance, an affine map does not: on the horse at 12 bits it saves 2.3 bits per
/// vertex per frame, on samba 1.5.
///
/// The fit is split so that decoding stays fast: [`AffineFits::prepare`] solves, for every
/// vertex before the band is decoded, what depends on the previous frame alone (independent
/// work a CPU overlaps); `AffineFits::predict` then needs one pass over the stencil's
/// decoded positions and no division. Coordinates are relative to the vertex's previous
/// position, so on valid files the stencil sums are of small integers and exact in doubles;
/// proto/container.md fixes the order of every other operation.
#[derive(Clone, Debug, Default)]
pub struct AffineFits {
    fits: Vec<Fit>,
}

impl AffineFits {
    /// Solves the previous-frame part of every vertex's fit (proto/container.md, "Affine
    /// motion": everything up to `inv`).
    pub fn prepare(&mut self, lower: &LowerNeighbours, prev: &[[i32; 3]], n: usize) {
        self.fits.clear();
        self.fits.resize(n, Fit::default());
        for (v, fit) in self.fits.iter_mut().enumerate() {
            if let Some(f) = solve(lower.stencil(v), v, prev) {
                *fit = f;
            }
        }
    }

    /// The affine prediction of vertex `v` from its stencil's decoded positions; None when
    /// there is no fit or the result does not fit an i32 (only on broken input), and the
    /// caller falls back to the neighbours' mean motion.
    #[inline(always)]
    fn predict(&self, stencil: &[u32], v: usize, cur: &[[i32; 3]], prev: &[[i32; 3]]) -> Option<[i32; 3]> {
        let (fit, o) = (self.fits.get(v)?, prev.get(v)?);
        if stencil.is_empty() {
            return None;
        }
        let of = [o[0] as f64, o[1] as f64, o[2] as f64];
        let (mut sb, mut g) = ([0f64; 3], [0f64; 3]);
        for &w in stencil {
            let (Some(p), Some(c)) = (prev.get(w as usize), cur.get(w as usize)) else { return None };
            let a = [p[0] as f64 - of[0], p[1] as f64 - of[1], p[2] as f64 - of[2]];
            let s = a[0] * fit.z[0] + a[1] * fit.z[1] + a[2] * fit.z[2];
            for i in 0..3 {
                let b = c[i] as f64 - of[i];
                sb[i] += b;
                g[i] += b * s;
            }
        }
        let m = stencil.len() as f64;
        let mut q = [0i32; 3];
        for i in 0..3 {
            let e = (sb[i] * fit.det - (m * g[i] - sb[i] * fit.k + fit.t * fit.z[i])) * fit.inv + 0.5;
            // floor(e), without the libm call `f64::floor` is on CPUs without SSE4.1: truncate,
            // then step down where truncation went up. NaN is refused with the rest.
            if e.is_nan() || e.abs() >= 2147483648.0 {
                return None;
            }
            let r = e as i32;
            q[i] = o[i].wrapping_add(if (r as f64) > e { r - 1 } else { r });
        }
        Some(q)
    }
}

/// The part of vertex `v`'s affine fit that its stencil's positions `at` give (proto/
/// container.md, "Affine motion": everything up to `inv`); None for an empty stencil.
#[inline]
fn solve(stencil: &[u32], v: usize, at: &[[i32; 3]]) -> Option<Fit> {
    let o = at.get(v)?;
    if stencil.is_empty() {
        return None;
    }
    let o = [o[0] as f64, o[1] as f64, o[2] as f64];
    let mut sa = [0f64; 3];
    // Sums of a a^T, upper triangle: 00 01 02 11 12 22.
    let mut s = [0f64; 6];
    for &w in stencil {
        let p = at.get(w as usize)?;
        let a = [p[0] as f64 - o[0], p[1] as f64 - o[1], p[2] as f64 - o[2]];
        sa[0] += a[0];
        sa[1] += a[1];
        sa[2] += a[2];
        s[0] += a[0] * a[0];
        s[1] += a[0] * a[1];
        s[2] += a[0] * a[2];
        s[3] += a[1] * a[1];
        s[4] += a[1] * a[2];
        s[5] += a[2] * a[2];
    }
    let m = stencil.len() as f64;
    let im = 1.0 / m;
    // m times the centred scatter of the stencil's positions, plus t.
    let mut m00 = m * s[0] - sa[0] * sa[0];
    let m01 = m * s[1] - sa[0] * sa[1];
    let m02 = m * s[2] - sa[0] * sa[2];
    let mut m11 = m * s[3] - sa[1] * sa[1];
    let m12 = m * s[4] - sa[1] * sa[2];
    let mut m22 = m * s[5] - sa[2] * sa[2];
    let t = (m00 + m11 + m22) * im * 0.015625 + m;
    m00 += t;
    m11 += t;
    m22 += t;
    // Cofactors of the symmetric M: z = adj(M) sa = det M^-1 sa.
    let c00 = m11 * m22 - m12 * m12;
    let c01 = m02 * m12 - m01 * m22;
    let c02 = m01 * m12 - m02 * m11;
    let c11 = m00 * m22 - m02 * m02;
    let c12 = m01 * m02 - m00 * m12;
    let c22 = m00 * m11 - m01 * m01;
    let det = m00 * c00 + m01 * c01 + m02 * c02;
    let z = [c00 * sa[0] + c01 * sa[1] + c02 * sa[2], c01 * sa[0] + c11 * sa[1] + c12 * sa[2], c02 * sa[0] + c12 * sa[1] + c22 * sa[2]];
    let k = sa[0] * z[0] + sa[1] * z[1] + sa[2] * z[2];
    Some(Fit { z, k, t, det, inv: 1.0 / (det * m) })
}

/// Band 0 on inter frames, from format version 5: the affine prediction as a weighted sum of
/// the stencil's motions, `v' = v + sum_w lambda_w (w' - w)`, with weights from the keyframe.
///
/// The fit of [`AffineFits`] predicts, at the vertex, a combination of its stencil's positions
/// whose weights `lambda_w = (det - m a_w.z + k) / (det m)` sum to one and depend on the
/// stencil's shape only: rotating or moving the neighbourhood leaves them unchanged. So they
/// hardly change while a surface bends, and the keyframe's can serve until the next keyframe:
/// on the horse at 12 bits that costs 0.1 bit per vertex per frame against weights fitted on
/// every previous frame (0.02 on samba), and decoding then costs about what the mean motion
/// does (a multiply-add per stencil vertex and axis), not a fit per vertex per frame.
#[derive(Clone, Debug, Default)]
pub struct StencilWeights {
    /// One weight per stencil entry, in [`LowerNeighbours`]' flat stencil order.
    weights: Vec<f64>,
}

impl StencilWeights {
    /// The weights of every stencil from the keyframe's decoded band 0 `key`
    /// (proto/container.md, "Keyframe affine motion").
    pub fn compute(&mut self, lower: &LowerNeighbours, key: &[[i32; 3]], n: usize) {
        self.weights.clear();
        self.weights.resize(lower.stencil_items.len(), 0.0);
        for v in 0..n {
            let range = lower.stencil_range(v);
            let stencil = &lower.stencil_items[range.clone()];
            let (Some(fit), Some(o)) = (solve(stencil, v, key), key.get(v)) else { continue };
            let o = [o[0] as f64, o[1] as f64, o[2] as f64];
            let m = stencil.len() as f64;
            for (weight, &w) in self.weights[range].iter_mut().zip(stencil) {
                let Some(p) = key.get(w as usize) else { break };
                let a = [p[0] as f64 - o[0], p[1] as f64 - o[1], p[2] as f64 - o[2]];
                let s = a[0] * fit.z[0] + a[1] * fit.z[1] + a[2] * fit.z[2];
                *weight = (fit.det - m * s + fit.k) * fit.inv;
            }
        }
    }

    /// The prediction of vertex `v` from its stencil's motions; None without weights or when
    /// the result does not fit an i32 (only on broken input): the caller then falls back to
    /// the mean motion.
    #[inline(always)]
    fn predict(&self, lower: &LowerNeighbours, v: usize, cur: &[[i32; 3]], prev: &[[i32; 3]]) -> Option<[i32; 3]> {
        let range = lower.stencil_range(v);
        let o = prev.get(v)?;
        if range.is_empty() {
            return None;
        }
        let (stencil, weights) = (&lower.stencil_items[range.clone()], self.weights.get(range)?);
        let mut e = [0f64; 3];
        for (&w, &l) in stencil.iter().zip(weights) {
            let (Some(c), Some(p)) = (cur.get(w as usize), prev.get(w as usize)) else { return None };
            e[0] += l * (c[0] as f64 - p[0] as f64);
            e[1] += l * (c[1] as f64 - p[1] as f64);
            e[2] += l * (c[2] as f64 - p[2] as f64);
        }
        let mut q = [0i32; 3];
        for i in 0..3 {
            let x = e[i] + 0.5;
            if x.is_nan() || x.abs() >= 2147483648.0 {
                return None;
            }
            // floor, as in AffineFits::predict.
            let r = x as i32;
            q[i] = o[i].wrapping_add(if (r as f64) > x { r - 1 } else { r });
        }
        Some(q)
    }
}

/// `e` of [`coarse_shift`]: `ceil(log4(|M0| / |Mj|) - 0.25)`, the level index for levels 4x
/// apart (and for a small mesh's levels anchored at 25% and 10%, which files before this rule
/// were written with), less for levels closer together; the index where the header lacks sizes.
fn level_exponent(level_sizes: &[u32], level: usize) -> u32 {
    match (level_sizes.first(), level_sizes.get(level)) {
        (Some(&fine), Some(&size)) if size > 0 && fine >= size => {
            let e = ((fine as f64 / size as f64).ln() / 4f64.ln() - 0.25).ceil();
            e.clamp(0.0, crate::payload::MAX_SHIFT as f64) as u32
        }
        _ => level as u32,
    }
}

/// The residual step (as a power of two of the quantum) the encoder uses for band `level`
/// given [`crate::EncodeOptions::coarse_grid`]. Input vertices, which the error bound applies
/// to, always get 0; with `None` so do coarser nodes. With `Some(k)` (the default is `Some(0)`) band j >= 1
/// is stored on a grid of `2^s` quanta, `s = e + k` at most, and `2^s` quanta at most
/// `2^(e + k) / 4096` of the bounding box's largest extent and at most `2^(k+1) / |Mj|` of it (so
/// 12-bit quantization of a mesh of a few thousand vertices gets `s = e + k`, coarser
/// quantization and larger meshes smaller steps), where `e` is how many times 4 the level is
/// coarser than the input, `ceil(log4(|M0| / |Mj|) - 0.25)`: the spacing of a level's
/// nodes grows as the square root of that ratio, and the grid with it. For the default levels
/// (anchored at 25% and 10% of the triangles, then 4 times fewer vertices each) `e = j`; levels
/// closer together (branching 2, an anchor at 50%) no longer get a grid twice as coarse per
/// level. Coarse nodes approximate many vertices,
/// but a grid still shows in cuts: on the horse at 12 bits, `Some(0)` saves 1.4 bits per vertex
/// per frame for about 3% more RMS error at 800 vertices, `Some(2)` 3 bits for 28% more.
pub fn coarse_shift(header: &Header, level: usize, grid: Option<u32>) -> u32 {
    let Some(k) = grid else { return 0 };
    if level == 0 {
        return 0;
    }
    let k = k.min(crate::payload::MAX_SHIFT);
    let extent = (0..3).map(|a| header.bbox_max[a] - header.bbox_min[a]).fold(0f32, f32::max) as f64;
    let step = header.quantization.step as f64;
    let cap = (level_exponent(&header.level_sizes, level) + k).min(crate::payload::MAX_SHIFT);
    // The grid must stay well under the level's own simplification error, which on a smooth
    // surface falls as the inverse of its node count: at most twice the extent over the node
    // count. The horse's default levels, 12-bit or not, keep their grids; on the 4x-subdivided
    // horse (16 times the vertices) grids sized by quanta alone dominated its coarse cuts' error.
    let nodes = header.level_sizes.get(level).copied().unwrap_or(1).max(1) as f64;
    let limit = (((1u64 << cap) as f64) * extent / 4096.0 * 1.01).min(2.0 * extent * 2f64.powi(k as i32) / nodes);
    let mut s = 0;
    while s < cap && ((1u64 << (s + 1)) as f64) * step <= limit {
        s += 1;
    }
    s
}

#[cfg(test)]
mod level_exponent_tests {
    use super::level_exponent;

    #[test]
    fn grids_follow_level_sizes_not_indices() {
        // The default horse levels (25% and 10% of the triangles, then 1/4): the index.
        let default = [8431, 2113, 847, 212, 53, 13];
        assert_eq!((0..6).map(|j| level_exponent(&default, j)).collect::<Vec<_>>(), [0, 1, 2, 3, 4, 5]);
        // A level at 50% and branching 2: one grid step per two levels.
        let fine = [8431, 4220, 2113, 847, 424, 212, 106];
        assert_eq!((0..7).map(|j| level_exponent(&fine, j)).collect::<Vec<_>>(), [0, 1, 1, 2, 2, 3, 3]);
        // The new default levels (25%, 10%, 5%, 2.5%, 1.2%): one grid step per 4x in size.
        let anchored = [8431, 2113, 847, 425, 213, 104, 26];
        assert_eq!((0..7).map(|j| level_exponent(&anchored, j)).collect::<Vec<_>>(), [0, 1, 2, 2, 3, 3, 4]);
        // No sizes: the index.
        assert_eq!(level_exponent(&[], 3), 3);
    }
}
