//! Temporal coherence: the identity of every shown triangle from frame to frame, and the share
//! of each frame's triangles that the previous frame did not show.

use crate::SplitMix64;
use pmcodec_hierarchy::cut::{self, Cut};
use pmcodec_hierarchy::{DegenerateSets, Hierarchy, NONE, NodeState};
use pmcodec_mesh::TriMesh;

/// One frame's approximation, and the identity of each of its triangles for coherence: the
/// three corner clusters' fingerprints (an order-free hash of their input vertices), sorted.
/// Every method is identified this way, so their figures compare (issue 15); a method whose
/// nodes persist from frame to frame also carries its triangles' corner node ids.
#[derive(Clone, Debug, Default)]
pub struct Approximation {
    /// The approximating mesh.
    pub mesh: TriMesh,
    /// Per triangle of `mesh`, its identity by cluster content (see above).
    pub keys: Vec<[u64; 3]>,
    /// Per triangle, its corner nodes' ids (hashed, sorted), for methods whose nodes persist
    /// (one evolving hierarchy: a client keeps their vertex slots and only moves them).
    pub node_keys: Option<Vec<[u64; 3]>>,
}

/// A 64-bit fingerprint of input vertex `v` (splitmix64's mix, so XORs of them over a cluster
/// practically never collide).
fn vertex_hash(v: u32) -> u64 {
    SplitMix64::new(v as u64).next_u64()
}

/// How triangles are identified from frame to frame for coherence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Identity {
    /// By cluster content and also by the ids of their corner nodes: nodes of one evolving
    /// hierarchy persist across frames.
    NodeIds,
    /// By cluster content only: hierarchies rebuilt per frame share no node identity.
    Clusters,
}

/// Triangle identities by cluster content: `node_of[v]` is the shown node whose cluster holds
/// input vertex `v`, and `corners` the shown triangles by their corners' nodes.
pub fn cluster_keys(node_of: &[u32], corners: &[[u32; 3]]) -> Vec<[u64; 3]> {
    let mut sig = std::collections::HashMap::<u32, u64>::new();
    for (v, &g) in node_of.iter().enumerate() {
        *sig.entry(g).or_default() ^= vertex_hash(v as u32);
    }
    corners
        .iter()
        .map(|t| {
            let mut k = t.map(|g| sig.get(&g).copied().unwrap_or_else(|| vertex_hash(g) ^ 0xC0FF_EE00));
            k.sort_unstable();
            k
        })
        .collect()
}

/// Triangle identities by node ids (hashed, sorted).
pub fn node_keys(corners: &[[u32; 3]]) -> Vec<[u64; 3]> {
    corners
        .iter()
        .map(|t| {
            let mut k = t.map(vertex_hash);
            k.sort_unstable();
            k
        })
        .collect()
}

pub(crate) fn approximation(h: &Hierarchy, triangles: &[[u32; 3]], nodes: &NodeState, c: &Cut, identity: Identity) -> Approximation {
    let d = DegenerateSets::new(h, triangles);
    let (mesh, _) = cut::extract(h, &d, triangles, c, &nodes.positions);
    let rep = cut::cut_nodes(h, c);
    let corners: Vec<[u32; 3]> = triangles
        .iter()
        .zip(&d.node_of)
        .filter(|&(_, &g)| g == NONE || c.expanded[g as usize])
        .map(|(t, _)| t.map(|v| rep[v as usize]))
        .collect();
    let node_of = &rep[..h.level_sizes[0] as usize];
    Approximation { mesh, keys: cluster_keys(node_of, &corners), node_keys: (identity == Identity::NodeIds).then(|| node_keys(&corners)) }
}

/// Share of each frame's identities that the frame before did not have, for f >= 1 (0 for
/// frame 0).
pub fn changed_share_of(frames: &[&[[u64; 3]]]) -> Vec<f64> {
    let mut out = vec![0.0];
    for w in frames.windows(2) {
        let prev: std::collections::HashSet<[u64; 3]> = w[0].iter().copied().collect();
        let changed = w[1].iter().filter(|k| !prev.contains(*k)).count();
        out.push(if w[1].is_empty() { 0.0 } else { changed as f64 / w[1].len() as f64 });
    }
    out
}

/// Share of frame f's triangles that frame f-1 did not show (by corner-cluster content), for
/// f >= 1 (0 for frame 0).
pub fn changed_share(frames: &[Approximation]) -> Vec<f64> {
    changed_share_of(&frames.iter().map(|a| a.keys.as_slice()).collect::<Vec<_>>())
}

/// [`changed_share`] by corner node ids, when every frame carries them.
pub fn changed_share_by_nodes(frames: &[Approximation]) -> Option<Vec<f64>> {
    let keys: Option<Vec<&[[u64; 3]]>> = frames.iter().map(|a| a.node_keys.as_deref()).collect();
    keys.map(|k| changed_share_of(&k))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clusters_identify_by_content_not_by_id() {
        // Vertices 0..4; frame a: clusters {0,1} (node 7) and {2} (8), {3} (9); frame b: the same
        // clusters under other node ids, then one cluster changed.
        let a = cluster_keys(&[7, 7, 8, 9], &[[7, 8, 9]]);
        let b = cluster_keys(&[1, 1, 2, 3], &[[3, 1, 2]]);
        let c = cluster_keys(&[1, 2, 2, 3], &[[3, 1, 2]]);
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_eq!(changed_share_of(&[&a, &b, &c]), vec![0.0, 0.0, 1.0]);
        // By node ids the renamed frame is all new.
        assert_eq!(changed_share_of(&[&node_keys(&[[7, 8, 9]]), &node_keys(&[[3, 1, 2]])]), vec![0.0, 1.0]);
    }
}
