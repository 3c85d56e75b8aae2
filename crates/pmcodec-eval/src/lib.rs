//! Symmetric sampled surface distance between triangle meshes, in the spirit of Metro (Cignoni,
//! Rocchini & Scopigno 1998) and MESH (Aspert et al. 2002), which Kircher & Garland measured
//! with. Points are sampled uniformly by area on one surface, plus its vertices, and each is
//! measured to the exact closest point of the other surface through a bounding volume
//! hierarchy; the two directions are pooled. Every quality figure pmcodec reports comes from
//! here.
//!
//! For many approximations of one original frame, build the original's [`SurfaceIndex`] once
//! and use [`one_sided_indexed`] / [`symmetric_indexed`].
//!
//! What is measured also lives here: [`approximate`] makes every frame's approximation by this
//! project's reclustering and by the two baselines of Kircher & Garland figure 11 (first-frame
//! static, each frame simplified on its own), [`changed_share`] measures their temporal
//! coherence, [`select_cut`] takes the greedy cut by node error the methods are compared at, and
//! [`rebalance`] carries a cut from frame to frame as a player does. All
//! sampling draws from [`SplitMix64`].
#![warn(missing_docs)]
// `!(x > 0.0)` is written on purpose: it is also true for NaN, which these checks must reject.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod approx;
mod bvh;
mod coherence;
mod greedy;
pub mod made;
pub mod plot;
mod rebalance;
mod rng;
mod sample;
pub mod triangle;

pub use approx::{ApproxOptions, Method, approximate, approximate_sizes};
pub use bvh::SurfaceIndex;
pub use coherence::{Approximation, changed_share, changed_share_by_nodes, changed_share_of, cluster_keys, node_keys};
use glam::Vec3;
pub use greedy::select_cut;
use pmcodec_mesh::TriMesh;
use rayon::prelude::*;
pub use rebalance::{rebalance, repair};
pub use rng::SplitMix64;
pub use sample::{area_samples, triangle_area};
use serde::Serialize;

/// How many points to sample on each mesh, and from which seed. The same meshes, options and
/// seed always give the same figures, whatever the number of threads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleOptions {
    /// Area-uniform points sampled on each mesh, in addition to its vertices.
    pub samples: usize,
    /// Seed of the sampling (see [`SplitMix64`]).
    pub seed: u64,
}

impl Default for SampleOptions {
    fn default() -> Self {
        SampleOptions { samples: 20_000, seed: 0x5EED }
    }
}

/// Distance statistics over all sample points: root mean square, maximum (the sampled
/// Hausdorff distance) and mean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Distance {
    /// Root mean square of the sampled distances.
    pub rms: f64,
    /// The largest sampled distance.
    pub max: f64,
    /// The mean sampled distance.
    pub mean: f64,
}

