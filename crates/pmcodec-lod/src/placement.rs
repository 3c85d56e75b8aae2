//! Where a collapsed vertex goes, and which skin and morph deltas it gets.
//!
//! The cost of a placement is the sum over poses of the pose's quadrics (both endpoints',
//! weighted) at the vertex's position *in that pose*, which depends on the vertex's skin and
//! morph deltas (see [`crate::attrs`]). Three policies:
//!
//! * [`Placement::Endpoint`] (Mohr & Gleicher, "Deformation Sensitive
//!   Decimation", 2003, section 4.3): the survivor is one of the
//!   two endpoints, unchanged. Influence sets, weights and morph deltas stay exactly those of an
//!   input vertex. The cheaper endpoint wins.
//! * [`Placement::Blended`]: influences blended half and half from both endpoints, cut to the
//!   four heaviest and renormalised; morph deltas averaged; the rest position is the minimiser of
//!   the summed quadric pulled back to rest space through every pose's affine map (exact for
//!   linear blend skinning: the pose position is affine in the rest position once the weights
//!   are fixed).
//! * [`Placement::HoulePoulin`] (Houle & Poulin, "Simplification and Real-time Smooth
//!   Transitions of Articulated Meshes", 2001, section 4.1): the survivor keeps one endpoint's skin
//!   and morph deltas, and its position moves by a translation expressed in that vertex's own
//!   bone space, i.e. in rest space before skinning. Houle & Poulin pick the translation in one
//!   pose; we pick it as the minimiser over all poses (the same pull-back), for both endpoints,
//!   and keep the cheaper. This is our generalisation, stated here and in `proto/lod.md`.
//!
//! Solves are regularised toward the midpoint of the two rest positions (see
//! [`pmcodec_hierarchy::Quadric::optimal`]), so a flat neighbourhood does not send the vertex
//! sliding away.

use crate::attrs::{Vertex, VertexAttrs, blend_influences};
use crate::poses::Pose;
use glam::{DVec3, Mat3, Vec3};
use pmcodec_hierarchy::Quadric;

/// How a collapse places the surviving vertex (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Placement {
    /// Keep the cheaper endpoint as it is (Mohr & Gleicher 2003, 4.3).
    Endpoint,
    /// Blend both endpoints' skins and solve the rest position over all poses.
    Blended,
    /// One endpoint's skin, moved by a bone-space translation (Houle & Poulin 2001, 4.1, over all poses).
    #[default]
    HoulePoulin,
}

impl Placement {
    /// Every policy: endpoint, blended, Houle & Poulin (examples and tests compare all three).
    pub const ALL: [Placement; 3] = [Placement::Endpoint, Placement::Blended, Placement::HoulePoulin];

    /// The policy's name on the command line and in the GLB's `extras` (`endpoint`, `blended`, `houle-poulin`).
    pub fn name(self) -> &'static str {
        match self {
            Placement::Endpoint => "endpoint",
            Placement::Blended => "blended",
            Placement::HoulePoulin => "houle-poulin",
        }
    }

    /// The policy named `s` (see [`Placement::name`]); `None` for any other text.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == s)
    }
}

/// A symmetric quadric `x'Ax + 2b'x + c` without the cluster moments: one per vertex per pose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Q {
    /// a00 a01 a02 a11 a12 a22.
    pub a: [f64; 6],
    pub b: [f64; 3],
    pub c: f64,
}

impl Q {
    pub fn from_quadric(q: &Quadric, scale: f64) -> Self {
        Q { a: q.a.map(|x| x * scale), b: q.b.map(|x| x * scale), c: q.c * scale }
    }

    #[inline]
    pub fn add(&mut self, o: &Q) {
        for i in 0..6 {
            self.a[i] += o.a[i];
        }
        for i in 0..3 {
            self.b[i] += o.b[i];
        }
        self.c += o.c;
    }

    #[inline]
    fn mul(&self, x: DVec3) -> DVec3 {
        let [a00, a01, a02, a11, a12, a22] = self.a;
        DVec3::new(a00 * x.x + a01 * x.y + a02 * x.z, a01 * x.x + a11 * x.y + a12 * x.z, a02 * x.x + a12 * x.y + a22 * x.z)
    }

    #[inline]
    pub fn eval(&self, x: DVec3) -> f64 {
        x.dot(self.mul(x)) + 2.0 * x.dot(DVec3::from_array(self.b)) + self.c
    }

    /// The quadric of `p -> self(L p + c)`.
    #[inline]
    pub fn pullback(&self, l: Mat3, c: Vec3) -> Q {
        let cols = [l.x_axis.as_dvec3(), l.y_axis.as_dvec3(), l.z_axis.as_dvec3()];
        let c = c.as_dvec3();
        let acol = cols.map(|x| self.mul(x));
        let ac = self.mul(c);
        let b = DVec3::from_array(self.b);
        let r = ac + b;
        Q {
            a: [
                cols[0].dot(acol[0]),
                cols[0].dot(acol[1]),
                cols[0].dot(acol[2]),
                cols[1].dot(acol[1]),
                cols[1].dot(acol[2]),
                cols[2].dot(acol[2]),
            ],
            b: [cols[0].dot(r), cols[1].dot(r), cols[2].dot(r)],
            c: c.dot(ac) + 2.0 * b.dot(c) + self.c,
        }
    }

