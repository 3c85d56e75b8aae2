//! Wedges in the simplifier: the attribute records (texture coordinates, colours, material) at
//! triangle corners, their seams, and the attribute quadrics that price and solve them.
//!
//! A *wedge* is a (vertex, attribute record) pair (Hoppe, "New quadric metric for simplifying
//! meshes with appearance attributes", 1999). Corners with equal texture coordinates, colour and
//! material at one vertex share a wedge; a vertex with several wedges sits on a *seam* (a UV
//! island's border, a colour break, a material boundary). Normals do not make seams here: every
//! level's normals are recomputed from its positions (see [`crate::gltf_out`]), and the input's
//! normals only say where creases are.
//!
//! * **Seams move only along themselves.** Collapsing `gone` into `keep` maps each wedge of
//!   `gone` to the wedge of `keep` it meets across a triangle on the edge; every wedge of `gone`
//!   must be mapped, and to one wedge only ([`wedge_map`]). A vertex inside one attribute region
//!   then collapses freely; a vertex on a seam only along the seam (its two wedges map to the
//!   two wedges of the next seam vertex); a seam corner (three regions meet) never. Triangles
//!   keep their material, so no triangle at any level straddles two materials.
//! * **Attribute error.** Each wedge carries, per attribute channel, the quadric of Garland &
//!   Heckbert ("Simplifying surfaces with color and texture using quadric error metrics", 1998)
//!   in Hoppe's split form: per face, the channel is the linear function `s(p) = g . p + d` over
//!   the face's plane, and the error of value `s` at position `p` is `area (g . p + d - s)^2`.
//!   Summed over the faces of a wedge, it is a quadric in `(p, s)`; for the position the
//!   placement chose, the best value is its minimiser in `s` ([`AttrQuadric::solve`]), which is
//!   both the collapse's attribute cost and the wedge's new attribute (solved per wedge).

use glam::{DVec3, Vec3};
use pmcodec_mesh::Appearance;
use std::collections::HashMap;

/// The wedges of the welded input, as the simplifier starts from them.
#[derive(Clone, Debug, Default)]
pub struct Wedges {
    /// Per input triangle, the wedge of each corner.
    pub corner: Vec<[u32; 3]>,
    /// Material of each input triangle.
    pub material: Vec<u32>,
    /// Input vertex of each wedge.
    pub vertex: Vec<u32>,
    /// Attribute values, `channels` per wedge: uv0 (2), uv1 (2), colour (4), those present.
    pub values: Vec<f32>,
    pub channels: usize,
    pub layout: Layout,
    /// The input normal of each wedge (of its first input corner), or empty.
    pub normals: Vec<[f32; 3]>,
}

/// Which attributes the channels hold, in this order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Layout {
    pub uv0: bool,
    pub uv1: bool,
    pub colors: bool,
}

impl Wedges {
    /// The simplifier's wedges of a welded mesh with an appearance: input wedges merged when
    /// they agree on vertex, texture coordinates, colour and material (normals left out).
    pub fn from_appearance(app: &Appearance) -> Self {
        let layout = Layout { uv0: !app.uv0.is_empty(), uv1: !app.uv1.is_empty(), colors: !app.colors.is_empty() };
        let channels = 2 * usize::from(layout.uv0) + 2 * usize::from(layout.uv1) + 4 * usize::from(layout.colors);
        let mut out = Wedges { channels, layout, ..Default::default() };
        let mut first: HashMap<Vec<u32>, u32> = HashMap::new();
        let mut record = Vec::with_capacity(channels);
        for (t, cw) in app.corner_wedges.iter().enumerate() {
            let material = app.material_of(t);
            out.material.push(material);
            out.corner.push(cw.map(|w| {
                let w = w as usize;
                record.clear();
                if layout.uv0 {
                    record.extend(app.uv0[w]);
                }
                if layout.uv1 {
                    record.extend(app.uv1[w]);
                }
                if layout.colors {
                    record.extend(app.colors[w]);
                }
                let vertex = app.wedge_vertex[w];
                let mut key: Vec<u32> = vec![vertex, material];
                key.extend(record.iter().map(|x| x.to_bits()));
                *first.entry(key).or_insert_with(|| {
                    out.vertex.push(vertex);
                    out.values.extend_from_slice(&record);
                    if let Some(n) = app.normals.get(w) {
                        out.normals.push(*n);
                    }
                    out.vertex.len() as u32 - 1
                })
            }));
        }
        out
    }

