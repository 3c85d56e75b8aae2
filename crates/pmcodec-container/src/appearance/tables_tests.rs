//! The encoder's tables: a free coarse entry (a pair only another frame's swap makes) takes
//! its parent entry's value.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use super::*;
use glam::Vec3;

/// Two charts: triangle 0 alone (chart 0), triangles 1 and 2 (chart 1), every vertex its own
/// texture coordinate (u = its index / 8, v = 0.1 * index, so no two agree).
fn two_charts() -> (Vec<[u32; 3]>, Vec<Vec3>, Appearance) {
    let triangles = vec![[0, 1, 2], [3, 4, 5], [5, 4, 6]];
    let positions: Vec<Vec3> = (0..7).map(|i| Vec3::new(i as f32, (i * i % 5) as f32, 0.0)).collect();
    let mut app = Appearance::default();
    for v in 0..7u32 {
        app.wedge_vertex.push(v);
        app.uv0.push([v as f32 / 8.0, 0.1 * v as f32]);
    }
    app.corner_wedges = triangles.clone();
    (triangles, positions, app)
}

#[test]
fn a_free_coarse_entry_takes_its_parent_entrys_value() {
    let (triangles, positions, app) = two_charts();
    let charts = super::super::charts::build(&triangles, 7, &app);
    assert_eq!(charts.triangle_chart, vec![0, 1, 1]);
    let info = super::super::info_for(&app, &charts, 12);
    let mut b = TableBuilder::new(&triangles, &positions, &app, charts, info, 3);
    // Level 1 -> 2 in both frames; level 0 -> 1 differs: frame 1 moves vertex 5 from node 3
    // (and 6) to node 4, so (4, chart 1) is a pair only frame 1 makes: no frame-0 child of node 4
    // is in chart 1, and its parent entry (1, chart 1) is already represented by (3, chart 1).
    let up = vec![0, 0, 0, 1, 1];
    b.observe(&[vec![0, 1, 4, 2, 2, 3, 3], up.clone()]);
    b.observe(&[vec![0, 1, 4, 2, 2, 4, 4], up]);
    let tables = b.finish();
    let band = |j: usize, key: (u32, u32)| {
        let e = tables[j].entries.iter().position(|&k| k == key).unwrap_or_else(|| panic!("no entry {key:?} in band {j}"));
        tables[j].values[2 * e..2 * e + 2].to_vec()
    };
    // (1, chart 1) of band 2 is vertex 5's value, carried up through (3, chart 1).
    let v5 = [5.0f64 / 8.0, 0.5].iter().enumerate().map(|(k, &x)| quantize(b.info(), k, x)).collect::<Vec<_>>();
    assert_eq!(band(2, (1, 1)), v5);
    assert_eq!(band(1, (3, 1)), v5);
    // The free entry copies it (its frame-1 mean would mix vertices 5 and 6).
    assert_eq!(band(1, (4, 1)), v5);
    // A represented entry keeps its representative's value: (4, chart 0) is vertex 2's.
    let v2 = [2.0f64 / 8.0, 0.2].iter().enumerate().map(|(k, &x)| quantize(b.info(), k, x)).collect::<Vec<_>>();
    assert_eq!(band(1, (4, 0)), v2);
}
