//! Reclustering and the progressive representation on real sequences: clusters stay connected
//! every frame, the replayed hierarchy equals the encoder's bit for bit, and the incrementally
//! maintained cut equals one re-derived from scratch.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::*;
use pmcodec_hierarchy::CutTarget;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::cut::{self, ChildIndex, Cut};
use pmcodec_hierarchy::progressive::{BELOW, CornerUpdate, DeltaError, Encoder, FrameDelta, Replay, node_level};
use pmcodec_hierarchy::recluster::{ReclusterOptions, Swap};
use pmcodec_hierarchy::*;

fn encoder_for(seq: &pmcodec_mesh::Sequence, opts: ReclusterOptions) -> (Encoder, Hierarchy) {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions::default()).expect("build");
    (Encoder::new(h.clone(), topo, seq.triangles.clone(), opts), h)
}

/// What a replayed sequence did: swaps in all, and swaps that broke section 4.2's
/// homeomorphism rule as [`homeomorphism_violations`] checks it.
struct Replayed {
    swaps: usize,
    violations: usize,
}

/// Replays every frame and checks it against the encoder and against re-deriving the cut.
fn replay_matches(seq: &pmcodec_mesh::Sequence, opts: ReclusterOptions) -> Replayed {
    let (mut enc, base) = encoder_for(seq, opts);
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let mut replay = Replay::new(base, &seq.triangles);
    let mut out = Replayed { swaps: 0, violations: 0 };
    for (f, frame) in seq.frames.iter().enumerate() {
        let before = enc.hierarchy().clone();
        let (delta, stats) = enc.encode_frame(frame);
        assert_eq!(stats.swaps as usize, delta.swaps.len(), "frame {f}: swaps counted and sent");
        out.swaps += delta.swaps.len();
        out.violations += homeomorphism_violations(&before, &seq.triangles, &delta.swaps);
        enc.hierarchy().check(&topo).unwrap_or_else(|e| panic!("frame {f}: {e}"));
        // Every few frames, pick a fresh budget cut on the encoder's side and hand it over, so
        // the replay maintains different cuts through later deltas.
        if f % 7 == 1 {
            let h = enc.hierarchy();
            let d = DegenerateSets::from_nodes(h.node_count(), enc.degeneration().to_vec());
            let nodes = NodeState::compute(h, &vec![Quadric::default(); seq.vertex_count()], frame);
            let budget = [2000, 500, 9000][f % 3];
            let c = pmcodec_eval::select_cut(h, &d, &ChildIndex::new(h), &nodes, CutTarget::Triangles(budget));
            replay.set_cut(&c.expanded);
        }
        replay.apply(&delta).unwrap_or_else(|e| panic!("frame {f}: {e}"));
        assert_eq!(&replay.h, enc.hierarchy(), "frame {f}: parent maps");
        assert_eq!(replay.degeneration(), enc.degeneration(), "frame {f}: degenerate sets");
        // The maintained cut is closed upward...
        let expanded = replay.expanded().to_vec();
        for g in 0..expanded.len() as u32 {
            let p = replay.h.parent_global(g);
            assert!(!expanded[g as usize] || p == NONE || expanded[p as usize], "frame {f}: cut not closed at {g}");
        }
        // ...and shows exactly what re-deriving from scratch shows.
        let d = DegenerateSets::new(&replay.h, &seq.triangles);
        let derived = cut::shown_triangles(&d, &Cut { expanded, triangles: 0, vertices: 0 });
        let mut shown = replay.shown().to_vec();
        shown.sort_unstable();
        assert_eq!(shown, derived, "frame {f}: shown triangles");
    }
    out
}

