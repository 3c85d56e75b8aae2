//! Symmetric surface distance on the real horse (16,843 triangles) against a ~1,600-triangle
//! vertex-clustered copy, 20,000 samples each way: the measurement every quality figure costs.
//! `cargo bench -p pmcodec-eval --bench distance`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use glam::Vec3;
use pmcodec_eval::{SampleOptions, SurfaceIndex, one_sided_indexed, symmetric};
use pmcodec_mesh::TriMesh;
use std::collections::HashMap;
use std::sync::OnceLock;

fn main() {
    // Load and coarsen before timing starts, so no benchmark's first sample pays for it.
    coarse();
    divan::main();
}

/// Just `v x y z` and `f a b c` (1-based): all the horse uses, and independent of the OBJ
/// reader so this bench measures the distance and nothing else.
fn parse_obj(text: &str) -> TriMesh {
    let mut m = TriMesh::default();
    for line in text.lines() {
        let mut w = line.split_whitespace();
        match w.next() {
            Some("v") => {
                let c: Vec<f32> = w.take(3).map(|x| x.parse().expect("coordinate")).collect();
                m.positions.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let i: Vec<u32> = w.take(3).map(|x| x.parse::<u32>().expect("index") - 1).collect();
                m.triangles.push([i[0], i[1], i[2]]);
            }
            _ => {}
        }
    }
    m
}

/// Vertex clustering on a grid of `cells` cells along the longest axis: every vertex moves to
/// the mean of its cell, triangles whose corners share a cell vanish, duplicates are dropped.
fn cluster(m: &TriMesh, cells: u32) -> TriMesh {
    let (lo, hi) = m.bounds().expect("vertices");
    let size = (hi - lo).max_element() / cells as f32;
    let mut id: HashMap<[i32; 3], u32> = HashMap::new();
    let mut sums: Vec<(Vec3, u32)> = Vec::new();
    let map: Vec<u32> = m
        .positions
        .iter()
        .map(|&p| {
            let k = ((p - lo) / size).floor().as_ivec3().to_array();
            let next = sums.len() as u32;
            let c = *id.entry(k).or_insert(next);
            if c == next {
                sums.push((Vec3::ZERO, 0));
            }
            sums[c as usize].0 += p;
            sums[c as usize].1 += 1;
            c
        })
        .collect();
    let mut seen = std::collections::HashSet::new();
    let triangles = m
        .triangles
        .iter()
        .map(|t| t.map(|v| map[v as usize]))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .filter(|t| {
            let mut k = *t;
            k.sort_unstable();
            seen.insert(k)
        })
        .collect();
    TriMesh { positions: sums.iter().map(|&(s, n)| s / n as f32).collect(), triangles }
}

fn horse() -> &'static TriMesh {
    static H: OnceLock<TriMesh> = OnceLock::new();
    H.get_or_init(|| {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/horse-gallop/horse-gallop-01.obj");
        parse_obj(&std::fs::read_to_string(path).expect("the horse gallop in shared/data"))
    })
}

/// The clustering whose triangle count is nearest 1,600.
fn coarse() -> &'static TriMesh {
    static C: OnceLock<TriMesh> = OnceLock::new();
    C.get_or_init(|| {
        let m = (8..80).map(|cells| cluster(horse(), cells)).min_by_key(|c| c.triangles.len().abs_diff(1600)).expect("some");
        eprintln!("horse: {} triangles; coarse: {} triangles", horse().triangles.len(), m.triangles.len());
        m
    })
}

fn one_thread() -> &'static rayon::ThreadPool {
    static P: OnceLock<rayon::ThreadPool> = OnceLock::new();
    P.get_or_init(|| rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool"))
}

/// The performance target: both indices built, 2 × 20,000 samples plus the vertices, one core.
#[divan::bench(sample_count = 30)]
fn symmetric_one_core() -> f64 {
    let (a, b) = (horse(), coarse());
    one_thread().install(|| symmetric(a, b, &SampleOptions::default()).expect("distance").rms)
}

/// The same on every core of the machine.
#[divan::bench(sample_count = 30)]
fn symmetric_all_cores() -> f64 {
    symmetric(horse(), coarse(), &SampleOptions::default()).expect("distance").rms
}

/// Building the index of the full-resolution frame, which callers can do once per frame.
#[divan::bench(sample_count = 30)]
fn index_horse() -> usize {
    SurfaceIndex::new(horse()).expect("index").triangle_count()
}

/// The reused-index direction: samples of the approximation against the frame's prebuilt index.
#[divan::bench(sample_count = 30)]
fn coarse_to_indexed_horse_one_core(bencher: divan::Bencher) {
    let index = SurfaceIndex::new(horse()).expect("index");
    bencher.bench(|| one_thread().install(|| one_sided_indexed(coarse(), &index, &SampleOptions::default()).expect("distance").rms));
}