    /// Regularised minimiser, pulled toward `centre`.
    pub fn optimal(&self, centre: Vec3) -> DVec3 {
        let q = Quadric { a: self.a, b: self.b, c: self.c, area: 0.0, count: 1.0, sum: centre.as_dvec3().to_array() };
        q.optimal()
    }
}

/// The outcome of placing one collapse.
#[derive(Clone, Debug)]
pub struct Candidate {
    pub cost: f64,
    pub vertex: Vertex,
    /// Which endpoint's slot survives (the other is merged into it).
    pub keep: u32,
}

/// What a placement needs to see of the simplifier's state.
pub struct Context<'a> {
    pub attrs: &'a VertexAttrs,
    pub verts: &'a [Vertex],
    pub poses: &'a [Pose],
    /// `posed[v * F + f]`: position of vertex `v` in pose `f`.
    pub posed: &'a [Vec3],
    /// `quadrics[v * F + f]`.
    pub quadrics: &'a [Q],
}

impl Context<'_> {
    fn f(&self) -> usize {
        self.poses.len()
    }

    fn merged(&self, u: u32, v: u32) -> impl Iterator<Item = Q> + '_ {
        let f = self.f();
        let (u, v) = (u as usize * f, v as usize * f);
        (0..f).map(move |k| {
            let mut q = self.quadrics[u + k];
            q.add(&self.quadrics[v + k]);
            q
        })
    }

    /// Cost of keeping endpoint `e` as it is.
    pub(crate) fn endpoint_cost(&self, u: u32, v: u32, e: u32) -> f64 {
        let f = self.f();
        self.merged(u, v).enumerate().map(|(k, q)| q.eval(self.posed[e as usize * f + k].as_dvec3()).max(0.0)).sum()
    }

    /// Best rest position for a record whose skin and morph deltas are fixed, and its cost.
    fn solve(&self, u: u32, v: u32, mut vert: Vertex) -> (f64, Vertex) {
        let mut total = Q::default();
        for (q, pose) in self.merged(u, v).zip(self.poses) {
            let (l, c) = self.attrs.affine(&vert, pose);
            total.add(&q.pullback(l, c));
        }
        let centre = (self.verts[u as usize].rest + self.verts[v as usize].rest) * 0.5;
        let p = total.optimal(centre);
        let p32 = p.as_vec3();
        if p32.is_finite() {
            vert.rest = p32;
        } else {
            vert.rest = centre;
        }
        // Evaluate where the vertex really is (f32 rest position) so costs match positions.
        (total.eval(vert.rest.as_dvec3()).max(0.0), vert)
    }

    /// Places the collapse of edge `(u, v)` by `policy`.
    pub fn place(&self, policy: Placement, u: u32, v: u32) -> Candidate {
        match policy {
            Placement::Endpoint => {
                let (cu, cv) = (self.endpoint_cost(u, v, u), self.endpoint_cost(u, v, v));
                let keep = if cu <= cv { u } else { v };
                Candidate { cost: cu.min(cv), vertex: self.verts[keep as usize].clone(), keep }
            }
            Placement::HoulePoulin => {
                let (cu, xu) = self.solve(u, v, self.verts[u as usize].clone());
                let (cv, xv) = self.solve(u, v, self.verts[v as usize].clone());
                if cu <= cv { Candidate { cost: cu, vertex: xu, keep: u } } else { Candidate { cost: cv, vertex: xv, keep: v } }
            }
            Placement::Blended => {
                let (a, b) = (&self.verts[u as usize], &self.verts[v as usize]);
                let (joints, weights) = blend_influences((a.joints, a.weights), (b.joints, b.weights), 0.5);
                let morph = a.morph.iter().zip(&b.morph).map(|(x, y)| (*x + *y) * 0.5).collect();
                let vert = Vertex { rest: a.rest, joints, weights, morph, class: a.class };
                let (cost, vertex) = self.solve(u, v, vert);
                Candidate { cost, vertex, keep: u }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pullback_matches_composition() {
        let q = Q::from_quadric(&Quadric::plane(DVec3::new(0.6, 0.8, 0.0), -1.0, 2.0), 1.0);
        let l = Mat3::from_cols_array(&[1.0, 0.5, 0.0, -0.2, 2.0, 0.1, 0.3, 0.0, 1.5]);
        let c = Vec3::new(0.3, -1.0, 2.0);
        let p = Vec3::new(0.7, 0.1, -0.4);
        let direct = q.eval((l * p + c).as_dvec3());
        let pulled = q.pullback(l, c).eval(p.as_dvec3());
        assert!((direct - pulled).abs() < 1e-5 * direct.abs().max(1.0), "{direct} {pulled}");
    }
}