    pub fn len(&self) -> usize {
        self.vertex.len()
    }

    /// Per wedge and channel, the attribute quadric of its faces in `rest` positions.
    pub fn quadrics(&self, rest: &[Vec3], triangles: &[[u32; 3]]) -> Vec<AttrQuadric> {
        let c = self.channels;
        let mut out = vec![AttrQuadric::default(); self.len() * c];
        for (tri, cw) in triangles.iter().zip(&self.corner) {
            let p = tri.map(|i| rest[i as usize].as_dvec3());
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let n = e1.cross(e2);
            let area = 0.5 * n.length();
            if !(area > 0.0) {
                continue;
            }
            // Rows e1, e2, n: the gradient g solves e1.g = s1 - s0, e2.g = s2 - s0, n.g = 0.
            let det = n.length_squared();
            for ch in 0..c {
                let s = cw.map(|w| f64::from(self.values[w as usize * c + ch]));
                let (ds1, ds2) = (s[1] - s[0], s[2] - s[0]);
                // g = (ds1 (e2 x n) + ds2 (n x e1)) / |n|^2.
                let g = (e2.cross(n) * ds1 + n.cross(e1) * ds2) / det;
                let d = s[0] - g.dot(p[0]);
                let q = AttrQuadric::face(g, d, area);
                for &w in cw {
                    out[w as usize * c + ch].add(&q);
                }
            }
        }
        out
    }

    /// Interior edges `(a, b, t1, t2)` whose two triangles disagree on the wedge at either end
    /// (or on the material): the seams, which get constraint planes like boundaries.
    pub fn seam_edges(&self, triangles: &[[u32; 3]], interior: &[(u32, u32, u32, u32)]) -> Vec<(u32, u32, u32, u32)> {
        let wedge_at = |t: u32, v: u32| {
            let tri = triangles[t as usize];
            tri.iter().position(|&c| c == v).map(|i| self.corner[t as usize][i])
        };
        interior
            .iter()
            .copied()
            .filter(|&(a, b, t1, t2)| {
                self.material[t1 as usize] != self.material[t2 as usize]
                    || wedge_at(t1, a) != wedge_at(t2, a)
                    || wedge_at(t1, b) != wedge_at(t2, b)
            })
            .collect()
    }
}

/// Maps the wedges of `gone` to those of `keep` for the collapse of edge (`gone`, `keep`), or
/// `None` when the collapse would tear or smear a seam (see the module documentation).
/// `tris`/`corner` are the live triangles and their corner wedges, `around_gone` the triangles
/// of `gone`.
pub fn wedge_map(tris: &[[u32; 3]], corner: &[[u32; 3]], around_gone: &[u32], gone: u32, keep: u32) -> Option<Vec<(u32, u32)>> {
    let mut map: Vec<(u32, u32)> = Vec::with_capacity(2);
    let at = |t: u32, v: u32| tris[t as usize].iter().position(|&c| c == v).map(|i| corner[t as usize][i]);
    for &t in around_gone {
        if !tris[t as usize].contains(&keep) {
            continue;
        }
        let (wg, wk) = (at(t, gone)?, at(t, keep)?);
        match map.iter().find(|(g, _)| *g == wg) {
            Some(&(_, k)) if k != wk => return None,
            Some(_) => {}
            None => map.push((wg, wk)),
        }
    }
    for &t in around_gone {
        let wg = at(t, gone)?;
        if !map.iter().any(|(g, _)| *g == wg) {
            return None;
        }
    }
    Some(map)
}

/// Garland & Heckbert's attribute quadric for one channel in `(p, s)`: `x' A x + 2 b' x + c`
/// with `x = (p, s)`, `A` symmetric 4x4 stored as its upper triangle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AttrQuadric {
    /// a00 a01 a02 a03 a11 a12 a13 a22 a23 a33.
    pub a: [f64; 10],
    pub b: [f64; 4],
    pub c: f64,
}

impl AttrQuadric {
    /// `area (g . p + d - s)^2`, i.e. `area (h . x + d)^2` with `h = (g, -1)`.
    pub fn face(g: DVec3, d: f64, area: f64) -> Self {
        let h = [g.x, g.y, g.z, -1.0];
        let mut a = [0.0; 10];
        let mut k = 0;
        for i in 0..4 {
            for j in i..4 {
                a[k] = area * h[i] * h[j];
                k += 1;
            }
        }
        AttrQuadric { a, b: h.map(|x| area * d * x), c: area * d * d }
    }

