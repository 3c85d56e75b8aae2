//! The compact binary mesh decoder on hostile input: arbitrary bytes, and damaged encodings of
//! real meshes, give a mesh or an error, never a panic; whatever decodes is well formed.

use pmcodec_mesh::TriMesh;
use pmcodec_mesh::binmesh::{HEADER_LEN, MAGIC, decode_bin, encode_bin};
use proptest::prelude::*;

fn well_formed(m: &TriMesh) -> bool {
    m.triangles.iter().flatten().all(|&i| (i as usize) < m.positions.len())
}

fn mesh() -> impl Strategy<Value = TriMesh> {
    (1usize..40).prop_flat_map(|v| {
        (prop::collection::vec(prop::array::uniform3(-1e3f32..1e3), v), prop::collection::vec(prop::array::uniform3(0..v as u32), 0..60))
            .prop_map(|(p, t)| TriMesh { positions: p.into_iter().map(glam::Vec3::from_array).collect(), triangles: t })
    })
}

proptest! {
    #[test]
    fn arbitrary_bytes_never_panic(mut bytes in prop::collection::vec(any::<u8>(), 0..400), header in any::<bool>()) {
        // Half the cases start with a valid magic and version so the counts get exercised.
        if header && bytes.len() >= 8 {
            bytes[..4].copy_from_slice(MAGIC);
            bytes[4..8].copy_from_slice(&2u32.to_le_bytes());
        }
        if let Ok(m) = decode_bin(&bytes) {
            prop_assert!(well_formed(&m));
        }
    }

    #[test]
    fn round_trips(m in mesh()) {
        prop_assert_eq!(decode_bin(&encode_bin(&m)).ok(), Some(m));
    }

    #[test]
    fn damaged_encodings_are_errors_or_well_formed(m in mesh(), at in any::<prop::sample::Index>(), bit in 0u8..8, cut in any::<prop::sample::Index>()) {
        let b = encode_bin(&m);
        let mut flipped = b.clone();
        let i = at.index(b.len());
        flipped[i] ^= 1 << bit;
        if let Ok(d) = decode_bin(&flipped) {
            prop_assert!(well_formed(&d));
        }
        let n = cut.index(b.len());
        prop_assert!(n == b.len() || decode_bin(&b[..n]).is_err());
        prop_assert!(b.len() >= HEADER_LEN);
    }
}
