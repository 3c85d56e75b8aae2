//! The split order on real sequences: budget and error cuts are prefixes that are maximal for
//! their target, closed upward, and show exactly the mesh the replay shows for the same cut.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::*;
use glam::Vec3;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::progressive::{Encoder, Replay};
use pmcodec_hierarchy::split_order::{SplitOrder, Steps};
use pmcodec_hierarchy::*;
use pmcodec_hierarchy::{CutTarget, Distance};
use pmcodec_mesh::TriMesh;

/// A mesh as a sorted list of triangles, each its three corner positions (bit patterns)
/// rotated so the smallest comes first (orientation kept): equal iff the same triangles.
fn canonical(m: &TriMesh) -> Vec<[[u32; 3]; 3]> {
    let key = |p: Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let mut out: Vec<[[u32; 3]; 3]> = m
        .triangles
        .iter()
        .map(|t| {
            let c = t.map(|i| key(m.positions[i as usize]));
            let r = (0..3).min_by_key(|&i| c[i]).unwrap_or(0);
            [c[r], c[(r + 1) % 3], c[(r + 2) % 3]]
        })
        .collect();
    out.sort_unstable();
    out
}

/// Runs the encoder over `seq` and checks the split order of every `every`-th frame.
fn check_sequence(seq: &pmcodec_mesh::Sequence, every: usize, budgets: &[u32]) {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions::default()).expect("build");
    let mut enc = Encoder::new(h.clone(), topo, seq.triangles.clone(), Default::default());
    let mut replay = Replay::new(h, &seq.triangles);
    // One order reset frame after frame (as a player's decoder keeps it) must equal fresh ones.
    let mut reused = SplitOrder::default();
    for (f, frame) in seq.frames.iter().enumerate() {
        let (delta, _) = enc.encode_frame(frame);
        replay.apply(&delta).unwrap_or_else(|e| panic!("frame {f}: {e}"));
        if f % every != 0 {
            continue;
        }
        let positions: Vec<Vec3> = enc.node_positions().to_vec();
        let errors = replay.node_errors(&positions);
        let mut order = SplitOrder::new(&replay, &errors);
        for &n in budgets {
            let k = order.prefix(&replay, &errors, CutTarget::Triangles(n), 1.0).expect("a prefix");
            let shown = order.shown(k).len();
            // At most the budget, and the next split would break it (or there is none).
            assert!(shown as u32 <= n || k == 0, "frame {f} budget {n}: {shown} triangles after {k} splits");
            assert!(order.len() == k || order.shown(k + 1).len() as u32 > n, "frame {f} budget {n}: prefix {k} not maximal");
            // The same cut through the replay shows the same triangles and the same mesh.
            let expanded: Vec<bool> = (0..replay.h.node_count() as u32).map(|g| order.rank(g).is_some_and(|r| (r as usize) < k)).collect();
            for g in 0..expanded.len() as u32 {
                let p = replay.h.parent_global(g);
                assert!(!expanded[g as usize] || p == NONE || expanded[p as usize], "frame {f} budget {n}: not closed at {g}");
            }
            replay.set_cut(&expanded);
            let mut want = replay.shown().to_vec();
            want.sort_unstable();
            let mut got = order.shown(k).to_vec();
            got.sort_unstable();
            assert_eq!(got, want, "frame {f} budget {n}: shown triangles");
            let mesh = order.mesh(&replay, &positions, k);
            assert_eq!(mesh.triangles.len(), shown);
            assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < mesh.positions.len()));
            assert_eq!(canonical(&mesh), canonical(&replay.mesh(&positions).0), "frame {f} budget {n}: mesh");
        }
        // Error bounds: every split in the prefix is above the bound, the next is not.
        let diag = (seq.bounds().map(|(lo, hi)| (hi - lo).length()).unwrap_or(1.0)) as f64;
        for e in [0.05, 0.01, 0.002, 0.0] {
            let bound = e * diag;
            let k = order.prefix(&replay, &errors, CutTarget::MaxError(Distance::DiagonalFraction(e)), diag).expect("a prefix");
            let absolute = order.prefix(&replay, &errors, CutTarget::MaxError(Distance::Absolute(bound)), 1.0);
            assert_eq!(absolute, Ok(k), "frame {f} bound {bound}: the same bound in model units");
            assert_eq!(order.prefix(&replay, &errors, CutTarget::Level(1), diag), Err(1), "a level is no prefix");
            let mut all = SplitOrder::new(&replay, &errors);
            let full = all.prefix(&replay, &errors, CutTarget::Triangles(u32::MAX), 1.0).expect("a prefix");
            assert!(k <= full);
            for g in 0..replay.h.node_count() as u32 {
                if let Some(r) = all.rank(g) {
                    let p = errors[g as usize];
                    assert_eq!((r as usize) < k, p > bound, "frame {f} bound {bound}: node {g} priority {p} rank {r} prefix {k}");
                }
            }
        }
        // Vertex budgets count cut nodes.
        for n in [100, 1000, 4000] {
            let k = order.prefix(&replay, &errors, CutTarget::Vertices(n), 1.0).expect("a prefix");
            let mesh = order.mesh(&replay, &positions, k);
            assert!(mesh.positions.len() as u32 <= n, "frame {f}: {} vertices for a budget of {n}", mesh.positions.len());
        }
        // An order grown lazily by small requests gives what one grown at once gives, and so
        // does one reset from an earlier frame's.
        // `mesh_into` a buffer still holding the last, larger cut gives the same mesh.
        let mut fresh = SplitOrder::new(&replay, &errors);
        let mut buffer = TriMesh::default();
        for &n in budgets.iter().rev() {
            let a = fresh.prefix(&replay, &errors, CutTarget::Triangles(n), 1.0).expect("a prefix");
            let b = order.prefix(&replay, &errors, CutTarget::Triangles(n), 1.0).expect("a prefix");
            assert_eq!(a, b);
            fresh.mesh_into(&replay, &positions, a, &mut buffer);
            assert_eq!(buffer, order.mesh(&replay, &positions, b), "frame {f} budget {n}");
        }
        // (Small budgets first: a reset that left stale ranks would show in a short order.)
        reused.reset(&replay, &errors);
        for &n in budgets {
            let b = order.prefix(&replay, &errors, CutTarget::Triangles(n), 1.0).expect("a prefix");
            let c = reused.prefix(&replay, &errors, CutTarget::Triangles(n), 1.0).expect("a prefix");
            assert_eq!(c, b, "frame {f} budget {n}: reset order");
            assert_eq!(reused.mesh(&replay, &positions, c), order.mesh(&replay, &positions, b), "frame {f} budget {n}: reset order");
        }
        // Grow the reused order fully so the next reset has every rank to clear.
        reused.prefix(&replay, &errors, CutTarget::Triangles(u32::MAX), 1.0).expect("a prefix");
    }
}

