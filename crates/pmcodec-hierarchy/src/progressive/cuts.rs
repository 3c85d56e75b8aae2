//! Cuts a replay chooses from decoded data alone.

use super::*;

/// Cuts chosen from decoded data alone. The file carries no quadrics, so a decoder makes them
/// from what it decodes (Garland & Heckbert's plane quadrics, as the encoder's clusters are
/// built on; Kircher & Garland section 3): each triangle alive at the replay's finest level L
/// gives its three level-L corners the quadric of its plane weighted by a third of its area, a
/// node's quadric is the sum over its cluster, and its *own error* is the RMS distance
/// `sqrt(Q(x) / area)` of its cluster's faces from its decoded position `x`. A node's split
/// priority is the largest own error in its subtree, so priorities are monotone (a node's is
/// at least each child's) and "every split above an error bound" is a prefix of the order.
///
/// Against the largest distance to any finer node (what versions up to 4 of the spec used), a
/// flat cluster, however wide, no longer asks to be split first: on the horse, vertex-budget
/// cuts at 843 vertices have 28% less RMS surface error (0.094% -> 0.068% of the diagonal,
/// as good as the level of that size), 35% less at 3,000. Specified in proto/container.md
/// ("Cuts"), operation by operation, so every decoder picks the same cut.
impl Replay {
    /// Split priorities of every node from node positions (global ids).
    pub fn node_errors(&self, positions: &[Vec3]) -> Vec<f64> {
        let mut err = Vec::new();
        self.node_errors_into(positions, &mut err);
        err
    }

    /// [`Self::node_errors`] into a buffer (resized to the node count).
    pub fn node_errors_into(&self, positions: &[Vec3], err: &mut Vec<f64>) {
        let q = self.cluster_quadrics(positions);
        let first_above = self.first_above();
        err.clear();
        err.resize(self.h.node_count(), 0.0);
        for ((out, m), x) in err.iter_mut().zip(&q).zip(positions).skip(first_above) {
            let e = quadric_at(m, *x);
            *out = if m[10] > 0.0 && e > 0.0 { (e / m[10]).sqrt() } else { 0.0 };
        }
        self.subtree_max(err);
    }

    /// Reveal priorities of every node from node positions (global ids): what vertex and
    /// triangle budgets reveal by when a decoder cuts them by partial splits (an option,
    /// [`crate::split_order::Steps`]; proto/container.md, "Cuts", "Partial splits"). Revealing child c of node P moves c's cluster from P's
    /// position to c's own: its own benefit is what Garland & Heckbert's "Surface
    /// Simplification Using Quadric Error Metrics" (1997) would charge for collapsing c into
    /// P, `dQ = Q_c(x_P) - Q_c(x_c)` with c's cluster quadric, as `sqrt(dQ / sqrt(area))`
    /// (the area scaling whole splits had, see below), and its priority the largest in its
    /// subtree (monotone, as [`Self::node_errors`], so every reveal above a bound is a
    /// prefix). Top-level nodes are always revealed; theirs is unused.
    ///
    /// Measured (`pmcodec eval --sweep 12 --frames 12`, container over direct, horse-gallop):
    /// `dQ` alone (`area^0`) is within 4% from 1.4% of the vertices up but 1.50x against 1.18x
    /// at 1%; `dQ / area` (the mean) loses 3-22% from 2% up (1.93x against 1.64x at 50%).
    /// Against whole splits by [`Self::split_benefits_into`] (what budgets split by by
    /// default) no worse than 1% at any budget of horse-gallop, samba-60, cat-poses and the waving
    /// cloth, most better between levels: at 50% of the vertices horse 1.91x -> 1.64x, cat
    /// 2.34x -> 1.86x, cloth 2.75x -> 2.24x. Ordering each node's children by area instead
    /// (only how many are revealed left to `dQ`) lost 5-19% and flickered as much. Ranked on
    /// each frame's positions the cut flickers (issue 15): the spec keeps whole splits as the
    /// default for that reason (proto/container.md, "Partial splits").
    pub fn reveal_benefits_into(&self, positions: &[Vec3], out: &mut Vec<f64>) {
        let q = self.cluster_quadrics(positions);
        let h = &self.h;
        out.clear();
        out.resize(h.node_count(), 0.0);
        for k in self.min_level..h.levels() - 1 {
            for (v, &p) in h.parent[k].iter().enumerate() {
                let (c, a) = ((h.offsets[k] + v as u32) as usize, (h.offsets[k + 1] + p) as usize);
                let (Some(m), Some(&xc), Some(&xa)) = (q.get(c), positions.get(c), positions.get(a)) else { continue };
                let dq = quadric_at(m, xa) - quadric_at(m, xc);
                out[c] = if m[10] > 0.0 && dq > 0.0 { (dq / m[10].sqrt()).sqrt() } else { 0.0 };
            }
        }
        self.subtree_max(out);
    }

