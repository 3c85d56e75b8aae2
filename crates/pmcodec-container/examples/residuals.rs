//! Development probe: empirical entropy of position residuals per band under several
//! predictors, to see where the bits go.
use pmcodec_container::payload::zigzag;
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::progressive::Encoder;
use pmcodec_hierarchy::{BuildOptions, FineTopology, build};
use std::collections::HashMap;

fn entropy(values: &[i32]) -> f64 {
    let mut h: HashMap<i32, usize> = HashMap::new();
    for &v in values {
        *h.entry(v).or_default() += 1;
    }
    let n = values.len() as f64;
    h.values().map(|&c| { let p = c as f64 / n; -p * p.log2() }).sum()
}

fn main() {
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&std::env::args().nth(1).unwrap()), 30.0).unwrap();
    let (lo, hi) = seq.bounds().unwrap();
    let step = (hi - lo).max_element() / 4095.0;
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let h0 = build(&topo, &base_quadrics(&seq, &topo, &BaseOptions::default()), &BuildOptions::default()).unwrap();
    let adj = topo.clone();
    let mut enc = Encoder::new(h0, topo, seq.triangles.clone(), Default::default());
    let q = |p: glam::Vec3| { let x = ((p - lo) / step).round(); [x.x as i32, x.y as i32, x.z as i32] };
    let mut prev: Vec<[i32; 3]> = Vec::new();
    let (mut parent_res, mut nbr_res, mut temporal_res, mut mix_res) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut coarse_res = Vec::new();
    for frame in &seq.frames {
        enc.encode_frame(frame);
        let h = enc.hierarchy();
        let n0 = frame.len();
        let cur: Vec<[i32; 3]> = (0..h.node_count()).map(|g| q(if g < n0 { frame[g] } else { enc.recluster.nodes.positions[g] })).collect();
        if !prev.is_empty() {
            for v in 0..n0 {
                let p = (h.offsets[1] + h.parent[0][v]) as usize;
                // decoded neighbours: lower index
                let nb: Vec<usize> = adj.neighbours(v as u32).iter().map(|&u| u as usize).filter(|&u| u < v).collect();
                for a in 0..3 {
                    let pm = prev[v][a] + cur[p][a] - prev[p][a];
                    parent_res.push(cur[v][a] - pm);
                    temporal_res.push(cur[v][a] - prev[v][a]);
                    let nm = if nb.is_empty() { pm } else { prev[v][a] + (nb.iter().map(|&u| (cur[u][a] - prev[u][a]) as f64).sum::<f64>() / nb.len() as f64).round() as i32 };
                    nbr_res.push(cur[v][a] - nm);
                    let mm = if nb.is_empty() { pm } else { ((pm as f64 + nm as f64) / 2.0).round() as i32 };
                    mix_res.push(cur[v][a] - mm);
                }
            }
            for g in n0..h.node_count() {
                let (k, v) = h.local(g as u32);
                let pm = if k < h.top() { let p = (h.offsets[k + 1] + h.parent[k][v as usize]) as usize; [0, 1, 2].map(|a| prev[g][a] + cur[p][a] - prev[p][a]) } else { prev[g] };
                for a in 0..3 { coarse_res.push(cur[g][a] - pm[a]); }
            }
        }
        prev = cur;
    }
    let n0 = seq.vertex_count() as f64;
    for (name, r) in [("temporal", &temporal_res), ("parent motion", &parent_res), ("neighbour motion", &nbr_res), ("mix", &mix_res)] {
        let mean_abs = r.iter().map(|x| x.unsigned_abs() as f64).sum::<f64>() / r.len() as f64;
        let zz: Vec<u8> = r.iter().flat_map(|&x| { let mut o = Vec::new(); pmcodec_container::payload::put(&mut o, zigzag(x)); o }).collect();
        let z = zstd::bulk::compress(&zz, 19).unwrap().len();
        println!("level 0 {name:>16}: mean |r| {mean_abs:.2}, entropy {:.2} bits/coord = {:.2} bits/vertex; zstd(varint) {:.2} bits/vertex", entropy(r), 3.0 * entropy(r), z as f64 * 8.0 / (r.len() as f64 / 3.0));
    }
    println!("coarser nodes (parent motion): entropy {:.2} bits/coord over {} coords; per input vertex per frame {:.2} bits", entropy(&coarse_res), coarse_res.len(), entropy(&coarse_res) * coarse_res.len() as f64 / (n0 * (seq.frame_count() - 1) as f64));
}