#[test]
fn horse_gallop_budget_cuts_are_prefixes() {
    let seq = load("horse-gallop", 12);
    check_sequence(&seq, 5, &[0, 1, 50, 500, 1684, 2000, 8000, 16000, u32::MAX]);
}

#[test]
fn samba_budget_cuts_are_prefixes() {
    let seq = load("samba-60", 6);
    check_sequence(&seq, 5, &[20, 777, 5000, 19938]);
}

#[test]
fn generated_wave_budget_cuts_are_prefixes() {
    let seq = grid(30, 20, 6);
    check_sequence(&seq, 2, &[0, 3, 40, 300, 1000, 2000]);
}

/// Reveal priorities (budgets): monotone up the hierarchy, and the quadric error a reveal
/// removes over the square root of the cluster's area, square-rooted: scaling the surface by 4
/// scales split priorities (distances) by 4 and reveal priorities by sqrt(4^4 / 4) = 8 (powers
/// of two, so exactly up to rounding of the square roots). A priority without the area
/// factor, or with the area itself, scales by 16 or 4 and fails.
#[test]
fn budget_priorities_are_monotone_and_weigh_area() {
    let seq = grid(30, 20, 2);
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions::default()).expect("build");
    let mut enc = Encoder::new(h.clone(), topo, seq.triangles.clone(), Default::default());
    let mut replay = Replay::new(h, &seq.triangles);
    let (delta, _) = enc.encode_frame(&seq.frames[1]);
    replay.apply(&delta).expect("apply");
    let positions: Vec<Vec3> = enc.node_positions().to_vec();
    let mut benefits = Vec::new();
    replay.reveal_benefits_into(&positions, &mut benefits);
    let errors = replay.node_errors(&positions);
    let h = &replay.h;
    assert_eq!(benefits.len(), h.node_count());
    assert!(benefits[..h.level_sizes[0] as usize].iter().any(|&b| b > 0.0), "a bent grid's vertices are off their parents' positions");
    for g in 0..h.node_count() as u32 {
        let p = h.parent_global(g);
        assert!(p == NONE || benefits[p as usize] >= benefits[g as usize], "node {g}: parent {p} below it");
    }
    let scaled: Vec<Vec3> = positions.iter().map(|&p| p * 4.0).collect();
    let mut benefits4 = Vec::new();
    replay.reveal_benefits_into(&scaled, &mut benefits4);
    let errors4 = replay.node_errors(&scaled);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-300);
    for g in 0..h.node_count() {
        assert!(close(errors4[g], 4.0 * errors[g]), "node {g}: error {} -> {}", errors[g], errors4[g]);
        assert!(close(benefits4[g], 8.0 * benefits[g]), "node {g}: benefit {} -> {}", benefits[g], benefits4[g]);
    }
}