/// Each level-k node's neighbours: the level-k nodes whose clusters share a fine edge with its
/// own (sorted, without itself).
fn level_neighbours(h: &Hierarchy, triangles: &[[u32; 3]], k: usize) -> Vec<Vec<u32>> {
    let ancestor = |mut v: u32| {
        for p in &h.parent[..k] {
            v = p[v as usize];
        }
        v
    };
    let mut out = vec![Vec::new(); h.level_sizes[k] as usize];
    for t in triangles {
        for i in 0..3 {
            let (a, b) = (ancestor(t[i]), ancestor(t[(i + 1) % 3]));
            if a != b {
                out[a as usize].push(b);
                out[b as usize].push(a);
            }
        }
    }
    for row in &mut out {
        row.sort_unstable();
        row.dedup();
    }
    out
}

/// How many of a frame's swaps (in the order performed, on the hierarchy `before` the frame)
/// break section 4.2's homeomorphism rule in the conservative form the encoder applies it: a
/// node v moving to cluster b may touch another cluster c only where v's contact with c
/// continues a contact between b and c (a neighbour of v in b is adjacent to a neighbour of v
/// in c); otherwise the move could open a second boundary between b and c. Levels are
/// reclustered coarsest first, so a level's swaps see the frame's parent maps below it (which
/// fix its neighbours) and the swaps before them at their own level.
fn homeomorphism_violations(before: &Hierarchy, triangles: &[[u32; 3]], swaps: &[Swap]) -> usize {
    let mut h = before.clone();
    let mut adj: Option<(usize, Vec<Vec<u32>>)> = None;
    let mut violations = 0;
    for s in swaps {
        let k = s.level as usize;
        if adj.as_ref().is_none_or(|(level, _)| *level != k) {
            adj = Some((k, level_neighbours(&h, triangles, k)));
        }
        let Some((_, adj)) = adj.as_ref() else { unreachable!() };
        let parent = &h.parent[k];
        assert_eq!(parent[s.v as usize], s.from, "swap {s:?} does not start from v's parent");
        let nbrs = &adj[s.v as usize];
        let continues = |c: u32| {
            nbrs.iter().any(|&u| {
                parent[u as usize] == s.to && nbrs.iter().any(|&z| parent[z as usize] == c && adj[u as usize].binary_search(&z).is_ok())
            })
        };
        if !nbrs.iter().all(|&w| parent[w as usize] == s.to || continues(parent[w as usize])) {
            violations += 1;
        }
        h.parent[k][s.v as usize] = s.to;
    }
    violations
}

#[test]
fn horse_gallop_replays_bit_for_bit() {
    let seq = load("horse-gallop", 48);
    let r = replay_matches(&seq, ReclusterOptions::default());
    assert!(r.swaps > 48 * 50, "reclustering should move vertices on a gallop: {} swaps", r.swaps);
}

/// With the rule on, swaps still happen and none breaks it; with it off, the same frames give
/// swaps that do (so the check above can fail).
#[test]
fn samba_replays_with_homeomorphism_rule() {
    let seq = load("samba-60", 12);
    let with_rule = replay_matches(&seq, ReclusterOptions { homeomorphism: true, ..Default::default() });
    assert!(with_rule.swaps > 12 * 5, "reclustering should move vertices on a dance: {} swaps", with_rule.swaps);
    assert_eq!(with_rule.violations, 0, "of {} swaps", with_rule.swaps);
    let (mut enc, _) = encoder_for(&seq, ReclusterOptions::default());
    let mut without = 0;
    for frame in &seq.frames {
        let before = enc.hierarchy().clone();
        let (delta, _) = enc.encode_frame(frame);
        without += homeomorphism_violations(&before, &seq.triangles, &delta.swaps);
    }
    // Shown with --nocapture, for the figures quoted in commit messages and reports.
    eprintln!("samba, 12 frames: {} swaps with the rule, none breaking it; {without} swaps break it without the rule", with_rule.swaps);
    assert!(without > 0, "without the rule some swap should break it");
}

#[test]
fn cat_poses_replay() {
    let seq = load("cat-poses", 10);
    let r = replay_matches(&seq, ReclusterOptions::default());
    eprintln!("cat, 10 poses: {} swaps", r.swaps);
    // Ten different poses: every frame reclusters.
    assert!(r.swaps > 10 * 50, "reclustering should move vertices between poses: {} swaps", r.swaps);
}

