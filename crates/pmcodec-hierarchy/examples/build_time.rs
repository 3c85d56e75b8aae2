//! Development probe: where the multilevel build spends its time on a subdivided horse.
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::*;
use std::time::Instant;

fn main() {
    let path = std::path::PathBuf::from(std::env::args().nth(1).expect("obj"));
    let mut seq = pmcodec_mesh::obj::load_obj_files(&[path], 30.0).expect("load");
    for _ in 0..std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(2) {
        let mut pos = seq.frames[0].clone();
        let mut mid = std::collections::HashMap::new();
        let mut tris = Vec::new();
        for &[a, b, c] in &seq.triangles {
            let mut m = |x: u32, y: u32| -> u32 {
                *mid.entry((x.min(y), x.max(y))).or_insert_with(|| {
                    pos.push((pos[x as usize] + pos[y as usize]) * 0.5);
                    pos.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            tris.extend_from_slice(&[[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        seq = pmcodec_mesh::Sequence { triangles: tris, frames: vec![pos], frame_rate: 30.0, ..Default::default() };
    }
    for _ in 0..3 {
        let t = Instant::now();
        let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
        let t1 = t.elapsed();
        let q = base_quadrics(&seq, &topo, &BaseOptions::default());
        let t2 = t.elapsed();
        let h = build(&topo, &q, &BuildOptions::default()).expect("build");
        let t3 = t.elapsed();
        println!(
            "{} tris: topology {:?}, quadrics {:?}, build {:?}; levels {:?}",
            seq.triangles.len(),
            t1,
            t2 - t1,
            t3 - t2,
            h.level_sizes
        );
    }
}