/// Each fine vertex's plane quadric (Garland & Heckbert: a third of each incident face's area
/// times its plane's squared distance), 10 coefficients then the area, as the decoder builds
/// them at level 0.
fn vertex_quadrics(positions: &[Vec3], triangles: &[[u32; 3]], n: usize) -> Vec<[f64; 11]> {
    let mut q = vec![[0f64; 11]; n];
    for t in triangles {
        let p = t.map(|v| positions[v as usize].as_dvec3());
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        let len = cross.length();
        if len <= 0.0 {
            continue;
        }
        let u = cross / len;
        let d = -u.dot(p[0]);
        let w = len / 6.0;
        let plane = [u.x * u.x, u.x * u.y, u.x * u.z, u.y * u.y, u.y * u.z, u.z * u.z, d * u.x, d * u.y, d * u.z, d * d, 1.0];
        for &v in t {
            for i in 0..11 {
                q[v as usize][i] += w * plane[i];
            }
        }
    }
    q
}

fn quadric_value(m: &[f64; 11], x: Vec3) -> f64 {
    let x = x.as_dvec3();
    let a = [m[0] * x.x + m[1] * x.y + m[2] * x.z, m[1] * x.x + m[3] * x.y + m[4] * x.z, m[2] * x.x + m[4] * x.y + m[5] * x.z];
    x.x * a[0] + x.y * a[1] + x.z * a[2] + 2.0 * (m[6] * x.x + m[7] * x.y + m[8] * x.z) + m[9]
}

/// RMS plane distance of the fine surface from a cut: every fine vertex's quadric at the
/// position of the cut node standing for it (what QEM charges the cut).
fn cut_rms(q: &[[f64; 11]], nodes: &[u32], positions: &[Vec3]) -> f64 {
    let (mut e, mut area) = (0.0, 0.0);
    for (m, &g) in q.iter().zip(nodes) {
        e += quadric_value(m, positions[g as usize]);
        area += m[10];
    }
    (e.max(0.0) / area).sqrt()
}

