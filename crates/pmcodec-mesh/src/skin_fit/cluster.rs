//! The first bones: vertices clustered by their motion, one rigid bone per cluster. Seeds by
//! farthest-point sampling of vertex trajectories, then Lloyd iterations in which every cluster
//! gets its per-frame rigid transform (Horn) and every vertex moves to the bone whose
//! transforms reproduce its trajectory best: the motion-based clustering that MPEG-4 FAMC
//! segments an animation with (Mamou, Zaharia and Prêteux, "FAMC: the MPEG-4 standard for
//! animated mesh compression", 2008) and that Le and Deng initialise SSDR with ("Smooth
//! Skinning Decomposition with Rigid Bones", 2012, section 4.2), including their reseeding of
//! an empty bone at the vertex reconstructed worst.

use super::horn::{Rigid, fit_rigid};
use glam::{DVec3, Vec3};

/// Frames the clustering looks at: all of them up to `cap`, else `cap` evenly spaced ones
/// (frame 0 always), which bounds the cost of a long sequence.
pub fn sample_frames(frames: usize, cap: usize) -> Vec<usize> {
    if frames <= cap {
        return (0..frames).collect();
    }
    let mut out: Vec<usize> = (0..cap).map(|i| i * (frames - 1) / (cap - 1).max(1)).collect();
    out.dedup();
    out
}

/// Bones a vertex is compared with at most, in the clustering and the choice of candidates:
/// those whose vertices' rest centroid is nearest its rest position. A bone far away in the
/// rest pose rarely follows a vertex better than a near one, and comparing every vertex with
/// every bone would make the cost grow with the square of the bone count.
pub const NEAR_BONES: usize = 24;

/// For every vertex, the (at most [`NEAR_BONES`]) bones whose members' rest centroid is
/// nearest its rest position, nearest first; `labels` gives each vertex's (main) bone, and a
/// bone without vertices is never near.
pub fn near_bones(rest: &[DVec3], labels: &[u32], bones: usize) -> Vec<Vec<u32>> {
    let mut sum = vec![(DVec3::ZERO, 0usize); bones];
    for (p, &b) in rest.iter().zip(labels) {
        if let Some(s) = sum.get_mut(b as usize) {
            s.0 += *p;
            s.1 += 1;
        }
    }
    let centroids: Vec<(u32, DVec3)> = sum.iter().enumerate().filter(|(_, s)| s.1 > 0).map(|(b, s)| (b as u32, s.0 / s.1 as f64)).collect();
    let mut scored: Vec<(f64, u32)> = Vec::with_capacity(centroids.len());
    rest.iter()
        .map(|p| {
            scored.clear();
            scored.extend(centroids.iter().map(|&(b, c)| (c.distance_squared(*p), b)));
            let m = NEAR_BONES.min(scored.len());
            if m < scored.len() {
                scored.select_nth_unstable_by(m, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            }
            let mut near = scored[..m].to_vec();
            near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            near.into_iter().map(|s| s.1).collect()
        })
        .collect()
}

/// One bone label per vertex and the bones' transforms per frame (`transforms[f * bones + b]`,
/// frame 0 the identity: the rest pose is frame 0).
pub struct Clusters {
    pub labels: Vec<u32>,
    pub transforms: Vec<Rigid>,
}

/// Clusters the `rest` vertices of `frames` into `bones` rigid bones (`bones` at most the
/// vertex count, at least 1).
pub fn cluster(rest: &[DVec3], frames: &[Vec<Vec3>], bones: usize, iterations: u32, sample: &[usize]) -> Clusters {
    let n = rest.len();
    let at = |f: usize, v: usize| frames[f][v].as_dvec3();
    // Trajectory distance over the sampled frames.
    let dist = |u: usize, v: usize| -> f64 { sample.iter().map(|&f| at(f, u).distance_squared(at(f, v))).sum() };
    // First seed: the vertex farthest from the mean trajectory, so that the seeding does not
    // depend on the input's vertex numbering more than ties require.
    let mean: Vec<DVec3> = sample.iter().map(|&f| frames[f].iter().map(|p| p.as_dvec3()).sum::<DVec3>() / n as f64).collect();
    let mut first = 0;
    let mut far = -1.0;
    for v in 0..n {
        let d: f64 = sample.iter().zip(&mean).map(|(&f, m)| at(f, v).distance_squared(*m)).sum();
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
    let frame_count = frames.len();
    let mut transforms = vec![Rigid::IDENTITY; frame_count * bones];
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
        for b in 0..bones {
            if members[b].is_empty() && it > 0 {
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
        // The final pass fits every frame; earlier ones only the sampled frames they compare.
        let fit_frames: Vec<usize> =
            if it == iterations { (1..frame_count).collect() } else { sample.iter().copied().filter(|&f| f > 0).collect() };
        for &f in &fit_frames {
            for (b, m) in members.iter().enumerate() {
                transforms[f * bones + b] = fit_rigid(m.iter().map(|&v| (rest[v], at(f, v), 1.0)));
            }
        }
        if it == iterations {
            break;
        }
        // Every vertex to the bone that reproduces its sampled trajectory best, among its own
        // and the bones near it.
        let near = near_bones(rest, &labels, bones);
        for v in 0..n {
            let mut best = (f64::INFINITY, labels[v]);
            for b in std::iter::once(labels[v] as usize).chain(near[v].iter().map(|&b| b as usize)) {
                let mut e = 0.0;
                for &f in sample {
                    e += transforms[f * bones + b].apply(rest[v]).distance_squared(at(f, v));
                    if e >= best.0 {
                        break;
                    }
                }
                if e < best.0 {
                    best = (e, b as u32);
                }
            }
            labels[v] = best.1;
            error[v] = best.0;
        }
    }
    Clusters { labels, transforms }
}
