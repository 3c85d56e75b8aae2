//! A level of detail of the skeleton: the palette entries a coarse level's nodes may be skinned
//! by.
//!
//! Why: a coarse node takes the summed influences of its cluster's vertices, so a node of the
//! coarsest levels, whose cluster spans a limb, uses every joint of that limb, and the top
//! bands' Joints chunks (read by every client) carried nearly the whole palette every frame
//! (RobotExpressive: 86 KB of joints, all read by a client at 10% of the triangles; the fitted
//! horse's 256 bones, 1.9 KB a frame). Houle and Poulin ("Simplification and real-time smooth
//! transitions of articulated meshes", 2001) simplify the skeleton with the mesh: bones whose
//! detail a level cannot show are merged, and coarse vertices follow the merged bones.
//!
//! Here, level by level from the finest, the kept entry whose merge into another kept entry
//! moves the level's nodes least is merged into it, as long as that move stays within a
//! fraction `tolerance` of the level's mean cluster radius (the size of a node's neighbourhood,
//! which grows as the level coarsens, so coarser levels merge more). The move of merging entry
//! e into k is the RMS distance between where the two carry e's points over the sequence
//! (weighted by e's weights), times the mean weight a node of the level has on e: a small joint
//! that moves much (a jaw, a tail tip) stays longer than a large one that moves like its
//! neighbour. Any kept entry may take a merged one, so skins without a hierarchy (a fitted skin's
//! flat bones) merge a bone into the bone that moves most like it, and a glTF skeleton mostly
//! into a parent or a neighbour on the same limb. (A first version kept a joint while its
//! coverage, its weight in nodes' worth, reached one node, whatever its motion: on Fox a client
//! at 10% of the triangles read about as much, 64.4% of a full client's bytes against 62.5%, but
//! the criterion ignores how far a merge moves anything.)
//!
//! Kept sets nest (an entry merged at a level stays merged above it, except as
//! [`fold_small_bands`] says), so the Joints chunks' band split (proto/container.md, "Joints")
//! carries the merged entries in the finer bands automatically, and a coarse client reads only
//! the entries its levels keep. Nothing here changes the format: the coarse nodes' influences
//! in the Bind chunks are fewer joints, and each coarse node is still placed at its skinned
//! prediction under them where its cluster's quadric allows ([`super::CoarseQuadrics`]), so
//! its positions stay near zero where the merged joints move it little, and it is stored near
//! its quadric-optimal point (at the cost of position bytes, not error) where they do not.

use glam::{DVec3, Vec3};
use pmcodec_mesh::SequenceSkin;

/// Frames sampled (evenly over the sequence) to compare entries' transforms: enough to see
/// every motion of an animation clip, few enough to keep the comparison of every pair of
/// entries cheap (256 fitted bones: 65,536 pairs).
const SAMPLED_FRAMES: usize = 32;

/// Skins whose vertices use more palette entries than this keep every entry at every level: the
/// comparison of every pair and the greedy merging grow as the square and the cube of the
/// count (a fitted skin has at most 256 bones).
const MAX_MERGED: usize = 512;

