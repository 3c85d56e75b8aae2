//! The compact binary mesh of proto/http.md (`format=bin` LOD responses): little-endian
//! `"PMCM"`, u32 version, u32 vertex count V, u32 triangle count T, V x 3 f32 positions,
//! T x 3 indices, u16 when V <= 65,536 and u32 otherwise (version 2; version 1, still read, had
//! u32 indices always). Written by the server, read by clients and tests.

use crate::TriMesh;

/// Magic of the compact binary mesh.
pub const MAGIC: &[u8; 4] = b"PMCM";
/// Version of the layout written.
pub const VERSION: u32 = 2;
/// Bytes before the positions: magic, version, vertex count, triangle count.
pub const HEADER_LEN: usize = 16;
/// Meshes with at most this many vertices get 16-bit indices (version 2).
pub const MAX_U16_VERTICES: usize = 1 << 16;

/// What is wrong with a compact binary mesh.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("binary mesh: {0}")]
pub struct BinMeshError(pub &'static str);

/// Bytes per index for a mesh of `vertices` vertices in layout `version`.
fn index_bytes(version: u32, vertices: usize) -> usize {
    if version >= 2 && vertices <= MAX_U16_VERTICES { 2 } else { 4 }
}

pub fn encode_bin(mesh: &TriMesh) -> Vec<u8> {
    let (v, t) = (mesh.positions.len(), mesh.triangles.len());
    let width = index_bytes(VERSION, v);
    let mut b = vec![0u8; HEADER_LEN + v * 12 + t * 3 * width];
    let (header, body) = b.split_at_mut(HEADER_LEN);
    header[..4].copy_from_slice(MAGIC);
    header[4..8].copy_from_slice(&VERSION.to_le_bytes());
    header[8..12].copy_from_slice(&(v as u32).to_le_bytes());
    header[12..16].copy_from_slice(&(t as u32).to_le_bytes());
    // Sized slots filled in place (no per-value capacity checks, so the loops vectorize: an
    // answer of 100 KB is written in a few microseconds).
    let (positions, indices) = body.split_at_mut(v * 12);
    for (out, p) in positions.chunks_exact_mut(12).zip(&mesh.positions) {
        out[0..4].copy_from_slice(&p.x.to_le_bytes());
        out[4..8].copy_from_slice(&p.y.to_le_bytes());
        out[8..12].copy_from_slice(&p.z.to_le_bytes());
    }
    if width == 2 {
        // Indices are below V <= 65,536, so they fit 16 bits.
        for (out, t) in indices.chunks_exact_mut(6).zip(&mesh.triangles) {
            out[0..2].copy_from_slice(&(t[0] as u16).to_le_bytes());
            out[2..4].copy_from_slice(&(t[1] as u16).to_le_bytes());
            out[4..6].copy_from_slice(&(t[2] as u16).to_le_bytes());
        }
    } else {
        for (out, &i) in indices.chunks_exact_mut(4).zip(mesh.triangles.iter().flatten()) {
            out.copy_from_slice(&i.to_le_bytes());
        }
    }
    b
}

/// Reads exactly one well-formed mesh (version 1 or 2); counts are checked against the length
/// before anything is allocated, so hostile counts cannot overflow or allocate without bound.
pub fn decode_bin(b: &[u8]) -> Result<TriMesh, BinMeshError> {
    let word = |i: usize| b.get(i..i + 4).and_then(|s| s.try_into().ok()).map(u32::from_le_bytes);
    if b.get(..4) != Some(&MAGIC[..]) {
        return Err(BinMeshError("bad magic"));
    }
    let version = match word(4) {
        Some(x @ (1 | 2)) => x,
        _ => return Err(BinMeshError("unknown version")),
    };
    let (v, t) = match (word(8), word(12)) {
        (Some(v), Some(t)) => (v as usize, t as usize),
        _ => return Err(BinMeshError("short header")),
    };
    let width = index_bytes(version, v);
    let pos_end = v.checked_mul(12).and_then(|n| n.checked_add(HEADER_LEN));
    let end = pos_end.zip(t.checked_mul(3 * width)).and_then(|(p, n)| p.checked_add(n));
    let (Some(pos_end), Some(end)) = (pos_end, end) else { return Err(BinMeshError("counts overflow")) };
    if b.len() != end {
        return Err(BinMeshError("length does not match its counts"));
    }
    let f = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    let index = |i: usize| {
        if width == 2 { u16::from_le_bytes([b[i], b[i + 1]]) as u32 } else { u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]) }
    };
    // In bounds: the length was checked against the counts above.
    let positions = (0..v).map(|k| HEADER_LEN + 12 * k).map(|o| glam::Vec3::new(f(o), f(o + 4), f(o + 8))).collect();
    let triangles: Vec<[u32; 3]> =
        (0..t).map(|k| pos_end + 3 * width * k).map(|o| [index(o), index(o + width), index(o + 2 * width)]).collect();
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

    /// A fan of `n` triangles over `n + 2` vertices.
    fn fan(n: u32) -> TriMesh {
        TriMesh {
            positions: (0..n + 2).map(|i| glam::Vec3::new(i as f32, (i * 7 % 13) as f32, -(i as f32))).collect(),
            triangles: (0..n).map(|i| [0, i + 1, i + 2]).collect(),
        }
    }

    #[test]
    fn sixteen_bit_indices_up_to_65536_vertices() {
        for (n, width) in [(1u32, 2usize), (65_534, 2), (65_535, 4)] {
            let mesh = fan(n);
            let b = encode_bin(&mesh);
            assert_eq!(b.len(), HEADER_LEN + 12 * mesh.positions.len() + 3 * width * mesh.triangles.len(), "{n} triangles");
            assert_eq!(decode_bin(&b), Ok(mesh));
        }
    }

    #[test]
    fn reads_version_1() {
        let mesh = fan(3);
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        for w in [1u32, 5, 3] {
            b.extend_from_slice(&w.to_le_bytes());
        }
        b.extend(mesh.positions.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes));
        b.extend(mesh.triangles.iter().flatten().flat_map(|i| i.to_le_bytes()));
        assert_eq!(decode_bin(&b), Ok(mesh));
        b[4] = 3;
        assert_eq!(decode_bin(&b), Err(BinMeshError("unknown version")));
    }

    #[test]
    fn index_out_of_range_is_an_error() {
        let mut b = encode_bin(&fan(2));
        let last = b.len() - 2;
        b[last..].copy_from_slice(&9u16.to_le_bytes());
        assert_eq!(decode_bin(&b), Err(BinMeshError("index out of range")));
    }
}
