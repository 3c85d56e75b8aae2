//! Shared helpers for the hierarchy's integration tests.
#![allow(dead_code)]

use pmcodec_mesh::Sequence;
use std::path::PathBuf;

/// `../shared/data` beside the repository; the test fails with a message where it is absent.
pub fn data_dir() -> PathBuf {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data"));
    assert!(dir.is_dir(), "{} is absent; real-mesh tests need ../shared/data beside the repository", dir.display());
    dir
}

/// The first `frames` frames of a real OBJ sequence; the test fails naming the folder when it
/// is missing or holds fewer frames.
pub fn load(name: &str, frames: usize) -> Sequence {
    let dir = data_dir().join(name);
    let mut paths = pmcodec_mesh::obj::frame_paths(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    assert!(paths.len() >= frames, "{}: {} frames, the test needs {frames}", dir.display(), paths.len());
    paths.truncate(frames);
    pmcodec_mesh::obj::load_obj_files(&paths, 30.0).unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
}

/// A deterministic generator for tests: the workspace's one ([`pmcodec_eval::SplitMix64`]).
pub struct Rng(pub pmcodec_eval::SplitMix64);
impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(pmcodec_eval::SplitMix64::new(seed))
    }
    #[allow(clippy::should_implement_trait)] // an endless generator, not an iterator
    pub fn next(&mut self) -> u64 {
        self.0.next_u64()
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
    pub fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A wavy grid of `w x h` vertices: a small generated fixture with a boundary.
pub fn grid(w: u32, h: u32, frames: usize) -> Sequence {
    let mut seq = Sequence { frame_rate: 30.0, triangles: pmcodec_mesh::samples::grid_triangles(w, h), ..Default::default() };
    for f in 0..frames {
        let t = f as f32 * 0.2;
        seq.frames.push(
            (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| {
                    let (u, v) = (x as f32 / (w - 1) as f32, y as f32 / (h - 1) as f32);
                    glam::Vec3::new(u, v, 0.2 * (6.0 * u + t).sin() * (4.0 * v).cos())
                })
                .collect(),
        );
    }
    seq
}

/// A random cut: expand each node with probability p, keeping the set closed upward.
pub fn random_cut(h: &pmcodec_hierarchy::Hierarchy, rng: &mut Rng, p: f32) -> pmcodec_hierarchy::Cut {
    let mut expanded = vec![false; h.node_count()];
    for k in (1..h.levels()).rev() {
        for v in 0..h.level_sizes[k] {
            let g = h.offsets[k] + v;
            let parent_ok = k == h.top() || expanded[(h.offsets[k + 1] + h.parent[k][v as usize]) as usize];
            expanded[g as usize] = parent_ok && rng.unit() < p;
        }
    }
    pmcodec_hierarchy::Cut { expanded, triangles: 0, vertices: 0 }
}
