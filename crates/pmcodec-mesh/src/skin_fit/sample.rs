//! What the fit looks at: a subsample of the vertices and of the frames, copied into flat
//! arrays. Le and Deng fit every vertex in every frame ("Smooth Skinning Decomposition with
//! Rigid Bones", 2012); a bone's rigid transform is determined by far fewer points than a
//! dense mesh gives it, so the bones (and the choice of their count) are fitted on a spatially
//! even subsample of the vertices, and only the last weight step visits every vertex. The
//! choice of the bone count is measured on other vertices than the bones were fitted to
//! (held out), so that more bones do not look better merely by fitting their own samples.

use glam::{DVec3, Vec3};

/// Positions of some vertices (`rest`, their frame-0 positions) in some frames (`frames`,
/// numbers in the sequence), flat: `pos[fi * len + i]`. Transforms fitted on a `Data` are
/// indexed by the position `fi` of their frame in `frames`.
pub struct Data {
    pub rest: Vec<DVec3>,
    pub frames: Vec<usize>,
    pub pos: Vec<DVec3>,
}

impl Data {
    /// The `vertices` (all when `None`) of `seq_frames` in `frames`.
    pub fn new(seq_frames: &[Vec<Vec3>], vertices: Option<&[usize]>, frames: Vec<usize>) -> Data {
        let pick = |frame: &[Vec3]| -> Vec<DVec3> {
            match vertices {
                Some(ids) => ids.iter().map(|&v| frame[v].as_dvec3()).collect(),
                None => frame.iter().map(|p| p.as_dvec3()).collect(),
            }
        };
        let rest = pick(&seq_frames[0]);
        let mut pos = Vec::with_capacity(rest.len() * frames.len());
        for &f in &frames {
            pos.extend(pick(&seq_frames[f]));
        }
        Data { rest, frames, pos }
    }

    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// Vertex `i` in the `fi`-th frame of this data.
    #[inline]
    pub fn at(&self, fi: usize, i: usize) -> DVec3 {
        self.pos[fi * self.rest.len() + i]
    }

    /// Whether the `fi`-th frame is the rest pose (frame 0, where every bone is the identity).
    #[inline]
    pub fn is_rest(&self, fi: usize) -> bool {
        self.frames[fi] == 0
    }
}

/// Frames the search for bones compares: all of them up to `cap`, else `cap / 2` evenly spaced
/// pairs of consecutive frames (frame 0 and 1 first). Pairs, because the container codes a
/// residual's change from one frame to the next, which the choice of the bone count estimates
/// from the pairs.
pub fn frame_pairs(frames: usize, cap: usize) -> Vec<usize> {
    if frames <= cap.max(2) {
        return (0..frames).collect();
    }
    let pairs = (cap / 2).max(1);
    let mut out = Vec::with_capacity(2 * pairs);
    for j in 0..pairs {
        let start = if pairs == 1 { 0 } else { j * (frames - 2) / (pairs - 1) };
        out.extend([start, start + 1]);
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// Vertices in the order of a Morton (Z-order) curve through their rest positions (10 bits
/// per axis over the bounding box), ties by index: neighbours on the curve are neighbours in
/// space, so every `k`-th vertex of it is a spatially even subsample.
fn morton_order(rest: &[Vec3]) -> Vec<usize> {
    let Some((lo, hi)) = crate::bounds_of(rest) else {
        return Vec::new();
    };
    let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
    let spread = |x: u32| -> u64 {
        let mut out = 0u64;
        for b in 0..10 {
            out |= (((x >> b) & 1) as u64) << (3 * b);
        }
        out
    };
    let mut keyed: Vec<(u64, usize)> = rest
        .iter()
        .enumerate()
        .map(|(v, p)| {
            let q = ((*p - lo) / extent * 1023.0).round().clamp(Vec3::ZERO, Vec3::splat(1023.0));
            (spread(q.x as u32) | spread(q.y as u32) << 1 | spread(q.z as u32) << 2, v)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|k| k.1).collect()
}

/// Held-out vertices the choice of the bone count is measured on, at most.
pub const HELD_OUT: usize = 1024;

/// `fit` vertices, evenly along the Morton curve (all of them when `fit` is at least the
/// count), and up to [`HELD_OUT`] other vertices between them (the fit vertices themselves
/// when there are no others).
pub fn vertex_samples(rest: &[Vec3], fit: usize) -> (Vec<usize>, Vec<usize>) {
    let n = rest.len();
    if fit >= n {
        let all: Vec<usize> = (0..n).collect();
        return (all.clone(), all);
    }
    let order = morton_order(rest);
    let mut taken = vec![false; n];
    let mut fit_ids = Vec::with_capacity(fit);
    for j in 0..fit {
        let v = order[j * n / fit];
        taken[v] = true;
        fit_ids.push(v);
    }
    let held = HELD_OUT.min(n - fit);
    let mut held_ids = Vec::with_capacity(held);
    for j in 0..held {
        let mut p = (j * n / held + n / (2 * held)).min(n - 1);
        // The next vertex along the curve that is not taken (there are n - fit of them).
        while taken[order[p]] {
            p = (p + 1) % n;
        }
        taken[order[p]] = true;
        held_ids.push(order[p]);
    }
    (fit_ids, held_ids)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_are_consecutive_and_start_at_zero() {
        assert_eq!(frame_pairs(5, 16), vec![0, 1, 2, 3, 4]);
        let p = frame_pairs(100, 16);
        assert_eq!(p.len(), 16);
        assert_eq!(&p[..2], &[0, 1]);
        assert_eq!(*p.last().unwrap_or(&0), 99);
        for pair in p.chunks(2) {
            assert_eq!(pair[1], pair[0] + 1);
        }
    }

    #[test]
    fn samples_are_distinct_and_disjoint() {
        let rest: Vec<Vec3> = (0..1000).map(|i| Vec3::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32)).collect();
        let (fit, held) = vertex_samples(&rest, 300);
        assert_eq!(fit.len(), 300);
        assert_eq!(held.len(), 700.min(HELD_OUT));
        let mut seen = vec![false; 1000];
        for &v in fit.iter().chain(&held) {
            assert!(!seen[v], "vertex {v} twice");
            seen[v] = true;
        }
        // Spatially even: each octant of the 10x10x10 grid (125 vertices) holds about 300/8.
        let mut blocks = vec![0; 8];
        for &v in &fit {
            let p = rest[v];
            blocks[(p.x as usize / 5) + 2 * (p.y as usize / 5) + 4 * (p.z as usize / 5)] += 1;
        }
        assert!(blocks.iter().all(|&c| (30..=45).contains(&c)), "{blocks:?}");
    }
}