    pub fn add(&mut self, o: &AttrQuadric) {
        for i in 0..10 {
            self.a[i] += o.a[i];
        }
        for i in 0..4 {
            self.b[i] += o.b[i];
        }
        self.c += o.c;
    }

    /// The value minimising the error at `p` (`fallback` when the wedge has no area), and that
    /// error.
    pub fn solve(&self, p: DVec3, fallback: f64) -> (f64, f64) {
        let [a00, a01, a02, a03, a11, a12, a13, a22, a23, a33] = self.a;
        let ps = a03 * p.x + a13 * p.y + a23 * p.z + self.b[3];
        let s = if a33 > 1e-30 { -ps / a33 } else { fallback };
        let pp = p.x * (a00 * p.x + 2.0 * (a01 * p.y + a02 * p.z)) + p.y * (a11 * p.y + 2.0 * a12 * p.z) + a22 * p.z * p.z;
        let lin = 2.0 * (self.b[0] * p.x + self.b[1] * p.y + self.b[2] * p.z);
        // E(p, s) = p'A_pp p + 2 b_p . p + c + 2 s ps + a33 s^2, ps holding b_s.
        let e = pp + lin + self.c + 2.0 * s * ps + a33 * s * s;
        (s, e.max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_linear_attribute_has_no_error_and_is_reproduced() {
        // s = 2x + 3y + 1 on two triangles of the z = 0 plane.
        let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        let s = |p: Vec3| 2.0 * p.x + 3.0 * p.y + 1.0;
        let w = Wedges {
            corner: vec![[0, 1, 2], [1, 3, 2]],
            material: vec![0, 0],
            vertex: vec![0, 1, 2, 3],
            values: rest.iter().map(|&p| s(p)).collect(),
            channels: 1,
            layout: Layout::default(),
            normals: Vec::new(),
        };
        let q = w.quadrics(&rest, &[[0, 1, 2], [1, 3, 2]]);
        let p = Vec3::new(0.3, 0.6, 0.0);
        let (value, err) = q[1].solve(p.as_dvec3(), 0.0);
        assert!((value - f64::from(s(p))).abs() < 1e-9, "{value}");
        assert!(err < 1e-9, "{err}");
        // Off the linear function, the error is area-weighted squared distance in s.
        let (_, e0) = q[0].solve(DVec3::ZERO, 0.0);
        assert!(e0 < 1e-9);
        let mut bent = q[0];
        bent.add(&AttrQuadric::face(DVec3::ZERO, 5.0, 2.0));
        let (v, e) = bent.solve(DVec3::ZERO, 0.0);
        // Two faces: s = 1 with area 0.5 and s = 5 with area 2: the mean is 4.2.
        assert!((v - 4.2).abs() < 1e-9, "{v}");
        assert!((e - (0.5 * 3.2f64.powi(2) + 2.0 * 0.8f64.powi(2))).abs() < 1e-9, "{e}");
    }

    #[test]
    fn seam_vertices_collapse_only_along_the_seam() {
        // A strip of four triangles; the vertical line x = 1 (vertices 1, 4) is a UV seam:
        // left triangles use wedges 0..., right triangles their own wedges at 1 and 4.
        //   3---4---5
        //   | / | / |
        //   0---1---2
        let tris = vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]];
        let corner = vec![[0, 1, 4], [0, 4, 3], [6, 2, 5], [6, 5, 7]];
        // Vertex 1 has wedges 1 (left) and 6 (right); vertex 4 has 4 and 7.
        let around = |v: u32| -> Vec<u32> { (0..4).filter(|&t| tris[t as usize].contains(&v)).collect() };
        // Along the seam: 1 into 4 maps both wedges.
        let map = wedge_map(&tris, &corner, &around(1), 1, 4).unwrap();
        assert_eq!(map, [(1, 4), (6, 7)]);
        // Off the seam: 1 into 0 would leave wedge 6 unmapped.
        assert!(wedge_map(&tris, &corner, &around(1), 1, 0).is_none());
        // Interior-side vertex 0 into seam vertex 1: one wedge, one target.
        assert_eq!(wedge_map(&tris, &corner, &around(0), 0, 1).unwrap(), [(0, 1)]);
    }
}
