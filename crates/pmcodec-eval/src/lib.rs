//! Symmetric sampled surface distance between triangle meshes (in the spirit of Metro, Cignoni
//! et al. 1998, and MESH, Aspert et al. 2002, which Kircher & Garland measured with): points
//! sampled uniformly by area on one surface (plus its vertices), each measured to the closest
//! point of the other surface through a bounding volume hierarchy; both directions pooled.

// `!(x > 0.0)` is written on purpose: it is also true for NaN, which these checks must reject.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod bvh;

pub use bvh::SurfaceIndex;
use glam::Vec3;
use pmcodec_mesh::TriMesh;
use rayon::prelude::*;
use serde::Serialize;

/// Sampling density and seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleOptions {
    /// Points sampled on each mesh (in addition to its vertices).
    pub samples: usize,
    pub seed: u64,
}

impl Default for SampleOptions {
    fn default() -> Self {
        SampleOptions { samples: 20_000, seed: 0x5EED }
    }
}

/// Distances: root mean square, maximum and mean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Distance {
    pub rms: f64,
    pub max: f64,
    pub mean: f64,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EvalError {
    #[error("the {0} mesh has no triangles")]
    NoTriangles(&'static str),
    #[error("the {which} mesh has a NaN or infinite coordinate at vertex {vertex}")]
    NonFinite { which: &'static str, vertex: usize },
    #[error("the {which} mesh's triangle {triangle} indexes beyond its vertices")]
    BadIndex { which: &'static str, triangle: usize },
}

fn check(m: &TriMesh, which: &'static str) -> Result<(), EvalError> {
    if m.triangles.is_empty() {
        return Err(EvalError::NoTriangles(which));
    }
    if let Some(vertex) = m.positions.iter().position(|p| !p.is_finite()) {
        return Err(EvalError::NonFinite { which, vertex });
    }
    let n = m.positions.len() as u32;
    if let Some(triangle) = m.triangles.iter().position(|t| t.iter().any(|&i| i >= n)) {
        return Err(EvalError::BadIndex { which, triangle });
    }
    Ok(())
}

/// splitmix64: small, fast, and enough for sample placement.
struct Rng(u64);
impl Rng {
    fn next_f32(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// `samples` points uniformly distributed by area over the mesh, then its vertices.
pub fn sample_points(m: &TriMesh, opts: &SampleOptions) -> Vec<Vec3> {
    let mut cumulative = Vec::with_capacity(m.triangles.len());
    let mut total = 0.0f64;
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        total += 0.5 * (b - a).cross(c - a).length() as f64;
        cumulative.push(total);
    }
    let mut rng = Rng(opts.seed);
    let mut out = Vec::with_capacity(opts.samples + m.positions.len());
    if total > 0.0 {
        for _ in 0..opts.samples {
            let r = rng.next_f32() as f64 * total;
            let i = cumulative.partition_point(|&c| c < r).min(m.triangles.len() - 1);
            let [a, b, c] = m.triangles[i].map(|v| m.positions[v as usize]);
            // Uniform barycentrics by folding the unit square onto the triangle.
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                u = 1.0 - u;
                v = 1.0 - v;
            }
            out.push(a + (b - a) * u + (c - a) * v);
        }
    }
    out.extend_from_slice(&m.positions);
    out
}

fn squared_distances(points: &[Vec3], to: &SurfaceIndex) -> Vec<f64> {
    points.par_chunks(1024).flat_map_iter(|chunk| chunk.iter().map(|&p| to.closest(p).0 as f64)).collect()
}

fn summarise(sq: impl Iterator<Item = f64>) -> Distance {
    let (mut n, mut sum_sq, mut sum, mut max) = (0usize, 0.0, 0.0, 0.0f64);
    for d2 in sq {
        n += 1;
        sum_sq += d2;
        let d = d2.sqrt();
        sum += d;
        max = max.max(d);
    }
    if n == 0 {
        return Distance::default();
    }
    Distance { rms: (sum_sq / n as f64).sqrt(), max, mean: sum / n as f64 }
}

/// Distance from points sampled on `from` to the surface indexed by `to`.
pub fn one_sided_indexed(from: &TriMesh, to: &SurfaceIndex, opts: &SampleOptions) -> Result<Distance, EvalError> {
    check(from, "source")?;
    Ok(summarise(squared_distances(&sample_points(from, opts), to).into_iter()))
}

/// Distance from points sampled on `from` to the surface of `to`.
pub fn one_sided(from: &TriMesh, to: &TriMesh, opts: &SampleOptions) -> Result<Distance, EvalError> {
    check(to, "target")?;
    one_sided_indexed(from, &SurfaceIndex::new(to), opts)
}

/// Symmetric distance: samples of both meshes, each measured to the other, pooled.
pub fn symmetric(a: &TriMesh, b: &TriMesh, opts: &SampleOptions) -> Result<Distance, EvalError> {
    check(a, "first")?;
    check(b, "second")?;
    let (ia, ib) = (SurfaceIndex::new(a), SurfaceIndex::new(b));
    let mut sq = squared_distances(&sample_points(a, opts), &ib);
    sq.extend(squared_distances(&sample_points(b, &SampleOptions { seed: opts.seed ^ 0xA5A5, ..*opts }), &ia));
    Ok(summarise(sq.into_iter()))
}

/// [`symmetric`] in percent of the reference's bounding-box diagonal.
pub fn symmetric_relative(reference: &TriMesh, approx: &TriMesh, opts: &SampleOptions) -> Result<Distance, EvalError> {
    let d = symmetric(reference, approx, opts)?;
    let diag = reference.diagonal() as f64;
    let scale = if diag > 0.0 { 100.0 / diag } else { 0.0 };
    Ok(Distance { rms: d.rms * scale, max: d.max * scale, mean: d.mean * scale })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f32) -> TriMesh {
        TriMesh {
            positions: vec![Vec3::new(0.0, 0.0, z), Vec3::new(1.0, 0.0, z), Vec3::new(1.0, 1.0, z), Vec3::new(0.0, 1.0, z)],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn shifted_square_is_at_its_offset() {
        let d = symmetric(&square(0.0), &square(0.1), &SampleOptions::default()).unwrap();
        assert!((d.rms - 0.1).abs() < 1e-5 && (d.max - 0.1).abs() < 1e-5 && (d.mean - 0.1).abs() < 1e-5, "{d:?}");
    }

    #[test]
    fn identical_meshes_are_at_zero() {
        let d = symmetric(&square(0.0), &square(0.0), &SampleOptions::default()).unwrap();
        assert!(d.max < 1e-6);
    }

    #[test]
    fn relative_divides_by_diagonal() {
        let d = symmetric_relative(&square(0.0), &square(0.1), &SampleOptions::default()).unwrap();
        assert!((d.rms - 10.0 / 2f64.sqrt()).abs() < 1e-3, "{d:?}");
    }

    #[test]
    fn bad_meshes_are_errors() {
        let empty = TriMesh { positions: vec![Vec3::ZERO], triangles: vec![] };
        assert_eq!(symmetric(&empty, &square(0.0), &SampleOptions::default()), Err(EvalError::NoTriangles("first")));
        let mut nan = square(0.0);
        nan.positions[2].x = f32::NAN;
        assert!(matches!(symmetric(&square(0.0), &nan, &SampleOptions::default()), Err(EvalError::NonFinite { vertex: 2, .. })));
    }
}