    /// Budget priorities of every node from node positions (global ids): what vertex and
    /// triangle budgets split by (proto/container.md, "Cuts"). A node's own benefit is
    /// `sqrt(Q(x) / sqrt(area))`, its RMS error scaled by the fourth root of its cluster's area,
    /// and its priority the largest in its subtree (monotone, as [`Self::node_errors`]).
    ///
    /// The RMS alone is blind to the cluster's size: a small cluster a unit off outranks a wide
    /// one nearly as far off, and a budget spent by it leaves the wide one coarse, although the
    /// surface error a client sees is an integral over area (what Garland & Heckbert's
    /// "Surface Simplification Using Quadric Error Metrics", 1997, sum as `Q(x)`). Ranking by
    /// the drop in `Q` per added vertex cut more error between levels 0 and 1 but left small
    /// features coarse at the coarsest budgets (horse-gallop at 1% of the vertices: 2.2x plain
    /// QEM against 1.2x; likely elongated ones, whose plane quadrics see their radius, not
    /// their length); ranking by `Q(x)` itself lost up to 7% at 4-8% of the vertices. The
    /// fourth root measured within 3% of the RMS priority at every budget of horse-gallop and
    /// samba-60, up to 8% better between levels 0 and 1 on them and 12% on cat-poses (`pmcodec
    /// eval --sweep 12 --frames 12`); the waving cloth loses 4-12% at 35-50% (proto/container.md).
    pub fn split_benefits_into(&self, positions: &[Vec3], out: &mut Vec<f64>) {
        let q = self.cluster_quadrics(positions);
        let first_above = self.first_above();
        out.clear();
        out.resize(self.h.node_count(), 0.0);
        for ((o, m), x) in out.iter_mut().zip(&q).zip(positions).skip(first_above) {
            let e = quadric_at(m, *x);
            *o = if m[10] > 0.0 && e > 0.0 { (e / m[10].sqrt()).sqrt() } else { 0.0 };
        }
        self.subtree_max(out);
    }

    /// Global id of the first node above level L (the node count with one level).
    fn first_above(&self) -> usize {
        self.h.offsets.get(self.min_level + 1).map_or(self.h.node_count(), |&o| o as usize)
    }

