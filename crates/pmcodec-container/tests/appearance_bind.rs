//! Band 0's texture coordinates predicted from a skinned file's bind positions (issue 16;
//! proto/container.md, "Attributes, band 0 with derived entries", *bind positions*), on a
//! generated character.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::{CutTarget, Decoder, EncodeOptions, QuantizationChoice, Reader, encode, format::ChunkKind, verify};
use pmcodec_mesh::InputLimits;
use pmcodec_mesh::gltf_input::RiggedMesh;
use pmcodec_mesh::samples::{CharacterOptions, skinned_character};

/// A generated skinned character whose texture is an atlas of its triangles, each laid flat
/// as it is in the rest pose (lengths kept: the bind pose places each third corner exactly,
/// the parallelogram rule does not), in a grid of cells.
fn atlas_character(seed: u64) -> pmcodec_mesh::Sequence {
    let opts = CharacterOptions { parts: 6, limbs: 3, chain: 2, segments: 8, rings: 5, seconds: 1.0, keys_per_second: 5.0, seed };
    let mut rig = RiggedMesh::from_bytes(&skinned_character(&opts).unwrap()).unwrap();
    rig.weld();
    let mut seq = rig.to_sequence_with(Some(0), 10.0, &InputLimits::default()).unwrap();
    let rest = seq.skin.as_ref().expect("a skin").rest.clone();
    let rest = &rest;
    let extent = seq
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |i| (rest[t[i] as usize] - rest[t[(i + 1) % 3] as usize]).length()))
        .fold(0.0, f32::max);
    let mut app = pmcodec_mesh::Appearance::default();
    let columns = (seq.triangles.len() as f32).sqrt().ceil() as u32;
    for (t, tri) in seq.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|v| rest[v as usize]);
        let (ab, ac) = (b - a, c - a);
        let along = ab.normalize_or_zero();
        let (x2, y2) = (ac.dot(along), ac.cross(along).length());
        let origin = [(t as u32 % columns) as f32 * 1.5 * extent, (t as u32 / columns) as f32 * 1.5 * extent];
        let base = app.wedge_vertex.len() as u32;
        for (v, uv) in tri.iter().zip([[0.0, 0.0], [ab.length(), 0.0], [x2, y2]]) {
            app.wedge_vertex.push(*v);
            app.uv0.push([origin[0] + uv[0], origin[1] + uv[1]]);
        }
        app.corner_wedges.push([base, base + 1, base + 2]);
    }
    app.validate(seq.frames[0].len(), &seq.triangles).expect("a valid appearance");
    seq.appearance = Some(app);
    seq
}

#[test]
fn a_skinned_atlas_predicts_from_bind_positions_and_level_0_reads_back_the_input() {
    for seed in [1, 2] {
        let seq = atlas_character(seed);
        let app = seq.appearance.clone().unwrap();
        let opts = EncodeOptions { keyframe_interval: 4, quantization: QuantizationChoice::Bits(12), ..Default::default() };
        let bytes = encode(&seq, &opts, |_| {}).expect("encode");
        let reader = Reader::open(bytes.as_slice()).expect("open");
        verify(&reader).expect("verify");
        assert!(reader.header().skin.is_some(), "seed {seed}: not encoded skinned");
        let band0 = reader.read_chunk(reader.find(ChunkKind::Attributes, 0, 0).expect("band 0")).expect("read");
        assert!(band0.len() > 1 && band0[0] == 0 && band0[1] & 3 == 1 && band0[1] & 4 != 0, "seed {seed}: band 0 mode {:?}", &band0[..2]);
        // Level 0 draws the input's texture coordinates (on the header's grid) at every corner.
        let info = reader.header().appearance.clone().unwrap();
        let q = |uv: [f32; 2]| [0, 1].map(|a| ((uv[a] - info.uv_min[a]) / info.uv_step[a]).round() as i64);
        let mut d = Decoder::new(reader.borrowed(), 0).expect("decoder");
        d.seek(0).expect("seek");
        let (mesh, got) = d.textured_mesh(CutTarget::Level(0)).expect("textured");
        assert_eq!(mesh.triangles.len(), seq.triangles.len());
        let mut want: Vec<Vec<[i64; 2]>> = app.corner_wedges.iter().map(|w| w.iter().map(|&w| q(app.uv0[w as usize])).collect()).collect();
        let mut have: Vec<Vec<[i64; 2]>> = mesh.triangles.iter().map(|t| t.iter().map(|&v| q(got.uv0[v as usize])).collect()).collect();
        for t in want.iter_mut().chain(have.iter_mut()) {
            t.sort_unstable();
        }
        want.sort_unstable();
        have.sort_unstable();
        assert_eq!(have, want, "seed {seed}");
    }
}