#[test]
fn generated_wave_replays() {
    let seq = grid(30, 20, 12);
    let r = replay_matches(&seq, ReclusterOptions::default());
    assert!(r.swaps > 0);
}

#[test]
fn stopped_corners_leave_the_reclustering_unchanged() {
    // A generated wave: swaps every frame, corner updates at several levels.
    let seq = grid(30, 20, 8);
    let (mut followed, _) = encoder_for(&seq, ReclusterOptions::default());
    let (mut stopped, _) = encoder_for(&seq, ReclusterOptions::default());
    stopped.stop_corners();
    let mut updates = 0;
    for (f, frame) in seq.frames.iter().enumerate() {
        let (a, _) = followed.encode_frame(frame);
        let (b, _) = stopped.encode_frame(frame);
        assert_eq!(a.swaps, b.swaps, "frame {f}: swaps");
        assert_eq!(followed.hierarchy(), stopped.hierarchy(), "frame {f}: parent maps");
        assert_eq!(followed.node_positions(), stopped.node_positions(), "frame {f}: node positions");
        assert!(b.corners.is_empty(), "frame {f}: corner updates after stop_corners");
        updates += a.corners.len();
    }
    assert!(updates > 0, "the wave made no corner updates: nothing was skipped");
    let key = stopped.keyframe();
    assert!(key.bands.iter().all(|b| b.faces.is_empty()));
    assert_eq!(
        key.bands.iter().map(|b| &b.parent).collect::<Vec<_>>(),
        followed.keyframe().bands.iter().map(|b| &b.parent).collect::<Vec<_>>()
    );
}

#[test]
fn reclustering_lowers_level_error() {
    let seq = load("horse-gallop", 16);
    let (mut enc, base) = encoder_for(&seq, ReclusterOptions::default());
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let mut stat = pmcodec_hierarchy::recluster::Reclusterer::new(base, topo, seq.triangles.clone(), Default::default());
    let level = 2;
    let (mut sum_static, mut sum_rc) = (0.0, 0.0);
    for frame in &seq.frames {
        enc.encode_frame(frame);
        stat.fit(frame);
        let h = enc.hierarchy();
        sum_rc += (h.offsets[level]..h.offsets[level + 1]).map(|g| enc.nodes().error(g)).sum::<f64>();
        sum_static += (h.offsets[level]..h.offsets[level + 1]).map(|g| stat.nodes().error(g)).sum::<f64>();
    }
    assert!(sum_rc < 0.8 * sum_static, "reclustered {sum_rc:e} vs static {sum_static:e}");
}

#[test]
fn swap_cap_is_respected() {
    let seq = load("horse-gallop", 3);
    let (mut enc, _) = encoder_for(&seq, ReclusterOptions { max_swaps_per_frame: 10, ..Default::default() });
    for frame in &seq.frames {
        let (delta, _) = enc.encode_frame(frame);
        assert!(delta.swaps.len() <= 10);
    }
}

