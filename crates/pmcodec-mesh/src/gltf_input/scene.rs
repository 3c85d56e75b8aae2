//! Scene structure: nodes, their parents and world transforms, the mesh nodes of the scene, skins.

use super::*;

pub(super) fn read_nodes(root: &json::Root) -> Result<Vec<NodeTransform>, MeshError> {
    let mut out = Vec::with_capacity(root.nodes.len());
    for (i, node) in root.nodes.iter().enumerate() {
        let transform = match node.matrix {
            // Column-major, as glTF stores it (§5.25).
            Some(m) => {
                let matrix = Mat4::from_cols_array(&m);
                let (scale, rotation, translation) = matrix.to_scale_rotation_translation();
                NodeTransform { translation, rotation: unit_quat(rotation), scale, matrix: Some(matrix) }
            }
            None => NodeTransform {
                translation: node.translation.map_or(Vec3::ZERO, Vec3::from_array),
                rotation: node.rotation.map_or(Quat::IDENTITY, |q| unit_quat(Quat::from_array(q.0))),
                scale: node.scale.map_or(Vec3::ONE, Vec3::from_array),
                matrix: None,
            },
        };
        let finite = transform.translation.is_finite()
            && transform.scale.is_finite()
            && node.rotation.is_none_or(|q| q.0.iter().all(|c| c.is_finite()))
            && transform.matrix.is_none_or(|m| m.is_finite());
        if !finite {
            return Err(gltf_error(format!("node {i}: its transform is not made of finite numbers")));
        }
        out.push(transform);
    }
    Ok(out)
}

/// Parents from the `children` lists. glTF requires the nodes to form disjoint strict trees
/// (§3.5.3); a node with two parents or a cycle is rejected rather than guessed at.
pub(super) fn node_parents(root: &json::Root) -> Result<Vec<Option<usize>>, MeshError> {
    let n = root.nodes.len();
    let mut parents: Vec<Option<usize>> = vec![None; n];
    for (p, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten().map(|c| c.value()) {
            let slot = parents.get_mut(c).ok_or_else(|| gltf_error(format!("node {p} has child {c}, which does not exist")))?;
            if let Some(other) = *slot {
                return Err(gltf_error(format!("node {c} is a child of both node {other} and node {p}")));
            }
            if c == p {
                return Err(gltf_error(format!("node {p} is its own child")));
            }
            *slot = Some(p);
        }
    }
    // Every node must reach a root; one that meets its own path again sits on a cycle. Each
    // node is walked once (a deep chain must not cost n squared).
    const UNKNOWN: u8 = 0;
    const ON_PATH: u8 = 1;
    const REACHES_ROOT: u8 = 2;
    let mut state = vec![UNKNOWN; n];
    let mut path = Vec::new();
    for start in 0..n {
        let mut at = start;
        loop {
            match state.get(at).copied() {
                Some(UNKNOWN) => {
                    state[at] = ON_PATH;
                    path.push(at);
                    match parents.get(at).copied().flatten() {
                        Some(p) => at = p,
                        None => break,
                    }
                }
                Some(ON_PATH) => return Err(gltf_error(format!("node {at} is on a cycle of children"))),
                _ => break,
            }
        }
        for v in path.drain(..) {
            state[v] = REACHES_ROOT;
        }
    }
    Ok(parents)
}

/// Mesh nodes of the default scene (else the first scene, else all root nodes), depth first in
/// pre-order: the order in which primitives are numbered.
pub(super) fn scene_mesh_nodes(root: &json::Root, parents: &[Option<usize>]) -> Vec<usize> {
    let scene = root.scene.map(|s| s.value()).and_then(|s| root.scenes.get(s)).or_else(|| root.scenes.first());
    let roots: Vec<usize> = match scene {
        Some(s) => s.nodes.iter().map(|n| n.value()).collect(),
        None => (0..parents.len()).filter(|&n| parents.get(n).copied().flatten().is_none()).collect(),
    };
    let mut visited = vec![false; root.nodes.len()];
    let mut out = Vec::new();
    let mut stack: Vec<usize> = roots.into_iter().rev().collect();
    while let Some(n) = stack.pop() {
        let Some(node) = root.nodes.get(n) else { continue };
        if std::mem::replace(&mut visited[n], true) {
            continue;
        }
        if node.mesh.is_some() {
            out.push(n);
        }
        stack.extend(node.children.iter().flatten().rev().map(|c| c.value()));
    }
    out
}

pub(super) fn read_skin(file: &GltfFile, index: usize, skin: &json::Skin) -> Result<Skin, MeshError> {
    let joints: Vec<usize> = skin.joints.iter().map(|j| j.value()).collect();
    if let Some(&bad) = joints.iter().find(|&&j| j >= file.root.nodes.len()) {
        return Err(gltf_error(format!("skin {index} has joint node {bad}, which does not exist")));
    }
    if joints.len() > usize::from(u16::MAX) + 1 {
        return Err(MeshError::TooLarge { what: format!("skin {index} has {} joints", joints.len()) });
    }
    let inverse_bind_matrices = match skin.inverse_bind_matrices.map(|a| a.value()) {
        // Absent inverse bind matrices are identities (§5.28).
        None => vec![Mat4::IDENTITY; joints.len()],
        Some(at) => {
            let flat = file.read_floats(at, 16, &[ComponentType::F32], &format!("skin {index} inverseBindMatrices"))?;
            let matrices: Vec<Mat4> =
                flat.chunks_exact(16).filter_map(|c| c.try_into().ok()).map(|a: [f32; 16]| Mat4::from_cols_array(&a)).collect();
            if matrices.len() < joints.len() {
                return Err(gltf_error(format!("skin {index} has {} inverse bind matrices for {} joints", matrices.len(), joints.len())));
            }
            if matrices.iter().any(|m| !m.is_finite()) {
                return Err(gltf_error(format!("skin {index}: an inverse bind matrix is not finite")));
            }
            matrices
        }
    };
    Ok(Skin { joints, inverse_bind_matrices })
}

/// Number of morph targets of the mesh on each node (0 without a mesh): the width of a weights
/// channel that targets the node.
pub(super) fn morph_target_counts(root: &json::Root) -> Vec<usize> {
    root.nodes
        .iter()
        .map(|n| {
            n.mesh
                .and_then(|m| root.meshes.get(m.value()))
                .map_or(0, |m| m.primitives.iter().map(|p| p.targets.as_ref().map_or(0, Vec::len)).max().unwrap_or(0))
        })
        .collect()
}