/// Why two meshes cannot be measured. `which` names the mesh ("first", "reference", ...).
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[allow(missing_docs)] // `which` names the mesh in every variant; the messages say the rest.
pub enum EvalError {
    /// The mesh has no surface.
    #[error("the {which} mesh has no triangles, so it has no surface to measure")]
    NoTriangles { which: &'static str },
    /// More triangles than the surface index numbers.
    #[error("the {which} mesh has {count} triangles, more than a u32 can index")]
    TooManyTriangles { which: &'static str, count: usize },
    /// A coordinate is NaN or infinite.
    #[error("the {which} mesh has a NaN or infinite coordinate at vertex {vertex}")]
    NonFinite { which: &'static str, vertex: usize },
    /// A coordinate is beyond ±1e18 (squared distances must stay within `f32`).
    #[error("the {which} mesh has a coordinate beyond ±1e18 at vertex {vertex}")]
    OutOfRange { which: &'static str, vertex: usize },
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} of the {which} mesh uses vertex {index}, but there are only {vertex_count} vertices")]
    BadIndex { which: &'static str, triangle: usize, index: u32, vertex_count: usize },
    /// A relative distance was asked of a mesh with no extent.
    #[error("the {which} mesh's bounding box has a zero diagonal, so a relative distance means nothing")]
    ZeroExtent { which: &'static str },
}

/// Largest coordinate magnitude accepted. Squared distances between such points stay far inside
/// `f32` range, so the BVH can compare box distances in `f32` without overflow.
const MAX_COORDINATE: f32 = 1e18;

/// Checks what the sampler and the BVH rely on. Degenerate triangles are allowed: they are
/// measured as the segments or points they are.
pub(crate) fn validate(mesh: &TriMesh, which: &'static str) -> Result<(), EvalError> {
    if mesh.triangles.is_empty() {
        return Err(EvalError::NoTriangles { which });
    }
    if mesh.triangles.len() > u32::MAX as usize {
        return Err(EvalError::TooManyTriangles { which, count: mesh.triangles.len() });
    }
    for (vertex, p) in mesh.positions.iter().enumerate() {
        if !p.is_finite() {
            return Err(EvalError::NonFinite { which, vertex });
        }
        if p.abs().max_element() > MAX_COORDINATE {
            return Err(EvalError::OutOfRange { which, vertex });
        }
    }
    let vertex_count = mesh.positions.len();
    for (triangle, t) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = t.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(EvalError::BadIndex { which, triangle, index, vertex_count });
        }
    }
    Ok(())
}

/// The points [`one_sided`] measures from: `opts.samples` stratified area-uniform points on the
/// mesh, then every vertex a triangle uses. Exposed so callers can see or reuse them.
pub fn sample_points(mesh: &TriMesh, opts: &SampleOptions) -> Result<Vec<Vec3>, EvalError> {
    validate(mesh, "sampled")?;
    Ok(sample::sample_surface(mesh, opts.samples, opts.seed))
}

/// Running sums over squared distances. Kept in `f64`: tens of thousands of terms.
#[derive(Clone, Copy, Debug, Default)]
struct Stats {
    n: u64,
    sum_sq: f64,
    sum: f64,
    max_sq: f64,
}

impl Stats {
    fn add(&mut self, d2: f64) {
        self.n += 1;
        self.sum_sq += d2;
        self.sum += d2.sqrt();
        self.max_sq = self.max_sq.max(d2);
    }

    fn merge(self, o: Stats) -> Stats {
        Stats { n: self.n + o.n, sum_sq: self.sum_sq + o.sum_sq, sum: self.sum + o.sum, max_sq: self.max_sq.max(o.max_sq) }
    }

    fn distance(&self) -> Distance {
        if self.n == 0 {
            return Distance::default();
        }
        let n = self.n as f64;
        Distance { rms: (self.sum_sq / n).sqrt(), max: self.max_sq.sqrt(), mean: self.sum / n }
    }
}

/// Points per parallel task: large enough that a task's queries share cache and the hint from
/// one query to the next, small enough that two to a few dozen cores all get work.
const CHUNK: usize = 2048;

/// Measures every point against the index. Chunks are fixed and their partial sums are combined
/// in order, so the result does not depend on how rayon schedules them.
fn measure(points: &[Vec3], to: &SurfaceIndex) -> Stats {
    let parts: Vec<Stats> = points
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut s = Stats::default();
            let mut stack = bvh::new_stack();
            let mut hint = None;
            for &p in chunk {
                // Consecutive samples are close on the surface, so the previous answer is a
                // good first candidate.
                let (d2, slot) = to.query(p, hint, &mut stack);
                hint = Some(slot);
                s.add(d2);
            }
            s
        })
        .collect();
    parts.into_iter().fold(Stats::default(), Stats::merge)
}

fn one_sided_stats(from: &TriMesh, to: &SurfaceIndex, seed: u64, opts: &SampleOptions) -> Stats {
    measure(&sample::sample_surface(from, opts.samples, seed), to)
}

/// The seed of the second direction of a symmetric measure: a different stream from the
/// first, so two identical meshes are not sampled at identical points.
fn second_seed(seed: u64) -> u64 {
    SplitMix64::new(seed ^ 0x0005_ECD0_5EED).next_u64()
}

/// One-sided distance from the surface of `from` to the surface `to` was indexed from.
pub fn one_sided_indexed(from: &TriMesh, to: &SurfaceIndex, opts: &SampleOptions) -> Result<Distance, EvalError> {
    validate(from, "source")?;
    Ok(one_sided_stats(from, to, opts.seed, opts).distance())
}

/// One-sided distance from the surface of `from` to the surface of `to`: how far points of
/// `from` are from `to` (not the other way round).
pub fn one_sided(from: &TriMesh, to: &TriMesh, opts: &SampleOptions) -> Result<Distance, EvalError> {
    validate(from, "source")?;
    let index = SurfaceIndex::new(to)?;
    Ok(one_sided_stats(from, &index, opts.seed, opts).distance())
}

/// [`symmetric`] with both indices prebuilt. `a_index` must be built from `a` and `b_index` from
/// `b`.
pub fn symmetric_indexed(
    a: &TriMesh,
    a_index: &SurfaceIndex,
    b: &TriMesh,
    b_index: &SurfaceIndex,
    opts: &SampleOptions,
) -> Result<Distance, EvalError> {
    validate(a, "first")?;
    validate(b, "second")?;
    let (ab, ba) =
        rayon::join(|| one_sided_stats(a, b_index, opts.seed, opts), || one_sided_stats(b, a_index, second_seed(opts.seed), opts));
    Ok(ab.merge(ba).distance())
}

/// Symmetric distance: points of `a` measured to `b` and points of `b` measured to `a`, all
/// pooled. `rms` is the root of the mean square over the pooled points, `max` the larger of
/// the two one-sided maxima (the sampled Hausdorff distance), `mean` the pooled mean.
pub fn symmetric(a: &TriMesh, b: &TriMesh, opts: &SampleOptions) -> Result<Distance, EvalError> {
    validate(a, "first")?;
    validate(b, "second")?;
    let (ia, ib) = rayon::join(|| SurfaceIndex::new(a), || SurfaceIndex::new(b));
    symmetric_indexed(a, &ia?, b, &ib?, opts)
}

/// [`symmetric`] in percent of the reference's bounding-box diagonal, the scale-free figure
/// pmcodec reports.
pub fn symmetric_relative(reference: &TriMesh, approx: &TriMesh, opts: &SampleOptions) -> Result<Distance, EvalError> {
    validate(reference, "reference")?;
    validate(approx, "approximation")?;
    let diagonal = reference.bounds().map_or(0.0, |(lo, hi)| (hi.as_dvec3() - lo.as_dvec3()).length());
    if !(diagonal > 0.0) {
        return Err(EvalError::ZeroExtent { which: "reference" });
    }
    let d = symmetric(reference, approx, opts)?;
    let scale = 100.0 / diagonal;
    Ok(Distance { rms: d.rms * scale, max: d.max * scale, mean: d.mean * scale })
}

/// [`symmetric_relative`] with the reference's index prebuilt (`reference_index` must be built
/// from `reference`): for many approximations of one frame.
pub fn symmetric_relative_indexed(
    reference: &TriMesh,
    reference_index: &SurfaceIndex,
    approx: &TriMesh,
    opts: &SampleOptions,
) -> Result<Distance, EvalError> {
    validate(reference, "reference")?;
    validate(approx, "approximation")?;
    let diagonal = reference.bounds().map_or(0.0, |(lo, hi)| (hi.as_dvec3() - lo.as_dvec3()).length());
    if !(diagonal > 0.0) {
        return Err(EvalError::ZeroExtent { which: "reference" });
    }
    let approx_index = SurfaceIndex::new(approx)?;
    let d = symmetric_indexed(reference, reference_index, approx, &approx_index, opts)?;
    let scale = 100.0 / diagonal;
    Ok(Distance { rms: d.rms * scale, max: d.max * scale, mean: d.mean * scale })
}
