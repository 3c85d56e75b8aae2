//! The multilevel mesh on real and generated meshes: structure, connected clusters, degenerate
//! sets against brute force, and cuts.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::*;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::cut::{self, ChildIndex};
use pmcodec_hierarchy::*;
use pmcodec_hierarchy::{CutTarget, Distance};

struct Built {
    seq: pmcodec_mesh::Sequence,
    topo: FineTopology,
    h: Hierarchy,
    d: DegenerateSets,
}

fn build_seq(seq: pmcodec_mesh::Sequence, opts: &BuildOptions) -> Built {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, opts).expect("build");
    let d = DegenerateSets::new(&h, &seq.triangles);
    Built { seq, topo, h, d }
}

/// The degenerate-set rule against brute force: t is shown iff its corners map to three
/// distinct cut nodes.
fn check_degenerate_sets(b: &Built, seed: u64, cuts: usize) {
    let mut rng = Rng::new(seed);
    for i in 0..cuts {
        let p = [0.0, 0.3, 0.7, 0.95, 1.0][i % 5];
        let c = random_cut(&b.h, &mut rng, p);
        let rep = cut::cut_nodes(&b.h, &c);
        let brute: Vec<u32> = b
            .seq
            .triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                let [x, y, z] = t.map(|v| rep[v as usize]);
                x != y && y != z && x != z
            })
            .map(|(t, _)| t as u32)
            .collect();
        assert_eq!(cut::shown_triangles(&b.d, &c), brute, "cut {i} (p = {p})");
    }
}

#[test]
fn horse_hierarchy_is_valid() {
    let seq = load("horse-gallop", 1);
    let b = build_seq(seq, &BuildOptions::default());
    assert_eq!(b.h.level_sizes, vec![8431, 2108, 527, 132, 33, 8]);
    b.h.check(&b.topo).expect("every cluster connected");
    check_degenerate_sets(&b, 1, 10);
    // Every triangle degenerates somewhere or is shown at the top; D sets partition them.
    let in_sets: usize = (0..b.h.node_count() as u32).map(|g| b.d.size(g) as usize).sum();
    assert_eq!(in_sets + b.d.never.len(), b.seq.triangles.len());
}

#[test]
fn samba_and_cat_hierarchies_are_valid() {
    for name in ["samba-60", "cat-poses"] {
        let seq = load(name, 1);
        for branching in [2, 8] {
            let b = build_seq(seq.clone(), &BuildOptions { branching, ..Default::default() });
            b.h.check(&b.topo).unwrap_or_else(|e| panic!("{name} b={branching}: {e}"));
            for w in b.h.level_sizes.windows(2) {
                let ratio = w[0] as f64 / w[1] as f64;
                assert!((ratio - branching as f64).abs() < 0.1 * branching as f64, "{name}: {:?}", b.h.level_sizes);
            }
            check_degenerate_sets(&b, 2, 5);
        }
    }
}

#[test]
fn budget_cuts_are_exact_and_full() {
    let seq = load("horse-gallop", 1);
    let b = build_seq(seq, &BuildOptions::default());
    let children = ChildIndex::new(&b.h);
    let nodes = NodeState::compute(&b.h, &base_quadrics(&b.seq, &b.topo, &BaseOptions::default()), &b.seq.frames[0]);
    let max_d = (0..b.h.node_count() as u32).map(|g| b.d.size(g)).max().unwrap_or(0);
    for budget in [100, 1600, 2000, 5000, 16000] {
        let c = pmcodec_eval::select_cut(&b.h, &b.d, &children, &nodes, CutTarget::Triangles(budget));
        let (mesh, _) = cut::extract(&b.h, &b.d, &b.seq.triangles, &c, &nodes.positions);
        assert_eq!(mesh.triangles.len() as u32, c.triangles, "counted = extracted");
        assert!(c.triangles <= budget, "{} > {budget}", c.triangles);
        assert!(c.triangles + max_d > budget || c.triangles == b.seq.triangles.len() as u32, "budget {budget}: only {}", c.triangles);
        assert!(mesh.positions.len() as u32 <= c.vertices, "a cut node may carry no shown triangle, never the reverse");
    }
    for level in 0..b.h.levels() {
        let c = pmcodec_eval::select_cut(&b.h, &b.d, &children, &nodes, CutTarget::Level(level));
        let (mesh, _) = cut::extract(&b.h, &b.d, &b.seq.triangles, &c, &nodes.positions);
        assert!(mesh.positions.len() as u32 <= b.h.level_sizes[level]);
        if level == 0 {
            assert_eq!(mesh.triangles.len(), b.seq.triangles.len());
        }
    }
    let c = pmcodec_eval::select_cut(&b.h, &b.d, &children, &nodes, CutTarget::Vertices(800));
    assert!(c.vertices <= 800 && c.vertices > 780, "{}", c.vertices);
    // Max error: a looser tolerance never gives more triangles.
    let diag = b.seq.frame_mesh(0).unwrap().diagonal() as f64;
    let mut last = u32::MAX;
    for tol in [0.0001, 0.001, 0.01, 0.1] {
        let c = pmcodec_eval::select_cut(&b.h, &b.d, &children, &nodes, CutTarget::MaxError(Distance::Absolute(tol * diag)));
        assert!(c.triangles <= last);
        // The same bound as a fraction of the diagonal (nodes are of frame 0) is the same cut.
        let fraction = pmcodec_eval::select_cut(&b.h, &b.d, &children, &nodes, CutTarget::MaxError(Distance::DiagonalFraction(tol)));
        assert_eq!(fraction.expanded, c.expanded, "tolerance {tol} of the diagonal");
        last = c.triangles;
    }
}

#[test]
fn grid_fixture_hierarchies() {
    for (w, h) in [(3, 3), (10, 7), (40, 40)] {
        let b = build_seq(grid(w, h, 1), &BuildOptions { min_coarsest: 1, ..Default::default() });
        b.h.check(&b.topo).expect("connected");
        check_degenerate_sets(&b, 3, 10);
        assert!(b.h.level_sizes.len() >= 2);
    }
}

/// A hierarchy anchored at 0 vertices is refused with a typed error (it once never returned,
/// growing its list of level sizes without bound), and small anchors still build.
#[test]
fn anchor_of_zero_vertices_is_refused() {
    let seq = grid(12, 10, 1);
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(&seq, &topo, &BaseOptions::default());
    let e = pmcodec_hierarchy::build::anchored_build(&topo, &q, 0, 4).unwrap_err();
    assert!(e.to_string().contains("above 0"), "{e}");
    let (h, level) = pmcodec_hierarchy::build::anchored_build(&topo, &q, 30, 4).expect("anchor 30");
    assert_eq!(h.level_sizes[level], 30);
}