/// For each level of a hierarchy (`ancestors[j][v]`: vertex v's level-j node; `sizes[j]`: node
/// counts; `rest_world`: the vertices' frame-0 positions), the entry each palette entry stands
/// for there: itself where kept, else the kept entry that replaces it. Level 0 keeps every
/// entry; `tolerance <= 0` keeps every entry at every level.
///
/// At each level, greedily, the kept entry (with the entries merged into it so far) whose merge
/// into another kept entry moves the level's nodes least is merged, while that move stays
/// within `tolerance` times the level's mean cluster radius: a node's move is the sum over the
/// merged entries of its weight on each times the RMS distance between where the two entries
/// carry that entry's points over the sequence, averaged over the nodes that use them.
pub(crate) fn skeleton_levels(
    skin: &SequenceSkin,
    ancestors: &[Vec<u32>],
    sizes: &[u32],
    rest_world: &[Vec3],
    tolerance: f64,
) -> Vec<Vec<u32>> {
    let n = skin.palette_len as usize;
    let identity: Vec<u32> = (0..n as u32).collect();
    let mut out = vec![identity.clone(); ancestors.len()];
    if tolerance.is_nan() || tolerance <= 0.0 || n < 2 {
        return out;
    }
    // Only the entries some vertex uses take part (a glTF palette also lists joints and nodes
    // that move no vertex: RobotExpressive uses 36 of its 98), at most MAX_MERGED of them.
    let (moment, weight) = moments(skin);
    let used: Vec<usize> = (0..n).filter(|&e| weight[e] > 0.0).collect();
    let m = used.len();
    if !(2..=MAX_MERGED).contains(&m) {
        return out;
    }
    let frames = sampled_frames(skin);
    // apart[a * m + b]: the RMS distance between where used[a]'s points go under it and under
    // used[b] over the sampled frames.
    let mut apart_rms = vec![0.0f64; m * m];
    for (a, &e) in used.iter().enumerate() {
        let total = (weight[e] * frames.len() as f64).max(1e-300);
        for (b, &k) in used.iter().enumerate() {
            apart_rms[a * m + b] = (apart(&frames, e, k, &moment[e]).max(0.0) / total).sqrt();
        }
    }
    let distance = |a: usize, b: usize| apart_rms[a * m + b];
    // groups[a]: the used entries (by index in `used`) used[a] stands for (a itself while kept;
    // empty once merged).
    let mut groups: Vec<Vec<usize>> = (0..m).map(|a| vec![a]).collect();
    for (j, anc) in ancestors.iter().enumerate().skip(1) {
        let size = sizes.get(j).copied().unwrap_or(0) as usize;
        let (influence, users) = level_influence(skin, anc, size);
        let limit = tolerance * mean_radius(anc, size, rest_world);
        loop {
            let kept: Vec<usize> = (0..m).filter(|&a| !groups[a].is_empty()).collect();
            // The cheapest merge: (move, group, into).
            let mut best: Option<(f64, usize, usize)> = None;
            for &a in &kept {
                let g = &groups[a];
                let nodes = g.iter().map(|&x| users[used[x]]).max().unwrap_or(0);
                for &b in kept.iter().filter(|&&b| b != a) {
                    let moved: f64 =
                        if nodes == 0 { 0.0 } else { g.iter().map(|&x| influence[used[x]] * distance(x, b)).sum::<f64>() / nodes as f64 };
                    if best.is_none_or(|best| moved < best.0) {
                        best = Some((moved, a, b));
                    }
                }
            }
            let Some((_, a, b)) = best.filter(|best| best.0 <= limit) else { break };
            let g = std::mem::take(&mut groups[a]);
            groups[b].extend(g);
        }
        for (b, g) in groups.iter().enumerate() {
            for &x in g {
                out[j][used[x]] = used[b] as u32;
            }
        }
    }
    fold_small_bands(&mut out, &weight);
    out
}

/// A band whose Joints chunks would carry fewer entries than this keeps them at the level above
/// instead. Why: a band's chunk costs about a dozen bytes a frame whatever it carries (its
/// index entry, band mask and Exp-Golomb orders: proto/container.md, "Joints"), more than the
/// one or two entries cost the clients above it (RobotExpressive: 4 to 8 bytes an entry a
/// frame).
const MIN_CARRIED: usize = 3;

/// Band j carries (about: a coarse node keeps only its four strongest influences) the entries
/// level j keeps and level j + 1 merges; where those are 1 or 2, level j + 1 keeps them too,
/// standing for what they stand for at level j, so they move up a band (and on up while the
/// band above would carry few).
fn fold_small_bands(out: &mut [Vec<u32>], weight: &[f64]) {
    for j in 0..out.len().saturating_sub(1) {
        let mut targets: Vec<u32> =
            out[j].iter().enumerate().filter(|&(x, _)| weight.get(x).is_some_and(|&w| w > 0.0)).map(|(_, &e)| e).collect();
        targets.sort_unstable();
        targets.dedup();
        let dropped: Vec<u32> = targets.into_iter().filter(|&e| out[j + 1][e as usize] != e).collect();
        if dropped.is_empty() || dropped.len() >= MIN_CARRIED {
            continue;
        }
        let (below, above) = out.split_at_mut(j + 1);
        for (x, &e) in below[j].iter().enumerate() {
            if dropped.contains(&e) {
                above[0][x] = e;
            }
        }
    }
}

/// The mean over a level's clusters of the RMS distance of their vertices from their centroid.
fn mean_radius(ancestors: &[u32], size: usize, rest_world: &[Vec3]) -> f64 {
    let mut sums = vec![(DVec3::ZERO, 0.0f64, 0u32); size];
    for (&a, p) in ancestors.iter().zip(rest_world) {
        let Some(s) = sums.get_mut(a as usize) else { continue };
        let p = p.as_dvec3();
        s.0 += p;
        s.1 += p.length_squared();
        s.2 += 1;
    }
    let radii: Vec<f64> =
        sums.iter().filter(|s| s.2 > 0).map(|s| (s.1 / s.2 as f64 - (s.0 / s.2 as f64).length_squared()).max(0.0).sqrt()).collect();
    if radii.is_empty() { 0.0 } else { radii.iter().sum::<f64>() / radii.len() as f64 }
}

