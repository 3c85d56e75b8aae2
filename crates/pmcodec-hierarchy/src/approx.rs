//! Per-frame approximations of a sequence at a fixed vertex count, by three methods, for
//! measurement (Kircher & Garland figure 11):
//! - *first-frame static*: frame 0's clusters kept for every frame, node positions re-solved
//!   from each frame's quadrics (stronger than reusing a vertex subset);
//! - *direct*: every frame simplified on its own (QSlim per frame; flickers);
//! - *reclustered*: this project's method, the base hierarchy adapted frame by frame.
//!
//! All three take the hierarchy level that has exactly the requested vertex count, so they
//! differ only in how the clusters were chosen.

use crate::base::{BaseOptions, base_quadrics};
use crate::build::{BuildError, BuildOptions, anchored_sizes, build};
use crate::cut::{self, CutTarget};
use crate::degenerate::DegenerateSets;
use crate::quadric::vertex_quadrics;
use crate::recluster::{ReclusterOptions, Reclusterer};
use crate::topology::FineTopology;
use crate::{Hierarchy, NodeState};
use pmcodec_mesh::{Sequence, TriMesh};

/// The approximation methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    FirstFrameStatic,
    Direct,
    Reclustered,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::FirstFrameStatic => "static",
            Method::Direct => "direct",
            Method::Reclustered => "pmcodec",
        }
    }
}

/// Shared settings.
#[derive(Clone, Debug, Default)]
pub struct ApproxOptions {
    pub branching: u32,
    pub base: BaseOptions,
    pub recluster: ReclusterOptions,
}

fn level_mesh(h: &Hierarchy, triangles: &[[u32; 3]], nodes: &NodeState, level: usize) -> TriMesh {
    let d = DegenerateSets::new(h, triangles);
    let children = cut::ChildIndex::new(h);
    let c = cut::select(h, &d, &children, nodes, CutTarget::Level(level));
    cut::extract(h, &d, triangles, &c, &nodes.positions).0
}

/// Builds the hierarchy with one level at exactly `vertices` nodes; returns it and that level.
pub fn anchored_build(
    topo: &FineTopology,
    quadrics: &[crate::Quadric],
    vertices: u32,
    branching: u32,
) -> Result<(Hierarchy, usize), BuildError> {
    let b = if branching == 0 { 4 } else { branching };
    let sizes = anchored_sizes(topo.vertex_count, vertices, b, 8);
    let h = build(topo, quadrics, &BuildOptions { branching: b, level_sizes: Some(sizes.clone()), ..Default::default() })?;
    let level = h.level_sizes.iter().position(|&s| s == vertices).unwrap_or(0);
    Ok((h, level))
}

/// Approximations of every frame of `seq` at `vertices` vertices by `method`; calls
/// `progress(f)` after each frame.
pub fn approximate(
    seq: &Sequence,
    vertices: u32,
    method: Method,
    opts: &ApproxOptions,
    mut progress: impl FnMut(usize),
) -> Result<Vec<TriMesh>, BuildError> {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let mut out = Vec::with_capacity(seq.frame_count());
    match method {
        Method::Direct => {
            let mut q = Vec::new();
            for (f, frame) in seq.frames.iter().enumerate() {
                vertex_quadrics(frame, &seq.triangles, &topo.boundary, &opts.base.quadric, &mut q);
                let (h, level) = anchored_build(&topo, &q, vertices, opts.branching)?;
                let nodes = NodeState::compute(&h, &q, frame);
                out.push(level_mesh(&h, &seq.triangles, &nodes, level));
                progress(f);
            }
        }
        Method::FirstFrameStatic | Method::Reclustered => {
            let q = base_quadrics(seq, &topo, &opts.base);
            let (h, level) = anchored_build(&topo, &q, vertices, opts.branching)?;
            let mut rc = Reclusterer::new(h, topo, seq.triangles.clone(), opts.recluster.clone());
            let mut swaps = Vec::new();
            for (f, frame) in seq.frames.iter().enumerate() {
                if method == Method::Reclustered {
                    rc.frame(frame, &mut swaps);
                } else {
                    rc.fit(frame);
                }
                out.push(level_mesh(&rc.h, &seq.triangles, &rc.nodes, level));
                progress(f);
            }
        }
    }
    Ok(out)
}
