//! Prediction of quantized node positions, shared by encoder and decoder (proto/container.md,
//! "Positions, band j"). All arithmetic is on integers: 64-bit sums and a floor division for
//! the neighbour means, 32-bit wrapping for the rest, so any decoder reproduces it exactly.

use crate::format::Header;

/// For each input vertex, its *lower neighbours*: the distinct vertices u < v that share an
/// input triangle with it, in compressed rows. Within level 0 they are decoded before v.
#[derive(Clone, Debug, Default)]
pub struct LowerNeighbours {
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl LowerNeighbours {
    pub fn new(n: usize, triangles: &[[u32; 3]]) -> Self {
        let pairs = || {
            triangles
                .iter()
                .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
                .filter(move |&(a, b)| a != b && (a as usize) < n && (b as usize) < n)
        };
        let mut offsets = vec![0u32; n + 1];
        for (a, b) in pairs() {
            offsets[a.max(b) as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut items = vec![0u32; offsets[n] as usize];
        for (a, b) in pairs() {
            let (hi, lo) = (a.max(b) as usize, a.min(b));
            items[fill[hi] as usize] = lo;
            fill[hi] += 1;
        }
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
        LowerNeighbours { offsets: out, items }
    }

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

/// The prediction of node `v` (global id `g`) of band `j`. `parent` is its parent as (global
/// id, local id at level j+1) in the current frame's hierarchy (None for the top band),
/// `lower` the level-0 lower neighbours (used for band 0 only), `siblings` the motion of the
/// band's decoded nodes (inter frames), `intra` for keyframes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn predict(
    j: usize,
    v: usize,
    g: usize,
    parent: Option<(usize, usize)>,
    lower: &LowerNeighbours,
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
            (true, None) => {
                if v > 0 {
                    cur[g - 1][a]
                } else {
                    0
                }
            }
            (false, Some(p)) => prev[g][a].wrapping_add(cur[p][a].wrapping_sub(prev[p][a])),
            (false, None) => prev[g][a],
        };
    }
    out
}

/// The residual step (as a power of two of the quantum) the encoder uses for band `level`
/// given [`crate::EncodeOptions::coarse_grid`]. Input vertices, which the error bound applies
/// to, always get 0; with `None` (the default) so do coarser nodes. With `Some(k)` band j >= 1
/// is stored on a grid of `2^s` quanta, `s = j + k` at most, and `2^s` quanta at most
/// `2^(j + k) / 4096` of the bounding box's largest extent (so 12-bit quantization gets
/// `s = j + k`, coarser quantization smaller steps). Coarse nodes approximate many vertices,
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
    let cap = (level as u32 + k).min(crate::payload::MAX_SHIFT);
    let limit = ((1u64 << cap) as f64) * extent / 4096.0 * 1.01;
    let mut s = 0;
    while s < cap && ((1u64 << (s + 1)) as f64) * step <= limit {
        s += 1;
    }
    s
}