/// Each entry's influence at a level of `size` nodes, the sum over the level's clusters of the
/// entry's mean weight on the cluster's vertices (in nodes' worth), and how many of the level's
/// nodes it has a weight in.
fn level_influence(skin: &SequenceSkin, ancestors: &[u32], size: usize) -> (Vec<f64>, Vec<u32>) {
    let mut count = vec![0u32; size];
    for &a in ancestors {
        if let Some(c) = count.get_mut(a as usize) {
            *c += 1;
        }
    }
    let n = skin.palette_len as usize;
    let mut out = vec![0.0f64; n];
    // Per entry, the last node counted (nodes are visited in any order, so a set per entry).
    let mut seen = vec![std::collections::BTreeSet::new(); n];
    for (v, &a) in ancestors.iter().enumerate() {
        let (Some(js), Some(ws), Some(&c)) = (skin.joints.get(v), skin.weights.get(v), count.get(a as usize)) else { continue };
        for (&e, &w) in js.iter().zip(ws) {
            if let Some(slot) = out.get_mut(e as usize).filter(|_| w > 0.0 && w.is_finite()) {
                *slot += w as f64 / c.max(1) as f64;
                seen[e as usize].insert(a);
            }
        }
    }
    (out, seen.iter().map(|s| s.len() as u32).collect())
}

/// Each entry's weighted second moment of the homogeneous rest positions of its vertices
/// (row-major 4x4; its last value is the entry's total weight) and that total weight.
fn moments(skin: &SequenceSkin) -> (Vec<[f64; 16]>, Vec<f64>) {
    let n = skin.palette_len as usize;
    let mut moment = vec![[0.0f64; 16]; n];
    for (v, &r) in skin.rest.iter().enumerate() {
        let (Some(js), Some(ws)) = (skin.joints.get(v), skin.weights.get(v)) else { continue };
        for (&e, &w) in js.iter().zip(ws) {
            if let Some(s) = moment.get_mut(e as usize).filter(|_| w > 0.0 && w.is_finite()) {
                add_moment(s, r, w as f64);
            }
        }
    }
    let weight = moment.iter().map(|s| s[15]).collect();
    (moment, weight)
}

/// The frames whose transforms are compared, evenly over the sequence.
pub(crate) fn sampled_frames(skin: &SequenceSkin) -> Vec<&[[f32; 12]]> {
    let frames = skin.matrices.len();
    let count = SAMPLED_FRAMES.min(frames);
    (0..count).filter_map(|i| skin.matrices.get(i * frames / count).map(Vec::as_slice)).collect()
}

/// `sum_f tr(D_f S D_f^T)`: how far entry k's transforms carry points of weighted second moment
/// `s` (homogeneous, row-major 4x4) from where entry e's carry them, squared, over `frames`.
fn apart(frames: &[&[[f32; 12]]], e: usize, k: usize, s: &[f64; 16]) -> f64 {
    let mut sum = 0.0;
    for ms in frames {
        let (Some(me), Some(mk)) = (ms.get(e), ms.get(k)) else { continue };
        for a in 0..3 {
            let d: [f64; 4] = std::array::from_fn(|c| me[4 * a + c] as f64 - mk[4 * a + c] as f64);
            for x in 0..4 {
                let row: f64 = (0..4).map(|y| s[4 * x + y] * d[y]).sum();
                sum += d[x] * row;
            }
        }
    }
    sum
}

/// Adds weight `w` at rest point `p` to the second moment `s`.
pub(crate) fn add_moment(s: &mut [f64; 16], p: Vec3, w: f64) {
    let p = [p.x as f64, p.y as f64, p.z as f64, 1.0];
    for a in 0..4 {
        for b in 0..4 {
            s[4 * a + b] += w * p[a] * p[b];
        }
    }
}

