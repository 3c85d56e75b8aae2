//! Validity of the base hierarchy (issue 15 item 1): no level shows a triangle turned over
//! against the fine triangle it stands for, and open meshes keep their boundary loops.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::*;
use pmcodec_hierarchy::CutTarget;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::cut::{self, ChildIndex};
use pmcodec_hierarchy::*;
use pmcodec_mesh::Sequence;

/// Boundary edges of a mesh and the loops they form (connected components).
fn boundary_loops(vertices: usize, triangles: &[[u32; 3]]) -> (usize, usize) {
    let boundary = FineTopology::new(vertices as u32, triangles).boundary;
    let mut uf: Vec<usize> = (0..vertices).collect();
    fn find(uf: &mut [usize], mut x: usize) -> usize {
        while uf[x] != x {
            uf[x] = uf[uf[x]];
            x = uf[x];
        }
        x
    }
    let mut on = vec![false; vertices];
    for &(a, b, _) in &boundary {
        on[a as usize] = true;
        on[b as usize] = true;
        let (ra, rb) = (find(&mut uf, a as usize), find(&mut uf, b as usize));
        uf[ra.max(rb)] = ra.min(rb);
    }
    let loops = (0..vertices).filter(|&v| on[v] && find(&mut uf, v) == v).count();
    (boundary.len(), loops)
}

/// Per level: vertices, shown triangles, those facing against their fine triangle, and the
/// boundary edges and loops.
fn level_report(seq: &Sequence) -> Vec<(usize, usize, usize, (usize, usize))> {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(seq, &topo, &BaseOptions::default());
    let h = build(&topo, &q, &BuildOptions { min_coarsest: 16, ..Default::default() }).expect("build");
    let nodes = NodeState::compute(&h, &q, &seq.frames[0]);
    let d = DegenerateSets::new(&h, &seq.triangles);
    let children = ChildIndex::new(&h);
    let fine = &seq.frames[0];
    let normal = |p: &[glam::Vec3], t: [u32; 3]| {
        let [a, b, c] = t.map(|v| p[v as usize]);
        (b - a).cross(c - a)
    };
    (1..h.levels())
        .map(|level| {
            let c = pmcodec_eval::select_cut(&h, &d, &children, &nodes, CutTarget::Level(level));
            let (mesh, _) = cut::extract(&h, &d, &seq.triangles, &c, &nodes.positions);
            let shown = cut::shown_triangles(&d, &c);
            let folded = shown
                .iter()
                .zip(&mesh.triangles)
                .filter(|&(&t, &m)| normal(&mesh.positions, m).dot(normal(fine, seq.triangles[t as usize])) < 0.0)
                .count();
            let boundary = boundary_loops(mesh.positions.len(), &mesh.triangles);
            (h.level_sizes[level] as usize, mesh.triangles.len(), folded, boundary)
        })
        .collect()
}

#[test]
fn horse_levels_do_not_fold() {
    let seq = load("horse-gallop", 1);
    let report = level_report(&seq);
    eprintln!("levels (vertices, triangles, folded, (boundary edges, loops)): {report:?}");
    for (vertices, triangles, folded, _) in report {
        assert_eq!(folded, 0, "{folded} of {triangles} triangles folded at the {vertices}-vertex level");
    }
}

#[test]
fn open_grid_keeps_one_boundary_and_does_not_fold() {
    let seq = grid(40, 30, 1);
    let (fine_edges, fine_loops) = boundary_loops(seq.vertex_count(), &seq.triangles);
    assert_eq!(fine_loops, 1);
    let report = level_report(&seq);
    eprintln!("levels (vertices, triangles, folded, (boundary edges, loops)): {report:?}");
    for (vertices, triangles, folded, (edges, loops)) in report {
        assert_eq!(folded, 0, "{folded} of {triangles} triangles folded at the {vertices}-vertex level");
        // A boundary pinched across the surface opens holes: more loops than the one outline.
        assert_eq!(loops, 1, "{loops} boundary loops ({edges} edges) at the {vertices}-vertex level");
        assert!(edges <= fine_edges);
    }
}

/// The wavy grid of `common::grid` with the triangles whose centroids fall in `holes`
/// (rectangles in the unit square: x0, y0, x1, y1) removed and the unused vertices dropped:
/// an open mesh with one boundary loop per hole beside its outline.
fn grid_with_holes(w: u32, h: u32, holes: &[[f32; 4]]) -> Sequence {
    let full = grid(w, h, 1);
    let p = &full.frames[0];
    let kept: Vec<[u32; 3]> = full
        .triangles
        .iter()
        .copied()
        .filter(|t| {
            let c = (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
            !holes.iter().any(|r| c.x > r[0] && c.x < r[2] && c.y > r[1] && c.y < r[3])
        })
        .collect();
    let mut index = vec![u32::MAX; p.len()];
    let mut positions = Vec::new();
    let triangles = kept
        .iter()
        .map(|t| {
            t.map(|v| {
                if index[v as usize] == u32::MAX {
                    index[v as usize] = positions.len() as u32;
                    positions.push(p[v as usize]);
                }
                index[v as usize]
            })
        })
        .collect();
    Sequence { triangles, frames: vec![positions], frame_rate: 30.0, ..Default::default() }
}

#[test]
fn grid_with_holes_keeps_every_boundary_loop() {
    // Three holes of different sizes and shapes (the smallest 3 x 3 grid cells) and the outline.
    let seq = grid_with_holes(48, 40, &[[0.15, 0.2, 0.35, 0.45], [0.55, 0.6, 0.85, 0.7], [0.62, 0.15, 0.69, 0.24]]);
    let (fine_edges, fine_loops) = boundary_loops(seq.vertex_count(), &seq.triangles);
    assert_eq!(fine_loops, 4, "the fixture has three holes and an outline");
    let report = level_report(&seq);
    eprintln!("levels (vertices, triangles, folded, (boundary edges, loops)): {report:?}");
    for (vertices, triangles, folded, (edges, loops)) in report {
        assert_eq!(folded, 0, "{folded} of {triangles} triangles folded at the {vertices}-vertex level");
        if vertices >= 64 {
            // A hole collapsed across (its loop pinched, or closed) or a boundary pinched across
            // the surface (a new loop) changes the count.
            assert_eq!(loops, fine_loops, "{loops} boundary loops ({edges} edges) at the {vertices}-vertex level");
        }
        assert!(edges <= fine_edges);
    }
}
