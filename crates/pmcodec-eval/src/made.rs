//! Test meshes the developers make from the real sequences, so that quality can be measured on
//! shapes the project has no file of: a large closed mesh (Loop subdivision of every frame) and
//! open meshes (faces deleted in regions, leaving several boundary loops). Deterministic: the
//! same input gives the same output, bit for bit.
//!
//! Loop subdivision (Loop, *Smooth Subdivision Surfaces Based on Triangles*, 1987) is a linear
//! map from the coarse positions to the fine ones, fixed by the connectivity: it is built once
//! as sparse stencils and applied to every frame, so the subdivided sequence moves exactly as
//! the original does while its surface is smooth, not the flat facets of midpoint splitting
//! (which a simplifier would undo for free).

use glam::Vec3;
use pmcodec_mesh::Sequence;

/// One output vertex as a weighted sum of input vertices: `rows[offsets[i]..offsets[i + 1]]`.
struct Stencils {
    offsets: Vec<u32>,
    rows: Vec<(u32, f32)>,
}

impl Stencils {
    fn apply(&self, from: &[Vec3]) -> Vec<Vec3> {
        self.offsets
            .windows(2)
            .map(|w| self.rows[w[0] as usize..w[1] as usize].iter().fold(Vec3::ZERO, |acc, &(v, wt)| acc + from[v as usize] * wt))
            .collect()
    }
}

/// Undirected edges of `triangles` with the vertices opposite them: `(key, opposite)` per
/// half-edge, sorted by key (`min << 32 | max`), so an edge's copies are adjacent.
fn half_edges(triangles: &[[u32; 3]]) -> Vec<(u64, u32)> {
    let mut half = Vec::with_capacity(triangles.len() * 3);
    for t in triangles {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            half.push((((a.min(b) as u64) << 32) | a.max(b) as u64, c));
        }
    }
    half.sort_unstable();
    half
}

