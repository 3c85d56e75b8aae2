//! Building the whole multilevel hierarchy beside meshoptimizer's simplifier taking the same
//! mesh down to the coarsest level's size (issue bar: within 2x of meshoptimizer, one core).
//! Two meshes: the 8,431-vertex horse and a 270k-triangle mesh made by subdividing it twice.
//!
//! `cargo bench -p pmcodec-hierarchy --bench build`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::Vec3;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::*;
use pmcodec_mesh::Sequence;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::OnceLock;

fn main() {
    divan::main();
}

fn horse() -> &'static Sequence {
    static SEQ: OnceLock<Sequence> = OnceLock::new();
    SEQ.get_or_init(|| {
        let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/horse-gallop/horse-gallop-01.obj"));
        pmcodec_mesh::obj::load_obj_files(&[path], 30.0).expect("the horse in ../shared/data")
    })
}

/// 1-to-4 midpoint subdivision with shared edge midpoints (the result stays connected).
fn subdivide(seq: &Sequence) -> Sequence {
    let mut pos = seq.frames[0].clone();
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    let mut tris = Vec::with_capacity(seq.triangles.len() * 4);
    let mut m = |a: u32, b: u32, pos: &mut Vec<Vec3>| -> u32 {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            pos.push((pos[a as usize] + pos[b as usize]) * 0.5);
            pos.len() as u32 - 1
        })
    };
    for &[a, b, c] in &seq.triangles {
        let (ab, bc, ca) = (m(a, b, &mut pos), m(b, c, &mut pos), m(c, a, &mut pos));
        tris.extend_from_slice(&[[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    Sequence { triangles: tris, frames: vec![pos], frame_rate: 30.0, ..Default::default() }
}

fn subdivided() -> &'static Sequence {
    static SEQ: OnceLock<Sequence> = OnceLock::new();
    SEQ.get_or_init(|| subdivide(&subdivide(horse())))
}

fn pmcodec_build(seq: &Sequence) -> Hierarchy {
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let q = base_quadrics(seq, &topo, &BaseOptions::default());
    build(&topo, &q, &BuildOptions::default()).expect("build")
}

fn meshopt_simplify(seq: &Sequence, target_vertices: usize) -> Vec<u32> {
    let bytes: &[u8] = bytemuck_positions(&seq.frames[0]);
    let adapter = meshopt::VertexDataAdapter::new(bytes, 12, 0).expect("adapter");
    let indices: Vec<u32> = seq.triangles.iter().flatten().copied().collect();
    // About two triangles per vertex on a closed surface.
    meshopt::simplify(&indices, &adapter, target_vertices * 6, f32::MAX, meshopt::SimplifyOptions::empty(), None)
}

fn bytemuck_positions(p: &[Vec3]) -> &[u8] {
    // Vec3 is three packed f32 (glam's scalar Vec3 is #[repr(C)] without padding); meshopt's own
    // cast keeps the workspace free of unsafe code.
    meshopt::utilities::typed_to_bytes(p)
}

fn coarsest(seq: &Sequence) -> usize {
    let n = seq.vertex_count() as u32;
    *BuildOptions::default().targets(n).expect("targets").last().unwrap_or(&n) as usize
}

#[divan::bench]
fn pmcodec_build_horse() -> Hierarchy {
    pmcodec_build(divan::black_box(horse()))
}

#[divan::bench]
fn meshopt_simplify_horse() -> Vec<u32> {
    let seq = horse();
    meshopt_simplify(divan::black_box(seq), coarsest(seq))
}

#[divan::bench(sample_count = 10)]
fn pmcodec_build_subdivided() -> Hierarchy {
    pmcodec_build(divan::black_box(subdivided()))
}

#[divan::bench(sample_count = 10)]
fn meshopt_simplify_subdivided() -> Vec<u32> {
    let seq = subdivided();
    meshopt_simplify(divan::black_box(seq), coarsest(seq))
}

#[divan::bench]
fn degenerate_sets_horse(bencher: divan::Bencher) {
    let seq = horse();
    let h = pmcodec_build(seq);
    bencher.bench(|| DegenerateSets::new(divan::black_box(&h), &seq.triangles));
}
