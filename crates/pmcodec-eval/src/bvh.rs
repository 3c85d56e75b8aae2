//! A bounding volume hierarchy over triangles for closest-point queries: flat node array,
//! `u32` links, median splits on the longest axis, and a stack-based query that visits the
//! nearer child first and prunes by squared box distance against the best so far.

use glam::Vec3;
use pmcodec_mesh::TriMesh;

const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: first primitive in `order`; inner: index of the left child (right = left + 1).
    start: u32,
    /// Leaf: primitive count (> 0); inner: 0.
    count: u32,
}

/// Closest-point index over a mesh's triangles.
#[derive(Clone, Debug)]
pub struct SurfaceIndex {
    nodes: Vec<Node>,
    tris: Vec<[Vec3; 3]>,
}

impl SurfaceIndex {
    pub fn new(mesh: &TriMesh) -> Self {
        let n = mesh.positions.len() as u32;
        let tris: Vec<[Vec3; 3]> = mesh
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&i| i < n))
            .map(|t| t.map(|i| mesh.positions[i as usize]))
            .collect();
        let mut centroids: Vec<(Vec3, u32)> =
            tris.iter().enumerate().map(|(i, t)| ((t[0] + t[1] + t[2]) / 3.0, i as u32)).collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF_SIZE + 1);
        nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
        // Iterative build: (node index, range of centroids).
        let mut work = vec![(0usize, 0usize, centroids.len())];
        while let Some((ni, a, b)) = work.pop() {
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for &(_, t) in &centroids[a..b] {
                for p in tris[t as usize] {
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
            if b - a <= LEAF_SIZE {
                nodes[ni] = Node { lo, hi, start: a as u32, count: (b - a) as u32 };
                continue;
            }
            let ext = hi - lo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z { 0 } else if ext.y >= ext.z { 1 } else { 2 };
            let mid = (a + b) / 2;
            centroids[a..b].select_nth_unstable_by(mid - a, |x, y| x.0[axis].total_cmp(&y.0[axis]));
            let left = nodes.len();
            nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
            nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
            nodes[ni] = Node { lo, hi, start: left as u32, count: 0 };
            work.push((left, a, mid));
            work.push((left + 1, mid, b));
        }
        // Store triangles in leaf order so leaves read contiguous memory.
        let tris = centroids.iter().map(|&(_, t)| tris[t as usize]).collect();
        SurfaceIndex { nodes, tris }
    }

    /// Squared distance from `p` to the closest point of the surface, and that triangle's
    /// index in leaf order (`u32::MAX` and infinity for an empty index).
    pub fn closest(&self, p: Vec3) -> (f32, u32) {
        let mut best = (f32::INFINITY, u32::MAX);
        if self.tris.is_empty() {
            return best;
        }
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if box_distance2(p, node.lo, node.hi) >= best.0 {
                continue;
            }
            if node.count > 0 {
                for i in node.start..node.start + node.count {
                    let d = point_triangle_distance2(p, &self.tris[i as usize]);
                    if d < best.0 {
                        best = (d, i);
                    }
                }
            } else {
                let (l, r) = (node.start, node.start + 1);
                let dl = box_distance2(p, self.nodes[l as usize].lo, self.nodes[l as usize].hi);
                let dr = box_distance2(p, self.nodes[r as usize].lo, self.nodes[r as usize].hi);
                // Push the farther first so the nearer is visited first.
                let (first, second) = if dl <= dr { (r, l) } else { (l, r) };
                if top + 2 <= stack.len() {
                    stack[top] = first;
                    stack[top + 1] = second;
                    top += 2;
                }
            }
        }
        best
    }
}

#[inline]
fn box_distance2(p: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    let d = (lo - p).max(p - hi).max(Vec3::ZERO);
    d.length_squared()
}

/// Squared distance from p to triangle t, by the region of the closest feature (vertex, edge
/// or face) on the triangle's plane, computed from barycentric-style dot products.
pub fn point_triangle_distance2(p: Vec3, t: &[Vec3; 3]) -> f32 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + ab * v)).length_squared();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + ac * w)).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length_squared();
    }
    let denom = va + vb + vc;
    if !(denom.abs() > 0.0) {
        // Degenerate (zero-area) triangle: the nearest of its three edges.
        return seg2(p, a, b).min(seg2(p, b, c)).min(seg2(p, a, c));
    }
    let (v, w) = (vb / denom, vc / denom);
    (p - (a + ab * v + ac * w)).length_squared()
}

fn seg2(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).length_squared()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(p: Vec3, m: &TriMesh) -> f32 {
        m.triangles.iter().map(|t| point_triangle_distance2(p, &t.map(|i| m.positions[i as usize]))).fold(f32::INFINITY, f32::min)
    }

    #[test]
    fn bvh_matches_brute_force() {
        let mut s = 1u64;
        let mut r = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let positions: Vec<Vec3> = (0..300).map(|_| Vec3::new(r(), r(), r()) * 10.0).collect();
        let triangles: Vec<[u32; 3]> = (0..200).map(|i| [i % 300, (i * 7 + 1) % 300, (i * 13 + 2) % 300]).collect();
        let m = TriMesh { positions, triangles };
        let idx = SurfaceIndex::new(&m);
        for _ in 0..500 {
            let p = Vec3::new(r(), r(), r()) * 14.0 - 2.0;
            let (d, _) = idx.closest(p);
            assert!((d - brute(p, &m)).abs() <= 1e-4 * (1.0 + d), "{d} vs {}", brute(p, &m));
        }
    }

    #[test]
    fn closest_point_regions() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!((point_triangle_distance2(Vec3::new(0.2, 0.2, 1.0), &t) - 1.0).abs() < 1e-6); // face
        assert!((point_triangle_distance2(Vec3::new(-1.0, -1.0, 0.0), &t) - 2.0).abs() < 1e-6); // vertex a
        assert!((point_triangle_distance2(Vec3::new(0.5, -1.0, 0.0), &t) - 1.0).abs() < 1e-6); // edge ab
        assert!((point_triangle_distance2(Vec3::new(1.0, 1.0, 0.0), &t) - 0.5).abs() < 1e-6); // edge bc
        let flat = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert!((point_triangle_distance2(Vec3::new(1.0, 1.0, 0.0), &flat) - 1.0).abs() < 1e-6);
    }
}