/// Partial splits (budgets) on a generated wave: every vertex budget gets exactly that many cut
/// nodes, each one revealed and drawn (a node at the finest level, or one with an unrevealed
/// child), the shown triangles are exactly those whose three corners stand for three distinct
/// cut nodes, and between two levels the cut has less surface error than whole splits (every
/// child of a split node at once, by the area-scaled RMS priorities that budgets split by before
/// partial splits) at the same vertex count. Whole splits add three vertices at a time on this
/// 4-ary hierarchy, so they cannot meet most budgets exactly.
#[test]
fn partial_splits_meet_vertex_budgets_exactly_and_beat_whole_splits_between_levels() {
    let (seq, replay, positions) = replayed_wave();
    let h = replay.h.clone();
    let fine = h.level_sizes[0] as usize;
    assert!(h.levels() >= 3, "{:?}", h.level_sizes);
    let mut benefits = Vec::new();
    replay.reveal_benefits_into(&positions, &mut benefits);
    for g in 0..h.node_count() as u32 {
        let p = h.parent_global(g);
        assert!(p == NONE || benefits[p as usize] >= benefits[g as usize], "node {g}: parent {p} below it");
    }
    let mut order = SplitOrder::default();
    order.reset_steps(&replay, &benefits, Steps::PartialSplits);
    let vq = vertex_quadrics(&positions[..fine], &seq.triangles, fine);
    let revealed = |o: &SplitOrder, g: u32, k: usize| h.local(g).0 == h.top() || o.rank(g).is_some_and(|r| (r as usize) < k);
    let top = h.level_sizes[h.top()];
    for n in (top..=h.level_sizes[0]).step_by(13).chain([h.level_sizes[1], h.level_sizes[1] + 1, h.level_sizes[0]]) {
        let k = order.prefix(&replay, &benefits, CutTarget::Vertices(n), 1.0).expect("a prefix");
        let nodes: Vec<u32> = (0..fine as u32).map(|v| order.cut_node_of(&replay, v, k)).collect();
        let mut cut = nodes.clone();
        cut.sort_unstable();
        cut.dedup();
        assert_eq!(cut.len() as u32, n, "budget {n}: {} cut nodes after {k} reveals", cut.len());
        for &g in &cut {
            assert!(revealed(&order, g, k), "budget {n}: cut node {g} is not revealed");
            let children = replay.children_of(g);
            assert!(
                h.local(g).0 == 0 || children.iter().any(|&c| !revealed(&order, c, k)),
                "budget {n}: cut node {g} has every child revealed"
            );
        }
        let mut shown = order.shown(k).to_vec();
        shown.sort_unstable();
        let want: Vec<u32> = (0..seq.triangles.len() as u32)
            .filter(|&t| {
                let c = seq.triangles[t as usize].map(|v| nodes[v as usize]);
                c[0] != c[1] && c[1] != c[2] && c[0] != c[2]
            })
            .collect();
        assert_eq!(shown, want, "budget {n}: shown triangles");
        let mesh = order.mesh(&replay, &positions, k);
        assert!(mesh.positions.len() as u32 <= n && mesh.triangles.len() == want.len(), "budget {n}");
    }
    // Between levels 1 and 2 (their geometric mean): whole splits by the area-scaled RMS.
    let mut cluster = vec![[0f64; 11]; h.node_count()];
    for (v, m) in vq.iter().enumerate() {
        let mut g = v as u32;
        while g != NONE {
            for i in 0..11 {
                cluster[g as usize][i] += m[i];
            }
            g = h.parent_global(g);
        }
    }
    let mut whole_priority: Vec<f64> = cluster
        .iter()
        .zip(&positions)
        .map(|(m, &x)| {
            let e = quadric_value(m, x);
            if m[10] > 0.0 && e > 0.0 { (e / m[10].sqrt()).sqrt() } else { 0.0 }
        })
        .collect();
    for k in 0..h.top() {
        for (v, &p) in h.parent[k].iter().enumerate() {
            let (c, a) = ((h.offsets[k] + v as u32) as usize, (h.offsets[k + 1] + p) as usize);
            whole_priority[a] = whole_priority[a].max(whole_priority[c]);
        }
    }
    let mut whole = SplitOrder::new(&replay, &whole_priority);
    for (coarse, finer) in [(2, 1), (1, 0)] {
        let n = ((h.level_sizes[coarse] as f64 * h.level_sizes[finer] as f64).sqrt()) as u32;
        let kp = order.prefix(&replay, &benefits, CutTarget::Vertices(n), 1.0).expect("a prefix");
        let kw = whole.prefix(&replay, &whole_priority, CutTarget::Vertices(n), 1.0).expect("a prefix");
        let partial: Vec<u32> = (0..fine as u32).map(|v| order.cut_node_of(&replay, v, kp)).collect();
        let all: Vec<u32> = (0..fine as u32).map(|v| whole.cut_node_of(&replay, v, kw)).collect();
        let (ep, ew) = (cut_rms(&vq, &partial, &positions), cut_rms(&vq, &all, &positions));
        eprintln!("budget {n} between levels {coarse} and {finer}: partial {ep:.3e}, whole {ew:.3e}");
        assert!(ep < ew, "budget {n} between levels {coarse} and {finer}: partial splits {ep} against whole splits {ew}");
    }
}