/// One step of Loop subdivision of every frame: each triangle becomes four, each edge gets a
/// vertex (3/8 of its ends plus 1/8 of the two opposite vertices; the midpoint on a boundary or
/// non-manifold edge), and each old vertex moves toward its neighbours by Warren's weights
/// (3/4 itself and 1/8 of each boundary neighbour on a boundary; fixed at a corner). Vertex
/// count grows to V + E, triangle count fourfold.
pub fn loop_subdivide(seq: &Sequence) -> Sequence {
    let n = seq.vertex_count() as u32;
    let half = half_edges(&seq.triangles);
    // Unique edges with their half-edge ranges.
    let mut edges: Vec<(u64, usize, usize)> = Vec::new();
    let mut i = 0;
    while i < half.len() {
        let mut j = i + 1;
        while j < half.len() && half[j].0 == half[i].0 {
            j += 1;
        }
        edges.push((half[i].0, i, j));
        i = j;
    }
    // Neighbours of each vertex, and its boundary neighbours (across edges of one triangle or
    // of more than two: both are creases the surface must keep).
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n as usize];
    let mut crease: Vec<Vec<u32>> = vec![Vec::new(); n as usize];
    for &(key, a, b) in &edges {
        let (u, v) = ((key >> 32) as u32, key as u32);
        neighbours[u as usize].push(v);
        neighbours[v as usize].push(u);
        if b - a != 2 {
            crease[u as usize].push(v);
            crease[v as usize].push(u);
        }
    }
    let mut offsets = vec![0u32];
    let mut rows: Vec<(u32, f32)> = Vec::new();
    for v in 0..n {
        let (nb, cr) = (&neighbours[v as usize], &crease[v as usize]);
        if cr.is_empty() && !nb.is_empty() {
            let k = nb.len() as f32;
            let beta = if nb.len() == 3 { 3.0 / 16.0 } else { 3.0 / (8.0 * k) };
            rows.push((v, 1.0 - k * beta));
            rows.extend(nb.iter().map(|&u| (u, beta)));
        } else if cr.len() == 2 {
            rows.extend([(v, 0.75), (cr[0], 0.125), (cr[1], 0.125)]);
        } else {
            rows.push((v, 1.0));
        }
        offsets.push(rows.len() as u32);
    }
    for &(key, a, b) in &edges {
        let (u, v) = ((key >> 32) as u32, key as u32);
        if b - a == 2 {
            rows.extend([(u, 0.375), (v, 0.375), (half[a].1, 0.125), (half[a + 1].1, 0.125)]);
        } else {
            rows.extend([(u, 0.5), (v, 0.5)]);
        }
        offsets.push(rows.len() as u32);
    }
    let stencils = Stencils { offsets, rows };
    let mid = |a: u32, b: u32| -> u32 {
        let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
        // Every triangle edge is in `edges` by construction.
        n + edges.partition_point(|e| e.0 < key) as u32
    };
    let mut triangles = Vec::with_capacity(seq.triangles.len() * 4);
    for &[a, b, c] in &seq.triangles {
        let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
        triangles.extend_from_slice(&[[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    Sequence {
        triangles,
        frames: seq.frames.iter().map(|f| stencils.apply(f)).collect(),
        frame_rate: seq.frame_rate,
        frame_names: seq.frame_names.clone(),
        ..Default::default()
    }
}

/// The vertices at the extremes of `positions` along +Y, -X, +X, -Z and +Z (ties to the lowest
/// index), without repeats: on a standing character the head and the hands or paws, on any
/// mesh regions far apart. Seeds for [`open_regions`].
pub fn extreme_vertices(positions: &[Vec3]) -> Vec<u32> {
    let dirs = [Vec3::Y, -Vec3::X, Vec3::X, -Vec3::Z, Vec3::Z];
    let mut out: Vec<u32> = Vec::new();
    for d in dirs {
        let best = positions
            .iter()
            .enumerate()
            .fold(None::<(usize, f32)>, |b, (i, p)| match b {
                Some((_, s)) if p.dot(d) <= s => b,
                _ => Some((i, p.dot(d))),
            })
            .map(|(i, _)| i as u32);
        if let Some(v) = best
            && !out.contains(&v)
        {
            out.push(v);
        }
    }
    out
}

/// The sequence with every triangle deleted that has a corner within `radius` of a seed
/// vertex in frame 0 (a hole per seed, or more where a region cuts a thin part), and the
/// vertices no triangle uses any more dropped (the others keep their order).
pub fn open_regions(seq: &Sequence, seeds: &[u32], radius: f32) -> Sequence {
    let first = seq.frames.first().map(Vec::as_slice).unwrap_or(&[]);
    let centres: Vec<Vec3> = seeds.iter().filter_map(|&s| first.get(s as usize).copied()).collect();
    let r2 = radius * radius;
    let inside: Vec<bool> = first.iter().map(|p| centres.iter().any(|c| p.distance_squared(*c) <= r2)).collect();
    keep_triangles(seq, |t| !t.iter().any(|&v| inside[v as usize]))
}

/// The sequence cut in half: the triangles whose frame-0 centroid lies below the median along
/// `axis` (0 x, 1 y, 2 z) deleted, so one long boundary (or several, where the cut crosses
/// limbs) runs across the surface, as on a face mask or a garment; unused vertices dropped.
pub fn open_half(seq: &Sequence, axis: usize) -> Sequence {
    let first = seq.frames.first().map(Vec::as_slice).unwrap_or(&[]);
    let at = |t: &[u32; 3]| t.iter().filter_map(|&v| first.get(v as usize)).map(|p| p[axis.min(2)]).sum::<f32>() / 3.0;
    let mut centroids: Vec<f32> = seq.triangles.iter().map(at).collect();
    centroids.sort_by(f32::total_cmp);
    let median = centroids.get(centroids.len() / 2).copied().unwrap_or(0.0);
    keep_triangles(seq, |t| at(t) >= median)
}

/// The sequence with the triangles `keep` says yes to, and the vertices none of them uses
/// dropped (the others keep their order and their motion).
fn keep_triangles(seq: &Sequence, keep: impl Fn(&[u32; 3]) -> bool) -> Sequence {
    let n = seq.vertex_count();
    let kept: Vec<[u32; 3]> = seq.triangles.iter().copied().filter(|t| keep(t)).collect();
    let mut new_index = vec![u32::MAX; n];
    for t in &kept {
        for &v in t {
            new_index[v as usize] = 0;
        }
    }
    let mut next = 0u32;
    let mut old_of_new = Vec::new();
    for (v, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = next;
            old_of_new.push(v);
            next += 1;
        }
    }
    Sequence {
        triangles: kept.iter().map(|t| t.map(|v| new_index[v as usize])).collect(),
        frames: seq.frames.iter().map(|f| old_of_new.iter().map(|&v| f[v]).collect()).collect(),
        frame_rate: seq.frame_rate,
        frame_names: seq.frame_names.clone(),
        ..Default::default()
    }
}

/// Boundary edges (edges of exactly one triangle) and the number of boundary loops they form
/// (connected components of the boundary-edge graph).
pub fn boundary_loops(vertex_count: usize, triangles: &[[u32; 3]]) -> (usize, usize) {
    let half = half_edges(triangles);
    let mut parent: Vec<u32> = (0..vertex_count as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    let mut on_boundary = vec![false; vertex_count];
    let mut count = 0;
    let mut i = 0;
    while i < half.len() {
        let mut j = i + 1;
        while j < half.len() && half[j].0 == half[i].0 {
            j += 1;
        }
        if j - i == 1 {
            count += 1;
            let (u, v) = ((half[i].0 >> 32) as u32, half[i].0 as u32);
            on_boundary[u as usize] = true;
            on_boundary[v as usize] = true;
            let (ru, rv) = (find(&mut parent, u), find(&mut parent, v));
            parent[ru.max(rv) as usize] = ru.min(rv);
        }
        i = j;
    }
    let loops = (0..vertex_count as u32).filter(|&v| on_boundary[v as usize] && find(&mut parent, v) == v).count();
    (count, loops)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An octahedron: closed, every vertex of degree 4.
    fn octahedron() -> Sequence {
        let p = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let triangles = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        let moved: Vec<Vec3> = p.iter().map(|q| *q * 2.0 + Vec3::ONE).collect();
        Sequence { triangles, frames: vec![p, moved], frame_rate: 30.0, ..Default::default() }
    }

    #[test]
    fn loop_step_counts_and_motion() {
        let s = loop_subdivide(&octahedron());
        assert_eq!(s.vertex_count(), 6 + 12);
        assert_eq!(s.triangles.len(), 32);
        assert_eq!(boundary_loops(s.vertex_count(), &s.triangles), (0, 0));
        // Subdivision is linear: frame 1 is frame 0 scaled by 2 and moved by (1,1,1).
        for (a, b) in s.frames[0].iter().zip(&s.frames[1]) {
            assert!((*a * 2.0 + Vec3::ONE - *b).length() < 1e-5);
        }
        // Old vertex of degree 4: beta = 3/32, it keeps 5/8 of itself; X's neighbours sum to 0.
        assert!((s.frames[0][0] - Vec3::X * 0.625).length() < 1e-6, "{}", s.frames[0][0]);
        // Two subdivisions of the horse give the ~135k vertices of issue 15: V + E each time.
        let twice = loop_subdivide(&s);
        assert_eq!(twice.vertex_count(), 18 + 48);
    }

    #[test]
    fn boundary_edges_stay_on_their_line() {
        // A flat strip: the boundary rule keeps every vertex in the plane z = 0.
        let p: Vec<Vec3> = (0..6).map(|i| Vec3::new((i / 2) as f32, (i % 2) as f32, 0.0)).collect();
        let triangles = vec![[0, 1, 2], [2, 1, 3], [2, 3, 4], [4, 3, 5]];
        let s = loop_subdivide(&Sequence { triangles, frames: vec![p], frame_rate: 30.0, ..Default::default() });
        assert!(s.frames[0].iter().all(|q| q.z == 0.0 && q.y >= 0.0 && q.y <= 1.0));
        // Corners (two boundary neighbours at a bend still follow the rule) stay put at x = 0.
        assert_eq!(boundary_loops(s.vertex_count(), &s.triangles).1, 1);
    }

    #[test]
    fn regions_open_holes() {
        let s = loop_subdivide(&loop_subdivide(&octahedron()));
        let seeds = extreme_vertices(&s.frames[0]);
        assert_eq!(seeds.len(), 5);
        let open = open_regions(&s, &seeds, 0.1);
        let (edges, loops) = boundary_loops(open.vertex_count(), &open.triangles);
        assert_eq!(loops, 5, "one hole per seed");
        assert!(edges >= 15, "{edges}");
        assert!(open.vertex_count() < s.vertex_count());
        assert!(open.validate().is_ok());
        // Every kept vertex keeps its motion.
        assert_eq!(open.frames.len(), 2);
    }

    #[test]
    fn a_half_has_one_long_boundary() {
        let s = loop_subdivide(&loop_subdivide(&octahedron()));
        let half = open_half(&s, 1);
        let (edges, loops) = boundary_loops(half.vertex_count(), &half.triangles);
        assert_eq!(loops, 1, "a sphere cut in half");
        assert!(edges >= 16, "{edges}");
        // About half the triangles stay, every one of them on the kept side in every frame's order.
        assert!(half.triangles.len() * 2 >= s.triangles.len() && half.triangles.len() * 3 <= 2 * s.triangles.len());
        assert!(half.validate().is_ok());
        assert_eq!(half.frames.len(), s.frames.len());
    }
}
