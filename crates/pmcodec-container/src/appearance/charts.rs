//! Charts: the unit appearance is stored and interpolated in.
//!
//! A *chart* is an edge-connected set of triangles of one material across whose shared edges
//! the wedges agree at both ends (Hoppe, "New quadric metric for simplifying meshes with
//! appearance attributes", 1999, treats such edges as the inside of an attribute region; seams,
//! creases and material boundaries are its borders). Within a chart every vertex has exactly
//! one wedge: charts are grown greedily, breadth first, and a triangle whose free corner would
//! give a vertex a second wedge in the chart starts or joins another one (a UV island that
//! wraps around a cylinder is cut open along its seam this way). So the pair (node, chart)
//! names one attribute value at every level: the input's wedge at level 0, a solved value for
//! a cluster above.
//!
//! A *smoothing group* is the same for normals alone, apart from charts: an edge-connected set
//! of triangles whose shared edges agree in their input normals at both ends. Decoders sum face
//! normals per (cut node, group), so shading splits at creases (and every face of a flat-shaded
//! input is a group of its own) but not at UV seams or material boundaries the input shades
//! smoothly; and a flat-shaded input's texture charts stay whole.

// Corners index several parallel arrays in step (triangles, wedges, ancestors).
#![allow(clippy::needless_range_loop)]

use pmcodec_mesh::Appearance;

const NONE: u32 = u32::MAX;

/// Charts of a mesh's triangles.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Charts {
    /// Chart of each triangle; charts are numbered in order of their first triangle.
    pub triangle_chart: Vec<u32>,
    /// Material of each chart (an index into the appearance's materials; 0 when it has none).
    pub chart_material: Vec<u32>,
    /// Smoothing group of each triangle, numbered in order of first appearance.
    pub triangle_group: Vec<u32>,
}

impl Charts {
    /// Number of charts.
    pub fn count(&self) -> usize {
        self.chart_material.len()
    }
}

/// Whether wedges `a` and `b` carry the same stored attributes (texture coordinates and
/// colour; normals are the groups' business): the same wedge, or equal values.
fn same_wedge(app: &Appearance, a: u32, b: u32) -> bool {
    let (a, b) = (a as usize, b as usize);
    a == b || (app.uv0.get(a) == app.uv0.get(b) && app.uv1.get(a) == app.uv1.get(b) && app.colors.get(a) == app.colors.get(b))
}

/// Whether wedges `a` and `b` carry the same input normal (true when the input has none).
fn same_normal(app: &Appearance, a: u32, b: u32) -> bool {
    app.normals.get(a as usize) == app.normals.get(b as usize)
}

/// Triangles sharing each undirected edge: `(edge key, triangle, corner of the edge's start)`
/// sorted by key, so the triangles of an edge are adjacent.
fn edge_list(triangles: &[[u32; 3]]) -> Vec<(u64, u32, u8)> {
    let mut edges = Vec::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            edges.push((((a.min(b) as u64) << 32) | a.max(b) as u64, t as u32, i as u8));
        }
    }
    edges.sort_unstable();
    edges
}

/// The charts and smoothing groups of `triangles` with appearance `app` (whose
/// `corner_wedges` are parallel to them).
pub fn build(triangles: &[[u32; 3]], vertex_count: usize, app: &Appearance) -> Charts {
    let edges = edge_list(triangles);
    // Per triangle corner: the range of `edges` holding the edge starting at that corner.
    let mut range = vec![(0u32, 0u32); triangles.len() * 3];
    let mut s = 0;
    while s < edges.len() {
        let mut e = s + 1;
        while e < edges.len() && edges[e].0 == edges[s].0 {
            e += 1;
        }
        for &(_, t, i) in &edges[s..e] {
            range[t as usize * 3 + i as usize] = (s as u32, e as u32);
        }
        s = e;
    }
    let material = |t: usize| app.triangle_material.get(t).copied().unwrap_or(0);
    let wedge_at = |t: usize, v: u32| {
        let k = triangles[t].iter().position(|&x| x == v).unwrap_or(0);
        app.corner_wedges[t][k]
    };
    let mut chart = vec![NONE; triangles.len()];
    let mut charts = Charts::default();
    // The wedge each vertex has in the chart being grown (valid where `stamp` is that chart).
    let mut stamp = vec![NONE; vertex_count];
    let mut held = vec![0u32; vertex_count];
    let mut queue: Vec<u32> = Vec::new();
    for seed in 0..triangles.len() {
        if chart[seed] != NONE {
            continue;
        }
        let c = charts.chart_material.len() as u32;
        charts.chart_material.push(material(seed));
        chart[seed] = c;
        for i in 0..3 {
            stamp[triangles[seed][i] as usize] = c;
            held[triangles[seed][i] as usize] = app.corner_wedges[seed][i];
        }
        queue.clear();
        queue.push(seed as u32);
        let mut head = 0;
        while head < queue.len() {
            let t = queue[head] as usize;
            head += 1;
            for i in 0..3 {
                let (a, b) = (triangles[t][i], triangles[t][(i + 1) % 3]);
                let (lo, hi) = range[t * 3 + i];
                for &(_, u, _) in &edges[lo as usize..hi as usize] {
                    let u = u as usize;
                    if chart[u] != NONE || material(u) != material(t) {
                        continue;
                    }
                    if !same_wedge(app, wedge_at(u, a), held[a as usize]) || !same_wedge(app, wedge_at(u, b), held[b as usize]) {
                        continue;
                    }
                    let Some(k) = triangles[u].iter().position(|&x| x != a && x != b) else { continue };
                    let w = triangles[u][k] as usize;
                    if stamp[w] == c && !same_wedge(app, held[w], app.corner_wedges[u][k]) {
                        continue;
                    }
                    stamp[w] = c;
                    held[w] = app.corner_wedges[u][k];
                    chart[u] = c;
                    queue.push(u as u32);
                }
            }
        }
    }
    charts.triangle_chart = chart;
    charts.triangle_group = groups(triangles, app, &edges);
    charts
}

