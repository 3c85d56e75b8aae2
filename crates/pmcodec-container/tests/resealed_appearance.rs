//! Resealed damage to version 6's appearance chunks (Charts, Attributes, Materials, Image):
//! past the checksums, every damaged file gives `Ok` or a typed error naming the chunk, never
//! a panic; and the named cases are refused by name.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::testing::{Rng, Unsealed, exercise, reseal, stopped_at_the_door};
use pmcodec_container::{ChunkKind, ContainerError, EncodeOptions, QuantizationChoice, Reader, encode};

fn textured() -> Vec<u8> {
    let seq = pmcodec_mesh::samples::textured_cloth(10, 7, 5, 8);
    let opts = EncodeOptions { keyframe_interval: 2, quantization: QuantizationChoice::Bits(10), ..Default::default() };
    encode(&seq, &opts, |_| {}).expect("encode")
}

fn is_appearance(k: ChunkKind) -> bool {
    matches!(k, ChunkKind::Charts | ChunkKind::Attributes | ChunkKind::Materials | ChunkKind::Image)
}

#[test]
fn resealed_damage_to_appearance_chunks_gives_typed_errors() {
    let bytes = textured();
    exercise(&bytes).expect("the undamaged file plays");
    let base = Unsealed::open(&bytes).expect("unseal");
    let targets: Vec<usize> = base.chunks.iter().enumerate().filter(|(_, c)| is_appearance(c.entry.kind)).map(|(i, _)| i).collect();
    assert!(targets.len() >= 5, "{} appearance chunks", targets.len());
    let (mut refused, mut past) = (0, 0);
    let total = 300;
    for i in 0..total {
        let mut rng = Rng::new(0xA99E_A4A0 ^ i);
        let mut u = base.clone();
        let c = &mut u.chunks[targets[rng.below(targets.len())]];
        match rng.below(4) {
            0 if !c.raw.is_empty() => {
                let at = rng.below(c.raw.len());
                c.raw[at] ^= 1 << rng.below(8);
            }
            1 if !c.raw.is_empty() => {
                let at = rng.below(c.raw.len());
                c.raw[at] = rng.next_u64() as u8;
            }
            2 => {
                let n = c.raw.len();
                c.raw.truncate(rng.below(n.max(1)));
            }
            _ => c.raw.push(rng.next_u64() as u8),
        }
        if let Err(e) = exercise(&u.seal()) {
            refused += 1;
            if !stopped_at_the_door(&e) {
                past += 1;
            }
        }
    }
    // Image bytes are opaque to the container (a flipped pixel plays), but most damage to the
    // tables is refused, and by the parsers, not the checksums.
    assert!(refused * 2 >= total, "only {refused} of {total} refused");
    assert_eq!(past, refused, "refusals at the checksums");
}

fn refused_with(bytes: &[u8], what: &str, detail: &str) {
    match exercise(bytes) {
        Err(ContainerError::Corrupt { what: w, detail: d }) => {
            assert!(w.contains(what) && d.contains(detail), "{w}: {d} (wanted {what}: {detail})");
        }
        other => panic!("wanted {what}: {detail}, got {other:?}"),
    }
}

#[test]
fn named_appearance_damage_is_refused_by_name() {
    let bytes = textured();
    let with = |f: &dyn Fn(&mut Unsealed)| reseal(&bytes, f).expect("reseal");
    // A chart whose material is beyond the materials.
    refused_with(
        &with(&|u| {
            let c = u.chunks.iter_mut().find(|c| c.entry.kind == ChunkKind::Charts).unwrap();
            c.raw[1] = 7;
        }),
        "charts chunk",
        "material 7 out of range",
    );
    // An image whose bytes disagree with its description.
    refused_with(
        &with(&|u| {
            let c = u.chunks.iter_mut().find(|c| c.entry.kind == ChunkKind::Image).unwrap();
            c.raw.push(0);
        }),
        "image 0 chunk",
        "bytes where the materials chunk says",
    );
    // An attribute table without the entries its cuts need: refused by name, at band 1 or at
    // band 0, whose represented values (mode | 16) then find fewer representatives above and
    // more residuals than it holds.
    match exercise(&with(&|u| {
        let c = u.chunks.iter_mut().find(|c| c.entry.kind == ChunkKind::Attributes && c.entry.band == 1).unwrap();
        c.raw = vec![0];
    })) {
        Err(ContainerError::Corrupt { what, detail }) => assert!(
            (what == "band 1 attributes" && detail.contains("no entry for node"))
                || (what == "band 0 attributes" && detail.contains("ends inside a number")),
            "{what}: {detail}"
        ),
        other => panic!("wanted a corrupt band 1 or band 0, got {other:?}"),
    }
    // An image chunk beyond the header's images, and an appearance chunk in a bare file.
    let e = Reader::open(
        with(&|u| {
            let c = u.chunks.iter_mut().find(|c| c.entry.kind == ChunkKind::Image).unwrap();
            c.entry.band = 3;
        })
        .as_slice(),
    )
    .err()
    .expect("refused")
    .to_string();
    assert!(e.contains("image 3 chunk") && e.contains("out of range"), "{e}");
    let bare = encode(&pmcodec_mesh::samples::waving_cloth(6, 5, 2), &EncodeOptions::default(), |_| {}).unwrap();
    let charts = Unsealed::open(&bytes).unwrap().chunks.into_iter().find(|c| c.entry.kind == ChunkKind::Charts).unwrap();
    let e = Reader::open(reseal(&bare, |u| u.chunks.insert(1, charts.clone())).unwrap().as_slice()).err().expect("refused").to_string();
    assert!(e.contains("header has no appearance"), "{e}");
}
