//! Temporal coherence: the identity of every shown triangle from frame to frame, and the share
//! of each frame's triangles that the previous frame did not show.

use crate::SplitMix64;
use pmcodec_hierarchy::cut::{self, Cut};
use pmcodec_hierarchy::{DegenerateSets, Hierarchy, NONE, NodeState};
use pmcodec_mesh::TriMesh;

/// One frame's approximation, and the identity of each of its triangles for coherence: the
/// three corner clusters' fingerprints (an order-free hash of their input vertices), sorted.
#[derive(Clone, Debug, Default)]
pub struct Approximation {
    /// The approximating mesh.
    pub mesh: TriMesh,
    /// Per triangle of `mesh`, its identity (see above).
    pub keys: Vec<[u64; 3]>,
}

/// A 64-bit fingerprint of input vertex `v` (splitmix64's mix, so XORs of them over a cluster
/// practically never collide).
fn vertex_hash(v: u32) -> u64 {
    SplitMix64::new(v as u64).next_u64()
}

/// How triangles are identified from frame to frame for coherence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Identity {
    /// By the ids of their corner nodes: nodes of one evolving hierarchy persist across frames
    /// (a client keeps their vertex slots and only moves them).
    NodeIds,
    /// By the exact input-vertex sets of their corner clusters: for hierarchies rebuilt per
    /// frame, which share no node identity.
    Clusters,
}

pub(crate) fn approximation(h: &Hierarchy, triangles: &[[u32; 3]], nodes: &NodeState, c: &Cut, identity: Identity) -> Approximation {
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
        .filter(|&(_, &g)| g == NONE || c.expanded[g as usize])
        .map(|(t, _)| {
            let mut k = t.map(|v| sig[rep[v as usize] as usize]);
            k.sort_unstable();
            k
        })
        .collect();
    Approximation { mesh, keys }
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
