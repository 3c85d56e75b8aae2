//! The split order on real sequences: budget and error cuts are prefixes that are maximal for
//! their target, closed upward, and show exactly the mesh the replay shows for the same cut.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::*;
use glam::Vec3;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::progressive::{Encoder, Replay};
use pmcodec_hierarchy::split_order::SplitOrder;
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

/// Budget priorities: zero at the finest level, monotone up the hierarchy, and the RMS error
/// scaled by the fourth root of the cluster's area: scaling the surface by 4 scales split
/// priorities (distances) by 4 and budget priorities by 4^1.5 = 8 (powers of two, so exactly up
/// to rounding of the square roots). A priority without the area factor, or with the area
/// itself, scales by 4 or 16 and fails.
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
    replay.split_benefits_into(&positions, &mut benefits);
    let errors = replay.node_errors(&positions);
    let h = &replay.h;
    assert_eq!(benefits.len(), h.node_count());
    assert!(benefits[..h.level_sizes[0] as usize].iter().all(|&b| b == 0.0));
    assert!(benefits.iter().any(|&b| b > 0.0), "a bent grid has nodes off their faces");
    for g in 0..h.node_count() as u32 {
        let p = h.parent_global(g);
        assert!(p == NONE || benefits[p as usize] >= benefits[g as usize], "node {g}: parent {p} below it");
    }
    let scaled: Vec<Vec3> = positions.iter().map(|&p| p * 4.0).collect();
    let mut benefits4 = Vec::new();
    replay.split_benefits_into(&scaled, &mut benefits4);
    let errors4 = replay.node_errors(&scaled);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-300);
    for g in 0..h.node_count() {
        assert!(close(errors4[g], 4.0 * errors[g]), "node {g}: error {} -> {}", errors[g], errors4[g]);
        assert!(close(benefits4[g], 8.0 * benefits[g]), "node {g}: benefit {} -> {}", benefits[g], benefits4[g]);
    }
}