    /// Every node's plane quadric (proto/container.md, "Cuts"): a00 a01 a02 a11 a12 a22 b0 b1 b2
    /// c, then the area; level-L nodes' from their faces, summed over clusters finest first.
    fn cluster_quadrics(&self, positions: &[Vec3]) -> Vec<[f64; 11]> {
        let h = &self.h;
        let nodes = h.node_count();
        let mut q = vec![[0f64; 11]; nodes];
        let (base, size) = (h.offsets[self.min_level] as usize, h.level_sizes[self.min_level] as usize);
        let at = |v: u32| positions.get(base + v as usize).map(|p| [p.x as f64, p.y as f64, p.z as f64]);
        for c in &self.corners {
            if !distinct(*c) || c.iter().any(|&v| v as usize >= size) {
                continue;
            }
            let (Some(p0), Some(p1), Some(p2)) = (at(c[0]), at(c[1]), at(c[2])) else { continue };
            let e1 = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
            let e2 = [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]];
            let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if !(len > 0.0 && len.is_finite()) {
                continue;
            }
            let u = [n[0] / len, n[1] / len, n[2] / len];
            let d = -(u[0] * p0[0] + u[1] * p0[1] + u[2] * p0[2]);
            let w = len / 6.0;
            let plane = [
                w * (u[0] * u[0]),
                w * (u[0] * u[1]),
                w * (u[0] * u[2]),
                w * (u[1] * u[1]),
                w * (u[1] * u[2]),
                w * (u[2] * u[2]),
                w * (d * u[0]),
                w * (d * u[1]),
                w * (d * u[2]),
                w * (d * d),
                w,
            ];
            for &v in c {
                let acc = &mut q[base + v as usize];
                for i in 0..11 {
                    acc[i] += plane[i];
                }
            }
        }
        // Sums over clusters, finest level first.
        for k in self.min_level..h.levels() - 1 {
            for (v, &p) in h.parent[k].iter().enumerate() {
                let (c, a) = ((h.offsets[k] + v as u32) as usize, (h.offsets[k + 1] + p) as usize);
                if let (Some(&child), Some(_)) = (q.get(c), q.get(a)) {
                    for i in 0..11 {
                        q[a][i] += child[i];
                    }
                }
            }
        }
        q
    }

    /// Each node's value raised to the largest in its subtree, finest level first.
    fn subtree_max(&self, values: &mut [f64]) {
        let h = &self.h;
        for k in self.min_level..h.levels() - 1 {
            for (v, &p) in h.parent[k].iter().enumerate() {
                let (c, a) = ((h.offsets[k] + v as u32) as usize, (h.offsets[k + 1] + p) as usize);
                if let (Some(&e), Some(_)) = (values.get(c), values.get(a))
                    && e > values[a]
                {
                    values[a] = e;
                }
            }
        }
    }

    /// Collapses the whole cut, in time proportional to it: the cut is closed upward, so every
    /// expanded node lies under an expanded top-level node.
    pub(super) fn collapse_all(&mut self) {
        let top = self.h.top();
        for g in self.h.offsets[top]..self.h.offsets[top + 1] {
            if self.expanded[g as usize] {
                self.collapse(g);
            }
        }
        debug_assert!(!self.expanded.iter().any(|&e| e), "the cut was not closed upward");
    }

    /// The cut node standing for level-L node `v` (local id): its highest ancestor (itself
    /// included) whose parent is expanded, or its top-level ancestor. Walks up the local
    /// parent maps, so its cost is the node's depth below the cut.
    #[inline]
    pub fn cut_node_of(&self, v: u32) -> u32 {
        let h = &self.h;
        let (mut k, mut v) = (self.min_level, v);
        while k < h.top() {
            let p = h.parent[k][v as usize];
            if self.expanded[(h.offsets[k + 1] + p) as usize] {
                break;
            }
            (k, v) = (k + 1, p);
        }
        h.offsets[k] + v
    }

    /// Every node above `level` expanded (clamped to what this replay tracks). Budgets and
    /// error bounds are prefixes of the frame's [`crate::split_order::SplitOrder`].
    pub fn select_level(&mut self, level: usize) {
        self.collapse_all();
        let level = level.max(self.min_level).min(self.h.top());
        for g in self.h.offsets[level + 1]..self.h.offsets[self.h.levels()] {
            self.expand(g);
        }
    }

    /// The mesh the current cut shows, with node positions (global ids): its vertices are the
    /// cut nodes used by shown triangles, in first-use order.
    pub fn mesh(&self, positions: &[Vec3]) -> (pmcodec_mesh::TriMesh, Vec<u32>) {
        let rep = self.cut_nodes();
        let base = self.h.offsets[self.min_level];
        let mut index_of = std::collections::HashMap::new();
        let mut nodes = Vec::new();
        let mut mesh = pmcodec_mesh::TriMesh::default();
        for &t in &self.shown {
            let c = self.corners[t as usize];
            let tri = c.map(|x| {
                let g = rep.get((base + x) as usize).copied().unwrap_or(NONE);
                *index_of.entry(g).or_insert_with(|| {
                    nodes.push(g);
                    mesh.positions.push(positions.get(g as usize).copied().unwrap_or(Vec3::ZERO));
                    nodes.len() as u32 - 1
                })
            });
            mesh.triangles.push(tri);
        }
        (mesh, nodes)
    }
}

/// `x^T A x + 2 b.x + c` of quadric `m` at `x`, in the operation order of proto/container.md.
fn quadric_at(m: &[f64; 11], x: Vec3) -> f64 {
    let x = [x.x as f64, x.y as f64, x.z as f64];
    let ax = m[0] * x[0] + m[1] * x[1] + m[2] * x[2];
    let ay = m[1] * x[0] + m[3] * x[1] + m[4] * x[2];
    let az = m[2] * x[0] + m[4] * x[1] + m[5] * x[2];
    x[0] * ax + x[1] * ay + x[2] * az + 2.0 * (m[6] * x[0] + m[7] * x[1] + m[8] * x[2]) + m[9]
}
