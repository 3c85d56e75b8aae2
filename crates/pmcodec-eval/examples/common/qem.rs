//! Plain QEM on frame 0 by meshoptimizer (Kapoulkine's meshoptimizer, after Garland & Heckbert
//! 1997), the reference the frame-0 examples measure against (qem_reference, frame0_levels).

use pmcodec_mesh::{Sequence, TriMesh};

/// The simplified mesh with its unused vertices dropped.
pub fn simplify(seq: &Sequence, index_target: usize) -> Result<TriMesh, String> {
    let frame = &seq.frames[0];
    let flat: Vec<f32> = frame.iter().flat_map(|p| p.to_array()).collect();
    let bytes: Vec<u8> = flat.iter().flat_map(|x| x.to_le_bytes()).collect();
    let adapter = meshopt::VertexDataAdapter::new(&bytes, 12, 0).map_err(|e| format!("{e:?}"))?;
    let indices: Vec<u32> = seq.triangles.iter().flatten().copied().collect();
    let out = meshopt::simplify(&indices, &adapter, index_target, f32::MAX, meshopt::SimplifyOptions::empty(), None);
    let mut index = vec![u32::MAX; frame.len()];
    let mut mesh = TriMesh::default();
    for t in out.chunks_exact(3) {
        let tri = [t[0], t[1], t[2]].map(|v| {
            if index[v as usize] == u32::MAX {
                index[v as usize] = mesh.positions.len() as u32;
                mesh.positions.push(frame[v as usize]);
            }
            index[v as usize]
        });
        mesh.triangles.push(tri);
    }
    Ok(mesh)
}

/// Frame 0 simplified by meshoptimizer to within 1% of `vertices` (the target index count
/// bisected), or the closest it got.
pub fn reference(seq: &Sequence, vertices: usize) -> Result<TriMesh, String> {
    let (mut lo, mut hi) = (3usize, seq.triangles.len() * 3);
    let mut best: Option<TriMesh> = None;
    for _ in 0..24 {
        let mid = (lo + hi) / 2 / 3 * 3;
        let m = simplify(seq, mid)?;
        let got = m.positions.len();
        let better = best.as_ref().is_none_or(|b| got.abs_diff(vertices) < b.positions.len().abs_diff(vertices));
        if got > vertices {
            hi = mid;
        } else {
            lo = mid + 3;
        }
        if better {
            best = Some(m);
        }
        if got.abs_diff(vertices) * 100 <= vertices || hi <= lo {
            break;
        }
    }
    best.ok_or_else(|| "no simplification".to_string())
}
