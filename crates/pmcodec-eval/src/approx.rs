//! Per-frame approximations of a sequence at a fixed vertex count or budget, by three methods, for
//! measurement (Kircher & Garland figure 11):
//! - *first-frame static*: frame 0's clusters kept for every frame, node positions re-solved
//!   from each frame's quadrics (stronger than reusing a vertex subset);
//! - *direct*: every frame simplified on its own (QSlim per frame; flickers);
//! - *reclustered*: this project's method, the base hierarchy adapted frame by frame.
//!
//! At a vertex count all three take the hierarchy level that has exactly that many vertices,
//! so they differ only in how the clusters were chosen.

use crate::coherence::{Approximation, Identity, approximation};
use crate::rebalance::{rebalance, repair};
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::build::{BuildError, BuildOptions, anchored_build, build};
use pmcodec_hierarchy::cut;
use pmcodec_hierarchy::quadric::vertex_quadrics;
use pmcodec_hierarchy::recluster::{ReclusterOptions, Reclusterer};
use pmcodec_hierarchy::{CutTarget, DegenerateSets, FineTopology, Hierarchy, NodeState, Quadric};
use pmcodec_mesh::Sequence;

/// The approximation methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Frame 0's clusters kept for every frame, node positions re-solved per frame.
    FirstFrameStatic,
    /// Every frame simplified on its own.
    Direct,
    /// This project's method: the base hierarchy reclustered frame by frame.
    Reclustered,
}

impl Method {
    /// The method's name in reports and on the command line.
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
    /// Branching factor of the hierarchy (0: the default).
    pub branching: u32,
    /// The quadrics the base hierarchy is built from.
    pub base: BaseOptions,
    /// Per-frame reclustering (the reclustered method).
    pub recluster: ReclusterOptions,
}

fn select(h: &Hierarchy, triangles: &[[u32; 3]], nodes: &NodeState, target: CutTarget) -> cut::Cut {
    let d = DegenerateSets::new(h, triangles);
    crate::select_cut(h, &d, &cut::ChildIndex::new(h), nodes, target)
}

/// The hierarchy an approximation cuts, and the cut it takes: for `Vertices(n)`, a hierarchy
/// with a level of exactly `n` nodes (see [`pmcodec_hierarchy::build::anchored_sizes`]) and that
/// level; for any other target, the default hierarchy and the target itself.
fn hierarchy_for(topo: &FineTopology, q: &[Quadric], target: CutTarget, branching: u32) -> Result<(Hierarchy, CutTarget), BuildError> {
    match target {
        CutTarget::Vertices(n) => {
            let (h, level) = anchored_build(topo, q, n, branching)?;
            Ok((h, CutTarget::Level(level)))
        }
        other => {
            let b = if branching == 0 { 4 } else { branching };
            let h = build(topo, q, &BuildOptions { branching: b, ..Default::default() })?;
            Ok((h, other))
        }
    }
}

/// Approximations of every frame of `seq` by `method`, each held to `target`; calls
/// `progress(f)` after each frame. `Vertices(n)` is met exactly: the hierarchy gets a level of
/// `n` nodes and every method shows that level. Any other target is a cut of the default
/// hierarchy by this frame's node errors (first-frame static keeps frame 0's cut).
pub fn approximate(
    seq: &Sequence,
    target: CutTarget,
    method: Method,
    opts: &ApproxOptions,
    mut progress: impl FnMut(usize),
) -> Result<Vec<Approximation>, BuildError> {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let mut out = Vec::with_capacity(seq.frame_count());
    match method {
        Method::Direct => {
            let mut q = Vec::new();
            for (f, frame) in seq.frames.iter().enumerate() {
                vertex_quadrics(frame, &seq.triangles, &topo.boundary, &opts.base.quadric, &mut q);
                let (h, cut_target) = hierarchy_for(&topo, &q, target, opts.branching)?;
                let nodes = NodeState::compute(&h, &q, frame);
                let c = select(&h, &seq.triangles, &nodes, cut_target);
                out.push(approximation(&h, &seq.triangles, &nodes, &c, Identity::Clusters));
                progress(f);
            }
        }
        Method::FirstFrameStatic | Method::Reclustered => {
            let q = base_quadrics(seq, &topo, &opts.base);
            let (h, cut_target) = hierarchy_for(&topo, &q, target, opts.branching)?;
            let mut rc = Reclusterer::new(h, topo, seq.triangles.clone(), opts.recluster.clone());
            let mut swaps = Vec::new();
            let mut previous: Option<cut::Cut> = None;
            for (f, frame) in seq.frames.iter().enumerate() {
                if method == Method::Reclustered {
                    rc.frame(frame, &mut swaps);
                } else {
                    rc.fit(frame);
                }
                // Static keeps frame 0's cut; reclustered carries its cut from frame to frame
                // and rebalances it to the budget (a player does the same), so the shown
                // triangles change only where the hierarchy or the errors require it.
                let c = match (previous.take(), method) {
                    (Some(c), Method::FirstFrameStatic) => c,
                    (Some(mut c), Method::Reclustered) => {
                        let d = DegenerateSets::new(rc.hierarchy(), &seq.triangles);
                        let children = cut::ChildIndex::new(rc.hierarchy());
                        repair(rc.hierarchy(), &d, &children, &mut c);
                        // Hysteresis: leave a cut that is within 2% under its budget alone.
                        // A target that is no budget is chosen afresh (`rebalance` selects it).
                        let (used, budget) = match cut_target {
                            CutTarget::Triangles(n) => (c.triangles, n),
                            CutTarget::Vertices(n) => (c.vertices, n),
                            _ => (u32::MAX, 0),
                        };
                        if used > budget || (used as f64) < 0.98 * budget as f64 {
                            rebalance(rc.hierarchy(), &d, &children, rc.nodes(), &mut c, cut_target);
                        }
                        c
                    }
                    _ => select(rc.hierarchy(), &seq.triangles, rc.nodes(), cut_target),
                };
                out.push(approximation(rc.hierarchy(), &seq.triangles, rc.nodes(), &c, Identity::NodeIds));
                previous = Some(c);
                progress(f);
            }
        }
    }
    Ok(out)
}