/// For one coarse node: of `candidates` (entries its level keeps), the one whose transforms
/// carry the node's points that entry `e` moves (second moment `s`) nearest to where `e`
/// carries them; ties to the first. Why per node: the level's merge target of `e` is the best
/// over all of `e`'s points, and a node at one end of `e`'s region may follow another kept
/// entry more closely (a thigh bone's top with the hip, its bottom with the shin).
/// `frames`: [`sampled_frames`].
pub(crate) fn nearest(frames: &[&[[f32; 12]]], e: u32, s: &[f64; 16], candidates: &[u32]) -> Option<u32> {
    candidates.iter().map(|&k| (apart(frames, e as usize, k as usize, s), k)).min_by(|a, b| a.0.total_cmp(&b.0)).map(|(_, k)| k)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 32 vertices on a line, two halves. Entry 0 moves the first half along x, entry 1 the
    /// second along y; the last 12 vertices of each half also take a tenth of a minor entry's
    /// weight (entries 2..=4 and 5..=7, four vertices each), which moves like its half's major
    /// entry at 1.1, 1.25 and 0.8 times its speed.
    fn skin() -> SequenceSkin {
        let mut s = SequenceSkin { palette_len: 8, ..Default::default() };
        for v in 0..32u32 {
            s.rest.push(Vec3::new(v as f32, 0.0, 0.0));
            let (half, k) = (v / 16, v % 16);
            if k < 4 {
                s.joints.push([half, 0, 0, 0]);
                s.weights.push([1.0, 0.0, 0.0, 0.0]);
            } else {
                s.joints.push([half, 2 + 3 * half + (k - 4) / 4, 0, 0]);
                s.weights.push([0.9, 0.1, 0.0, 0.0]);
            }
        }
        let shift = |x: f32, y: f32| [1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, y, 0.0, 0.0, 1.0, 0.0];
        for f in 0..8 {
            let t = f as f32;
            let mut ms = vec![shift(t, 0.0), shift(0.0, t)];
            ms.extend([1.1, 1.25, 0.8].map(|a| shift(a * t, 0.0)));
            ms.extend([1.1, 1.25, 0.8].map(|a| shift(0.0, a * t)));
            s.matrices.push(ms);
        }
        s
    }

    #[test]
    fn entries_merge_into_the_entry_moving_most_like_them_as_levels_coarsen() {
        let s = skin();
        let rest = s.rest.clone();
        // Level 1: pairs of vertices (cluster radius 0.5); level 2: the two halves (4.61).
        let ancestors = vec![(0..32).collect::<Vec<u32>>(), (0..32).map(|v| v / 2).collect(), (0..32).map(|v| v / 16).collect()];
        let sizes = [32, 16, 2];
        let identity: Vec<u32> = (0..8).collect();
        // A quarter of the radius: every minor entry goes to its half's major one at level 1.
        let levels = skeleton_levels(&s, &ancestors, &sizes, &rest, 0.25);
        assert_eq!(levels[0], identity);
        assert_eq!(levels[1], [0, 1, 0, 0, 0, 1, 1, 1]);
        assert_eq!(levels[2], [0, 1, 0, 0, 0, 1, 1, 1]);
        // A tenth: at level 1 only the entries at 1.1 times their major's speed go, which would
        // leave band 0 two entries to carry: level 1 keeps them too; the halves take them all.
        let levels = skeleton_levels(&s, &ancestors, &sizes, &rest, 0.1);
        assert_eq!(levels[1], identity);
        assert_eq!(levels[2], [0, 1, 0, 0, 0, 1, 1, 1]);
        // An entry no vertex uses stands for itself at every level.
        let mut unused = s.clone();
        unused.palette_len = 9;
        let levels = skeleton_levels(&unused, &ancestors, &sizes, &rest, 0.25);
        assert_eq!(levels[2], [0, 1, 0, 0, 0, 1, 1, 1, 8]);
        // Without a bound one entry stands for all; 0 keeps every entry.
        let levels = skeleton_levels(&s, &ancestors, &sizes, &rest, 100.0);
        assert!(levels[1].iter().all(|&k| k == levels[1][0]), "{:?}", levels[1]);
        assert!(skeleton_levels(&s, &ancestors, &sizes, &rest, 0.0).iter().all(|l| *l == identity));
    }

    /// A node follows the kept entry that carries its own points best: entry 2 turns about
    /// (10, 0, 0), entry 0 turns the same way about the origin, entry 1 holds still. Near the
    /// pivot entry 2 moves nothing (entry 1 is nearer); at (-10, 0, 0) it moves twice as far
    /// from entry 1 as from entry 0.
    #[test]
    fn a_node_takes_the_entry_that_carries_its_own_points_nearest() {
        let turn = |angle: f32, pivot: f32| {
            let (s, c) = angle.sin_cos();
            // x' = R (x - p) + p, p = (pivot, 0, 0).
            [c, -s, 0.0, pivot - c * pivot, s, c, 0.0, -s * pivot, 0.0, 0.0, 1.0, 0.0]
        };
        let still = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let matrices: Vec<Vec<[f32; 12]>> = (0..8).map(|f| vec![turn(0.1 * f as f32, 0.0), still, turn(0.1 * f as f32, 10.0)]).collect();
        let s = SequenceSkin { palette_len: 3, matrices, ..Default::default() };
        let frames = sampled_frames(&s);
        let moment = |x: f32| {
            let mut m = [0.0; 16];
            add_moment(&mut m, Vec3::new(x, 0.0, 0.0), 1.0);
            add_moment(&mut m, Vec3::new(x, 1.0, 0.0), 1.0);
            m
        };
        assert_eq!(nearest(&frames, 2, &moment(10.0), &[0, 1]), Some(1));
        assert_eq!(nearest(&frames, 2, &moment(-10.0), &[0, 1]), Some(0));
        assert_eq!(nearest(&frames, 2, &moment(-10.0), &[]), None);
    }
}