/// Level-major whole splits (the option [`Steps::LevelSplits`], issue #15): on a generated
/// wave, a vertex budget or a triangle budget at exactly a level's count is that level's cut
/// (every fine vertex stands for its ancestor at the level, and the shown triangles are the
/// level's), and a budget between two levels refines the coarser one (every cut node at the
/// coarser level or the finer one).
#[test]
fn level_major_budgets_at_a_level_are_that_level() {
    let (_, replay, positions) = replayed_wave();
    let h = replay.h.clone();
    let fine = h.level_sizes[0];
    assert!(h.levels() >= 4, "{:?}", h.level_sizes);
    let ancestor = |v: u32, level: usize| (0..level).fold(v, |x, k| h.parent[k][x as usize]) + h.offsets[level];
    let mut benefits = Vec::new();
    replay.split_benefits_into(&positions, &mut benefits);
    let mut order = SplitOrder::default();
    order.reset_steps(&replay, &benefits, Steps::LevelSplits);
    let mut whole = SplitOrder::default();
    whole.reset_steps(&replay, &benefits, Steps::WholeSplits);
    let mut differs = false;
    for level in 1..h.top() {
        let mut level_replay = replay.clone();
        level_replay.select_level(level);
        let mut want = level_replay.shown().to_vec();
        want.sort_unstable();
        let targets = [CutTarget::Vertices(h.level_sizes[level]), CutTarget::Triangles(want.len() as u32)];
        for target in targets {
            let k = order.prefix(&replay, &benefits, target, 1.0).expect("a prefix");
            for v in 0..fine {
                assert_eq!(order.cut_node_of(&replay, v, k), ancestor(v, level), "{target:?}: vertex {v}");
            }
            let mut shown = order.shown(k).to_vec();
            shown.sort_unstable();
            assert_eq!(shown, want, "{target:?}: shown triangles");
            // The greedy order across levels need not pass through the level.
            let j = whole.prefix(&replay, &benefits, target, 1.0).expect("a prefix");
            differs |= (0..fine).any(|v| whole.cut_node_of(&replay, v, j) != ancestor(v, level));
        }
        // Between this level and the finer one: cut nodes of the two levels only.
        let between = (h.level_sizes[level] + h.level_sizes[level - 1]) / 2;
        let k = order.prefix(&replay, &benefits, CutTarget::Vertices(between), 1.0).expect("a prefix");
        for v in 0..fine {
            let g = order.cut_node_of(&replay, v, k);
            assert!(g == ancestor(v, level) || g == ancestor(v, level - 1), "budget {between}: vertex {v} on node {g}");
        }
    }
    assert!(differs, "the greedy order passes through every level here: the test shows nothing");
}

/// A generated 36 x 28 wave of 3 frames, built, encoded and replayed to its last frame: the
/// sequence, the replay and the encoder's node positions there.
fn replayed_wave() -> (pmcodec_mesh::Sequence, Replay, Vec<Vec3>) {
    let seq = grid(36, 28, 3);
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions::default()).expect("build");
    let mut enc = Encoder::new(h.clone(), topo, seq.triangles.clone(), Default::default());
    let mut replay = Replay::new(h, &seq.triangles);
    for frame in &seq.frames {
        let (delta, _) = enc.encode_frame(frame);
        replay.apply(&delta).expect("apply");
    }
    let positions: Vec<Vec3> = enc.node_positions().to_vec();
    (seq, replay, positions)
}