#[test]
fn corrupt_deltas_are_rejected() {
    let seq = grid(10, 10, 1);
    let (_, base) = encoder_for(&seq, ReclusterOptions::default());
    let mut r = Replay::new(base.clone(), &seq.triangles);
    let bad = |swaps: Vec<Swap>, _: Vec<(u32, u32)>| FrameDelta { swaps, corners: vec![] };
    let e = r.apply(&bad(vec![Swap { level: 99, v: 0, from: 0, to: 0 }], vec![])).unwrap_err();
    assert!(matches!(e, DeltaError::SwapOutOfRange { .. }));
    let actual = base.parent[0][0];
    let e = r.apply(&bad(vec![Swap { level: 0, v: 0, from: actual + 1, to: actual }], vec![])).unwrap_err();
    assert!(matches!(e, DeltaError::SwapMismatch { .. }), "{e}");
    // A level-1 replay rejects corner updates naming a triangle or a node that does not exist.
    let mut enc =
        Encoder::new(base.clone(), FineTopology::new(seq.vertex_count() as u32, &seq.triangles), seq.triangles.clone(), Default::default());
    let key = enc.keyframe();
    let h = enc.hierarchy().clone();
    let mut r1 = Replay::from_keyframe(&h.level_sizes, h.branching, &key, 1, seq.triangles.len(), None).expect("keyframe");
    let corner = |t: u32, corners: [u32; 3]| FrameDelta { swaps: vec![], corners: vec![CornerUpdate { level: 1, t, corners }] };
    let e = r1.apply(&corner(u32::MAX - 1, [0, 1, 2])).unwrap_err();
    assert!(matches!(e, DeltaError::CornerOutOfRange { .. }), "{e}");
    let e = r1.apply(&corner(0, [0, 1, h.level_sizes[1]])).unwrap_err();
    assert!(matches!(e, DeltaError::CornerOutOfRange { .. }), "{e}");
    let _ = enc.encode_frame(&seq.frames[0]);
}

/// A client that stops at level L: it starts from a keyframe's bands L.. and reads only the
/// bands L.. of each later delta, and must agree with the encoder on everything at and above L.
fn level_limited_replay_matches(seq: &pmcodec_mesh::Sequence, key_frame: usize, min_level: usize) {
    let (mut enc, _) = encoder_for(seq, ReclusterOptions::default());
    let mut replay: Option<Replay> = None;
    for (f, frame) in seq.frames.iter().enumerate() {
        let (delta, _) = enc.encode_frame(frame);
        let h = enc.hierarchy().clone();
        match replay.as_mut() {
            None if f == key_frame => {
                let key = enc.keyframe();
                let tris = (min_level == 0).then_some(&seq.triangles[..]);
                let mut r =
                    Replay::from_keyframe(&h.level_sizes, h.branching, &key, min_level, seq.triangles.len(), tris).expect("keyframe");
                // Expand everything above min_level: the finest cut this client can show.
                let all: Vec<bool> = (0..h.node_count()).map(|g| g as u32 >= h.offsets[min_level + 1]).collect();
                r.set_cut(&all);
                replay = Some(r);
            }
            None => continue,
            Some(r) => {
                let part = delta.from_level(min_level);
                r.apply(&part).unwrap_or_else(|e| panic!("frame {f}: {e}"));
            }
        }
        let r = replay.as_ref().expect("started");
        assert_eq!(&r.h.parent[min_level..], &h.parent[min_level..], "frame {f} L={min_level}: parent maps");
        for (t, (&mine, &theirs)) in r.degeneration().iter().zip(enc.degeneration()).enumerate() {
            let alive = node_level(&h, theirs) > min_level;
            if alive {
                assert_eq!(mine, theirs, "frame {f} L={min_level}: triangle {t}");
                if min_level > 0 {
                    assert_eq!(r.corners()[t], enc.corners_at(min_level)[t], "frame {f}: corners of {t}");
                }
            } else {
                assert_eq!(mine, BELOW, "frame {f} L={min_level}: triangle {t} should not be alive");
            }
        }
        // Shown = re-derived from the encoder's hierarchy with the same cut.
        let d = DegenerateSets::from_nodes(h.node_count(), enc.degeneration().to_vec());
        let derived = cut::shown_triangles(&d, &Cut { expanded: r.expanded().to_vec(), triangles: 0, vertices: 0 });
        let mut shown = r.shown().to_vec();
        shown.sort_unstable();
        assert_eq!(shown, derived, "frame {f} L={min_level}: shown triangles");
    }
}

#[test]
fn level_limited_clients_agree_with_encoder() {
    let seq = load("horse-gallop", 20);
    for (key, level) in [(0, 1), (0, 2), (5, 3), (9, 0), (0, 4)] {
        level_limited_replay_matches(&seq, key, level);
    }
}
