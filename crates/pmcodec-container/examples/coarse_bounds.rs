//! Development probe: what the coarse bands' positions could cost, frames 1.., from their
//! model error alone: every prediction is made from exact (unquantized) positions, and the
//! residual is rounded to the band's grid (2^j quanta at 12 bits, the encoder's default).
//! Bits are of per-frame, per-axis static tables, per input vertex per frame.
//!
//! - none: the node's previous position;
//! - parent: plus its parent's motion (what the container falls back to);
//! - siblings: plus the mean motion of all its siblings (the container uses those decoded
//!   before it);
//! - centroid: plus the motion of its cluster's centroid (needs the cluster's fine vertices
//!   of this frame, which a coarse-first reader does not have);
//! - fine affine: the affine map that carries its cluster's fine vertices (the same caveat).
//!
//! `cargo run --release -p pmcodec-container --example coarse_bounds -- DIR`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::progressive::Encoder;
use pmcodec_hierarchy::{BuildOptions, FineTopology, build};
#[path = "common/entropy.rs"]
mod entropy;
use entropy::entropy;
use std::collections::HashMap;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).unwrap();
    let (lo, hi) = seq.bounds().unwrap();
    let step = ((hi - lo).max_element() / 4095.0) as f64;
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let opts = BuildOptions { anchors: vec![0.25, 0.10], ..BuildOptions::default() };
    let h0 = build(&topo, &base_quadrics(&seq, &topo, &BaseOptions::default()), &opts).unwrap();
    let mut enc = Encoder::new(h0, topo, seq.triangles.clone(), Default::default());
    let n0 = seq.vertex_count();
    let names = ["none", "parent", "siblings", "centroid", "fine affine"];
    // Per level (0 unused: input vertices are not measured here), per predictor.
    let mut bits: Vec<Vec<f64>> = Vec::new();
    let mut prev_x: Vec<glam::DVec3> = Vec::new();
    let mut prev_c: Vec<glam::DVec3> = Vec::new();
    let mut prev_fine: Vec<glam::DVec3> = Vec::new();
    for (f, frame) in seq.frames.iter().enumerate() {
        enc.encode_frame(frame);
        let h = enc.hierarchy();
        let total = h.node_count();
        let x: Vec<glam::DVec3> = (0..total).map(|g| enc.node_positions()[g].as_dvec3() / step).collect();
        let c: Vec<glam::DVec3> =
            (0..total).map(|g| if g < n0 { frame[g].as_dvec3() / step } else { enc.nodes().quadrics[g].centroid() / step }).collect();
        let fine: Vec<glam::DVec3> = frame.iter().map(|p| p.as_dvec3() / step).collect();
        if f > 0 {
            bits.resize(h.levels(), vec![0.0; names.len()]);
            for j in 1..h.levels() {
                let unit = (1u32 << j) as f64;
                let base = h.offsets[j] as usize;
                let nj = h.level_sizes[j] as usize;
                // Each parent's children, for the siblings.
                let mut kids: HashMap<u32, Vec<usize>> = HashMap::new();
                if j < h.top() {
                    for v in 0..nj {
                        kids.entry(h.parent[j][v]).or_default().push(base + v);
                    }
                }
                // Each node's fine vertices, up the parents of level 0.
                let mut members: Vec<Vec<usize>> = vec![Vec::new(); nj];
                for v in 0..n0 {
                    let mut a = v;
                    let mut lvl = 0;
                    while lvl < j {
                        a = h.parent[lvl][a] as usize;
                        lvl += 1;
                    }
                    members[a].push(v);
                }
                let mut res = vec![Vec::with_capacity(nj); names.len()];
                for v in 0..nj {
                    let g = base + v;
                    let parent = (j < h.top()).then(|| (h.offsets[j + 1] + h.parent[j][v]) as usize);
                    let pm = parent.map_or(glam::DVec3::ZERO, |p| x[p] - prev_x[p]);
                    let sib = parent
                        .and_then(|_| {
                            let s: Vec<usize> = kids[&h.parent[j][v]].iter().copied().filter(|&s| s != g).collect();
                            (!s.is_empty()).then(|| s.iter().map(|&s| x[s] - prev_x[s]).sum::<glam::DVec3>() / s.len() as f64)
                        })
                        .unwrap_or(pm);
                    // Least-squares affine map of the cluster's fine vertices, previous to this frame.
                    let m = &members[v];
                    let fa = if m.len() >= 4 {
                        let k = m.len() as f64;
                        let ca = m.iter().map(|&u| prev_fine[u]).sum::<glam::DVec3>() / k;
                        let cb = m.iter().map(|&u| fine[u]).sum::<glam::DVec3>() / k;
                        let mut saa = glam::DMat3::ZERO;
                        let mut sba = glam::DMat3::ZERO;
                        for &u in m {
                            let a = prev_fine[u] - ca;
                            let b = fine[u] - cb;
                            saa += glam::DMat3::from_cols(a * a.x, a * a.y, a * a.z);
                            sba += glam::DMat3::from_cols(b * a.x, b * a.y, b * a.z);
                        }
                        let tr = saa.x_axis.x + saa.y_axis.y + saa.z_axis.z;
                        let reg = glam::DMat3::from_diagonal(glam::DVec3::splat(tr * 1e-3 + 1e-9));
                        let a = (sba + reg) * (saa + reg).inverse();
                        cb + a * (prev_x[g] - ca)
                    } else {
                        prev_x[g] + (c[g] - prev_c[g])
                    };
                    let preds = [prev_x[g], prev_x[g] + pm, prev_x[g] + sib, prev_x[g] + (c[g] - prev_c[g]), fa];
                    for (i, p) in preds.iter().enumerate() {
                        let r = (x[g] - *p) / unit;
                        res[i].push([r.x.round() as i32, r.y.round() as i32, r.z.round() as i32]);
                    }
                }
                for i in 0..names.len() {
                    bits[j][i] += entropy(&res[i]);
                }
            }
        }
        prev_x = x;
        prev_c = c;
        prev_fine = fine;
    }
    let vf = (n0 * (seq.frame_count() - 1)) as f64;
    for (i, name) in names.iter().enumerate() {
        let per: Vec<String> = (1..bits.len()).map(|j| format!("{:.2}", bits[j][i] / vf)).collect();
        println!("{name:>14}: total {:.2} bits/input v/f, by level {:?}", (1..bits.len()).map(|j| bits[j][i]).sum::<f64>() / vf, per);
    }
}
