//! The compact binary mesh of proto/http.md (`format=bin` LOD responses): little-endian
//! `"PMCM"`, u32 version, u32 vertex count V, u32 triangle count T, V x 3 f32 positions,
//! T x 3 u32 indices. Written by the server, read by clients and tests.

use crate::TriMesh;

/// Magic of the compact binary mesh.
pub const MAGIC: &[u8; 4] = b"PMCM";
/// Version of the layout.
pub const VERSION: u32 = 1;
/// Bytes before the positions: magic, version, vertex count, triangle count.
pub const HEADER_LEN: usize = 16;

/// What is wrong with a compact binary mesh.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("binary mesh: {0}")]
pub struct BinMeshError(pub &'static str);

pub fn encode_bin(mesh: &TriMesh) -> Vec<u8> {
    let mut b = Vec::with_capacity(HEADER_LEN + mesh.positions.len() * 12 + mesh.triangles.len() * 12);
    b.extend_from_slice(MAGIC);
    b.extend_from_slice(&VERSION.to_le_bytes());
    b.extend_from_slice(&(mesh.positions.len() as u32).to_le_bytes());
    b.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
    for p in &mesh.positions {
        for c in p.to_array() {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    b
}

/// Reads exactly one well-formed mesh; counts are checked against the length before anything
/// is allocated, so hostile counts cannot overflow or allocate without bound.
pub fn decode_bin(b: &[u8]) -> Result<TriMesh, BinMeshError> {
    let word = |i: usize| b.get(i..i + 4).and_then(|s| s.try_into().ok()).map(u32::from_le_bytes);
    if b.get(..4) != Some(&MAGIC[..]) {
        return Err(BinMeshError("bad magic"));
    }
    if word(4) != Some(VERSION) {
        return Err(BinMeshError("unknown version"));
    }
    let (v, t) = match (word(8), word(12)) {
        (Some(v), Some(t)) => (v as usize, t as usize),
        _ => return Err(BinMeshError("short header")),
    };
    let pos_end = v.checked_mul(12).and_then(|n| n.checked_add(HEADER_LEN));
    let end = pos_end.zip(t.checked_mul(12)).and_then(|(p, n)| p.checked_add(n));
    let (Some(pos_end), Some(end)) = (pos_end, end) else { return Err(BinMeshError("counts overflow")) };
    if b.len() != end {
        return Err(BinMeshError("length does not match its counts"));
    }
    let f = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    let u = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    // In bounds: the length was checked against the counts above.
    let positions = (0..v).map(|k| HEADER_LEN + 12 * k).map(|o| glam::Vec3::new(f(o), f(o + 4), f(o + 8))).collect();
    let triangles: Vec<[u32; 3]> = (0..t).map(|k| pos_end + 12 * k).map(|o| [u(o), u(o + 4), u(o + 8)]).collect();
    if triangles.iter().flatten().any(|&i| i as usize >= v) {
        return Err(BinMeshError("index out of range"));
    }
    Ok(TriMesh { positions, triangles })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_hostile_headers() {
        let mesh = TriMesh { positions: vec![glam::Vec3::X, glam::Vec3::Y, glam::Vec3::Z], triangles: vec![[0, 1, 2]] };
        let b = encode_bin(&mesh);
        assert_eq!(decode_bin(&b), Ok(mesh));
        let mut huge = b.clone();
        huge[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode_bin(&huge).is_err());
        assert_eq!(decode_bin(&b[..b.len() - 1]), Err(BinMeshError("length does not match its counts")));
        assert_eq!(decode_bin(b"PMC"), Err(BinMeshError("bad magic")));
    }
}
