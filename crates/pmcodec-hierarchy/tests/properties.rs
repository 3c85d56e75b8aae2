//! Property tests on random meshes: every cluster connected after the build and after every
//! reclustered frame, and the degenerate-set rule equal to brute force for random cuts.

use crate::common;
use common::{Rng, random_cut};
use glam::Vec3;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::cut::{self, Cut};
use pmcodec_hierarchy::progressive::{Encoder, Replay};
use pmcodec_hierarchy::*;
use pmcodec_mesh::Sequence;
use proptest::prelude::*;

/// A random mesh: a perturbed grid with some triangles removed (so boundaries, holes, several
/// components and non-manifold vertices appear), over a few frames of random smooth motion.
fn random_sequence(seed: u64, w: u32, h: u32, drop_percent: u64, frames: usize) -> Sequence {
    let mut rng = Rng::new(seed);
    let mut tris = Vec::new();
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let i = y * w + x;
            for t in [[i, i + 1, i + w + 1], [i, i + w + 1, i + w]] {
                if rng.below(100) >= drop_percent {
                    tris.push(t);
                }
            }
        }
    }
    if tris.is_empty() {
        tris.push([0, 1, w]);
    }
    let base: Vec<Vec3> =
        (0..w * h).map(|i| Vec3::new((i % w) as f32 + 0.3 * rng.unit(), (i / w) as f32 + 0.3 * rng.unit(), rng.unit())).collect();
    let mut seq = Sequence { triangles: tris, frame_rate: 30.0, ..Default::default() };
    for f in 0..frames {
        let (a, b) = (rng.unit() * 2.0, rng.unit() * 3.0);
        seq.frames
            .push(base.iter().map(|p| Vec3::new(p.x, p.y, p.z + a * (0.3 * p.x + f as f32 * 0.5).sin() + b * (0.2 * p.y).cos())).collect());
    }
    seq
}

fn brute_shown(h: &Hierarchy, tris: &[[u32; 3]], c: &Cut) -> Vec<u32> {
    let rep = cut::cut_nodes(h, c);
    tris.iter()
        .enumerate()
        .filter(|(_, t)| {
            let [x, y, z] = t.map(|v| rep[v as usize]);
            x != y && y != z && x != z
        })
        .map(|(t, _)| t as u32)
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn clusters_connected_and_degenerate_sets_exact(
        seed in any::<u64>(),
        w in 3u32..18,
        h in 3u32..18,
        drop in 0u64..40,
        branching in 2u32..9,
    ) {
        let seq = random_sequence(seed, w, h, drop, 4);
        let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
        let q = base_quadrics(&seq, &topo, &BaseOptions::default());
        let hier = build(&topo, &q, &BuildOptions { branching, min_coarsest: 1, level_sizes: None, anchors: Vec::new() }).unwrap();
        prop_assert!(hier.check(&topo).is_ok(), "{:?}", hier.check(&topo));
        let d = DegenerateSets::new(&hier, &seq.triangles);
        let mut rng = Rng::new(seed ^ 0x55);
        for p in [0.0, 0.5, 0.9, 1.0] {
            let c = random_cut(&hier, &mut rng, p);
            prop_assert_eq!(cut::shown_triangles(&d, &c), brute_shown(&hier, &seq.triangles, &c));
        }
        // Reclustering keeps every cluster connected and the replay in step.
        let mut enc = Encoder::new(hier.clone(), topo.clone(), seq.triangles.clone(), Default::default());
        let mut replay = Replay::new(hier, &seq.triangles);
        for frame in &seq.frames {
            let (delta, _) = enc.encode_frame(frame);
            prop_assert!(enc.hierarchy().check(&topo).is_ok());
            replay.apply(&delta).unwrap();
            prop_assert_eq!(&replay.h, enc.hierarchy());
            prop_assert_eq!(replay.degeneration(), enc.degeneration());
            let c = random_cut(&replay.h, &mut rng, 0.7);
            replay.set_cut(&c.expanded);
            let mut shown = replay.shown().to_vec();
            shown.sort_unstable();
            prop_assert_eq!(shown, brute_shown(&replay.h, &seq.triangles, &c));
        }
    }
}
