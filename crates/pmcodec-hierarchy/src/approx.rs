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

/// What each frame's approximation is held to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ApproxTarget {
    /// Exactly this many vertices: the hierarchy gets a level of that size (see
    /// [`anchored_sizes`]) and every method shows that level.
    Vertices(u32),
    /// At most this many triangles: a greedy budget cut (by this frame's node errors) on the
    /// default hierarchy. First-frame static keeps frame 0's cut.
    Triangles(u32),
}

/// One frame's approximation, and the identity of each of its triangles for coherence: the
/// three corner clusters' fingerprints (an order-free hash of their input vertices), sorted.
#[derive(Clone, Debug, Default)]
pub struct Approximation {
    pub mesh: TriMesh,
    pub keys: Vec<[u64; 3]>,
}

fn vertex_hash(v: u32) -> u64 {
    let mut z = (v as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// How triangles are identified from frame to frame for coherence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Identity {
    /// By the ids of their corner nodes: nodes of one evolving hierarchy persist across frames
    /// (a client keeps their vertex slots and only moves them).
    NodeIds,
    /// By the exact input-vertex sets of their corner clusters: for hierarchies rebuilt per
    /// frame, which share no node identity.
    Clusters,
}

fn approximation(h: &Hierarchy, triangles: &[[u32; 3]], nodes: &NodeState, c: &cut::Cut, identity: Identity) -> Approximation {
    let d = DegenerateSets::new(h, triangles);
    let (mesh, _) = cut::extract(h, &d, triangles, c, &nodes.positions);
    let rep = cut::cut_nodes(h, c);
    let mut sig = vec![0u64; h.node_count()];
    match identity {
        Identity::Clusters => {
            for v in 0..h.level_sizes[0] {
                sig[rep[v as usize] as usize] ^= vertex_hash(v);
            }
        }
        Identity::NodeIds => {
            for (g, s) in sig.iter_mut().enumerate() {
                *s = vertex_hash(g as u32);
            }
        }
    }
    let keys = triangles
        .iter()
        .zip(&d.node_of)
        .filter(|&(_, &g)| g == crate::NONE || c.expanded[g as usize])
        .map(|(t, _)| {
            let mut k = t.map(|v| sig[rep[v as usize] as usize]);
            k.sort_unstable();
            k
        })
        .collect();
    Approximation { mesh, keys }
}

fn select(h: &Hierarchy, triangles: &[[u32; 3]], nodes: &NodeState, target: CutTarget) -> cut::Cut {
    let d = DegenerateSets::new(h, triangles);
    cut::select(h, &d, &cut::ChildIndex::new(h), nodes, target)
}

fn hierarchy_for(
    topo: &FineTopology,
    q: &[crate::Quadric],
    target: ApproxTarget,
    branching: u32,
) -> Result<(Hierarchy, CutTarget), BuildError> {
    match target {
        ApproxTarget::Vertices(n) => {
            let (h, level) = anchored_build(topo, q, n, branching)?;
            Ok((h, CutTarget::Level(level)))
        }
        ApproxTarget::Triangles(n) => {
            let b = if branching == 0 { 4 } else { branching };
            let h = build(topo, q, &BuildOptions { branching: b, ..Default::default() })?;
            Ok((h, CutTarget::Triangles(n)))
        }
    }
}

/// Approximations of every frame of `seq` by `method`; calls `progress(f)` after each frame.
pub fn approximate(
    seq: &Sequence,
    target: ApproxTarget,
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
                        let d = DegenerateSets::new(&rc.h, &seq.triangles);
                        let children = cut::ChildIndex::new(&rc.h);
                        cut::repair(&rc.h, &d, &children, &mut c);
                        // Hysteresis: leave a cut that is within 2% under its budget alone.
                        let (used, budget) = match cut_target {
                            CutTarget::Triangles(n) => (c.triangles, n),
                            CutTarget::Vertices(n) => (c.vertices, n),
                            _ => (0, 0),
                        };
                        if used > budget || (used as f64) < 0.98 * budget as f64 {
                            cut::rebalance(&rc.h, &d, &children, &rc.nodes, &mut c, cut_target);
                        }
                        c
                    }
                    _ => select(&rc.h, &seq.triangles, &rc.nodes, cut_target),
                };
                out.push(approximation(&rc.h, &seq.triangles, &rc.nodes, &c, Identity::NodeIds));
                previous = Some(c);
                progress(f);
            }
        }
    }
    Ok(out)
}

/// Share of frame f's triangles that frame f-1 did not show (by corner-cluster identity), for
/// f >= 1 (0 for frame 0).
pub fn changed_share(frames: &[Approximation]) -> Vec<f64> {
    let mut out = vec![0.0];
    for w in frames.windows(2) {
        let prev: std::collections::HashSet<[u64; 3]> = w[0].keys.iter().copied().collect();
        let changed = w[1].keys.iter().filter(|k| !prev.contains(*k)).count();
        out.push(if w[1].keys.is_empty() { 0.0 } else { changed as f64 / w[1].keys.len() as f64 });
    }
    out
}