/// Smoothing groups: union-find over triangles joined by an edge whose input normals agree at
/// both ends (every edge when the input has no normals).
fn groups(triangles: &[[u32; 3]], app: &Appearance, edges: &[(u64, u32, u8)]) -> Vec<u32> {
    let count = triangles.len();
    let mut root: Vec<u32> = (0..count as u32).collect();
    fn find(root: &mut [u32], mut x: u32) -> u32 {
        while root[x as usize] != x {
            root[x as usize] = root[root[x as usize] as usize];
            x = root[x as usize];
        }
        x
    }
    let corner_wedge = |t: u32, v: u32| {
        let k = triangles[t as usize].iter().position(|&x| x == v).unwrap_or(0);
        app.corner_wedges[t as usize][k]
    };
    for pair in edges.windows(2) {
        let ((k0, t, i), (k1, u, _)) = (pair[0], pair[1]);
        if k0 != k1 {
            continue;
        }
        let (a, b) = (triangles[t as usize][i as usize], triangles[t as usize][(i as usize + 1) % 3]);
        if same_normal(app, corner_wedge(t, a), corner_wedge(u, a)) && same_normal(app, corner_wedge(t, b), corner_wedge(u, b)) {
            let (x, y) = (find(&mut root, t), find(&mut root, u));
            if x != y {
                root[x.max(y) as usize] = x.min(y);
            }
        }
    }
    // Number groups in order of first appearance (the smallest triangle of each is its root).
    let mut number = vec![NONE; count];
    let mut next = 0;
    (0..count as u32)
        .map(|c| {
            let r = find(&mut root, c) as usize;
            if number[r] == NONE {
                number[r] = next;
                next += 1;
            }
            number[r]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cloth_has_a_chart_per_material_and_one_group() {
        let seq = pmcodec_mesh::samples::textured_cloth(9, 6, 1, 8);
        let app = seq.appearance.as_ref().unwrap();
        let c = build(&seq.triangles, seq.vertex_count(), app);
        assert_eq!(c.count(), 2);
        assert_eq!(c.chart_material, vec![0, 1]);
        // No input normals: the seam is smooth, one group.
        assert!(c.triangle_group.iter().all(|&g| g == 0));
        for (t, &m) in app.triangle_material.iter().enumerate() {
            assert_eq!(c.triangle_chart[t], m);
        }
    }

    #[test]
    fn a_wrapped_island_is_cut_open() {
        // A strip of quads around a cylinder whose last column of wedges is a UV seam: one
        // edge-connected region, but its seam vertices would have two wedges in it.
        let n = 6u32;
        let mut triangles = Vec::new();
        let mut app = Appearance::default();
        for v in 0..2 * n {
            app.wedge_vertex.push(v);
            app.uv0.push([(v % n) as f32, (v / n) as f32]);
        }
        let seam = [app.wedge_vertex.len() as u32, app.wedge_vertex.len() as u32 + 1];
        app.wedge_vertex.extend([0, n]);
        app.uv0.extend([[n as f32, 0.0], [n as f32, 1.0]]);
        for s in 0..n {
            let (a, b, c, d) = (s, (s + 1) % n, n + (s + 1) % n, n + s);
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
            let w = |v: u32| {
                if s == n - 1 && v == 0 {
                    seam[0]
                } else if s == n - 1 && v == n {
                    seam[1]
                } else {
                    v
                }
            };
            app.corner_wedges.push([w(a), w(b), w(c)]);
            app.corner_wedges.push([w(a), w(c), w(d)]);
        }
        app.validate(2 * n as usize, &triangles).unwrap();
        let c = build(&triangles, 2 * n as usize, &app);
        // Whatever the split, no vertex has two wedges in one chart.
        for ch in 0..c.count() as u32 {
            let mut seen = std::collections::HashMap::new();
            for (t, tri) in triangles.iter().enumerate().filter(|(t, _)| c.triangle_chart[*t] == ch) {
                for i in 0..3 {
                    let w = app.corner_wedges[t][i];
                    assert_eq!(*seen.entry(tri[i]).or_insert(w), w, "vertex {} has two wedges in chart {ch}", tri[i]);
                }
            }
        }
        assert!(c.count() >= 2);
    }
}