/// Approximations of the frames `frames` of `seq` at every vertex count of `sizes` at once, for
/// a budget sweep: `out[i][j]` is frame `frames[i]` at `sizes[j]` vertices. One hierarchy is
/// built with a level at each size (`sizes` is sorted and de-duplicated here), so each level is
/// the state of one QEM run at exactly that count: per frame for *direct* (plain QEM of the
/// frame, Garland & Heckbert 1997), once from the base quadrics for *first-frame static* (node
/// positions re-solved per frame), and for *reclustered* the same base hierarchy adapted frame by
/// frame through every frame up to the last in `frames` (which must then be increasing). A size
/// the run cannot reach (fewer vertices than the mesh has connected components) is shown at the
/// coarsest level.
pub fn approximate_sizes(
    seq: &Sequence,
    frames: &[usize],
    sizes: &[u32],
    method: Method,
    opts: &ApproxOptions,
    mut progress: impl FnMut(usize),
) -> Result<Vec<Vec<pmcodec_mesh::TriMesh>>, BuildError> {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let mut levels: Vec<u32> = sizes.iter().copied().filter(|&s| s > 0 && (s as usize) < seq.vertex_count()).collect();
    levels.sort_unstable_by(|a, b| b.cmp(a));
    levels.dedup();
    let build_opts =
        BuildOptions { branching: if opts.branching == 0 { 4 } else { opts.branching }, level_sizes: Some(levels), ..Default::default() };
    let meshes_of = |h: &Hierarchy, nodes: &NodeState| -> Vec<pmcodec_mesh::TriMesh> {
        let d = DegenerateSets::new(h, &seq.triangles);
        let children = cut::ChildIndex::new(h);
        sizes
            .iter()
            .map(|&s| {
                // The level of exactly `s` nodes, else the coarsest (see above); level 0 for a
                // size at or above the input's.
                let level =
                    h.level_sizes.iter().position(|&l| l == s).unwrap_or(if s as usize >= seq.vertex_count() { 0 } else { h.top() });
                let c = crate::select_cut(h, &d, &children, nodes, CutTarget::Level(level));
                cut::extract(h, &d, &seq.triangles, &c, &nodes.positions).0
            })
            .collect()
    };
    let mut out = Vec::with_capacity(frames.len());
    let mut q = Vec::new();
    match method {
        Method::Direct => {
            for (i, &f) in frames.iter().enumerate() {
                let frame = &seq.frames[f];
                vertex_quadrics(frame, &seq.triangles, &topo.boundary, &opts.base.quadric, &mut q);
                let h = build(&topo, &q, &build_opts)?;
                out.push(meshes_of(&h, &NodeState::compute(&h, &q, frame)));
                progress(i);
            }
        }
        Method::FirstFrameStatic => {
            let h = build(&topo, &base_quadrics(seq, &topo, &opts.base), &build_opts)?;
            for (i, &f) in frames.iter().enumerate() {
                let frame = &seq.frames[f];
                vertex_quadrics(frame, &seq.triangles, &topo.boundary, &opts.base.quadric, &mut q);
                out.push(meshes_of(&h, &NodeState::compute(&h, &q, frame)));
                progress(i);
            }
        }
        Method::Reclustered => {
            let h = build(&topo, &base_quadrics(seq, &topo, &opts.base), &build_opts)?;
            let mut rc = Reclusterer::new(h, topo, seq.triangles.clone(), opts.recluster.clone());
            let mut swaps = Vec::new();
            let mut next = frames.iter().copied().enumerate().peekable();
            for (f, frame) in seq.frames.iter().enumerate() {
                let Some(&(i, want)) = next.peek() else { break };
                rc.frame(frame, &mut swaps);
                swaps.clear();
                if want == f {
                    out.push(meshes_of(rc.hierarchy(), rc.nodes()));
                    progress(i);
                    next.next();
                }
            }
        }
    }
    Ok(out)
}
