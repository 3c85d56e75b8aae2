//! Development probe: empirical entropy of position residuals per band under several
//! predictors and coarse-level residual steps, closed loop, to see where the bits go.
//! `cargo run --release -p pmcodec-container --example residuals -- DIR [bits] [shift per level]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_hierarchy::base::{BaseOptions, base_quadrics};
use pmcodec_hierarchy::progressive::Encoder;
use pmcodec_hierarchy::{BuildOptions, FineTopology, build};
use std::collections::HashMap;

#[derive(Default)]
struct Hist {
    by_ctx: HashMap<(usize, i32), usize>,
    n: usize,
}
impl Hist {
    fn add(&mut self, ctx: usize, v: i32) {
        *self.by_ctx.entry((ctx, v)).or_default() += 1;
        self.n += 1;
    }
    /// Total bits: conditional entropy given ctx, times count.
    fn bits(&self, use_ctx: bool) -> f64 {
        self.bits_map(|c| if use_ctx { c } else { 0 })
    }
    fn bits_map(&self, m: impl Fn(usize) -> usize) -> f64 {
        let mut ctx_tot: HashMap<usize, usize> = HashMap::new();
        let mut merged: HashMap<(usize, i32), usize> = HashMap::new();
        for (&(c, v), &k) in &self.by_ctx {
            let c = m(c);
            *ctx_tot.entry(c).or_default() += k;
            *merged.entry((c, v)).or_default() += k;
        }
        merged.iter().map(|(&(c, _), &k)| -(k as f64) * (k as f64 / ctx_tot[&c] as f64).log2()).sum()
    }
}

fn bucket(s: u32) -> usize {
    match s {
        0 => 0,
        1 => 1,
        2..=3 => 2,
        4..=7 => 3,
        8..=15 => 4,
        _ => 5,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).unwrap();
    let bits: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(12);
    let shifts: Vec<u32> = args.get(3).map(|s| s.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or_default();
    let slack = args.get(4).is_some_and(|s| s == "slack");
    let (lo, hi) = seq.bounds().unwrap();
    let step = (hi - lo).max_element() / ((1u32 << bits) - 1) as f32;
    let topo = FineTopology::new(seq.vertex_count() as u32, &seq.triangles);
    let h0 = build(&topo, &base_quadrics(&seq, &topo, &BaseOptions::default()), &BuildOptions::default()).unwrap();
    let adj = topo.clone();
    let mut enc = Encoder::new(h0, topo, seq.triangles.clone(), Default::default());
    let tq = |p: glam::Vec3| {
        let x = (p - lo) / step;
        [x.x as f64, x.y as f64, x.z as f64]
    };
    let mut prev: Vec<[i32; 3]> = Vec::new();
    let mut prev2: Vec<[i32; 3]> = Vec::new();
    let names = ["parent", "neighbour", "mix", "parent+2nd", "mix+2nd"];
    let mut l0: Vec<Hist> = (0..names.len()).map(|_| Hist::default()).collect();
    let mut coarse: Vec<Hist> = Vec::new();
    let n0 = seq.vertex_count();
    let mut maxerr = 0f64;
    for frame in &seq.frames {
        enc.encode_frame(frame);
        let h = enc.hierarchy();
        let total = h.node_count();
        let truth: Vec<[f64; 3]> = (0..total).map(|g| tq(enc.node_positions()[g])).collect();
        let mut cur = vec![[0i32; 3]; total];
        if coarse.is_empty() {
            coarse = (0..h.levels()).map(|_| Hist::default()).collect();
        }
        if prev.is_empty() {
            for g in 0..total {
                cur[g] = truth[g].map(|x| x.round() as i32);
            }
        } else {
            for k in (0..h.levels()).rev() {
                let s = shifts.get(k).copied().unwrap_or(0);
                let mut last = 0u32;
                for v in 0..h.level_sizes[k] as usize {
                    let g = h.offsets[k] as usize + v;
                    let par = (k < h.top()).then(|| (h.offsets[k + 1] + h.parent[k][v]) as usize);
                    let pm = match par {
                        Some(p) => [0, 1, 2].map(|a| prev[g][a] + cur[p][a] - prev[p][a]),
                        None => prev[g],
                    };
                    let mut preds = vec![pm];
                    if k == 0 {
                        let nb: Vec<usize> = adj.neighbours(v as u32).iter().map(|&u| u as usize).filter(|&u| u < v).collect();
                        let nm = if nb.is_empty() {
                            pm
                        } else {
                            [0, 1, 2].map(|a| {
                                prev[v][a]
                                    + (nb.iter().map(|&u| cur[u][a] - prev[u][a]).sum::<i32>() as f64 / nb.len() as f64).round() as i32
                            })
                        };
                        let mm = [0, 1, 2].map(|a| ((pm[a] + nm[a]) as f64 / 2.0).round() as i32);
                        preds.push(nm);
                        preds.push(mm);
                        let sec = |base: [i32; 3]| {
                            if prev2.is_empty() {
                                base
                            } else {
                                let p = par.unwrap();
                                [0, 1, 2].map(|a| {
                                    base[a] + (((prev[g][a] - prev[p][a]) - (prev2[g][a] - prev2[p][a])) as f64 * 0.5).round() as i32
                                })
                            }
                        };
                        preds.push(sec(pm));
                        preds.push(sec(mm));
                    }
                    let unit = (1i32 << s) as f64;
                    let qs: Vec<i32> = (0..3).map(|a| ((truth[g][a] - preds[0][a] as f64) / unit).round() as i32).collect();
                    if k == 0 {
                        let sum: u32 = qs.iter().map(|x| x.unsigned_abs()).sum();
                        for (i, p) in preds.iter().enumerate() {
                            if !(slack && i == 4) {
                                for a in 0..3 {
                                    l0[i].add(bucket(last) * 3 + a, (truth[g][a].round() as i32) - p[a]);
                                }
                            }
                        }
                        last = sum;
                        cur[g] = truth[g].map(|x| x.round() as i32);
                        if slack {
                            // cheapest (L1 residual to the neighbour prediction) lattice point within the ball
                            let t = truth[g];
                            let p = preds[1];
                            let mut best = (u32::MAX, f64::MAX, cur[g]);
                            for dx in -1..=1 {
                                for dy in -1..=1 {
                                    for dz in -1..=1 {
                                        let q = [cur[g][0] + dx, cur[g][1] + dy, cur[g][2] + dz];
                                        let d2: f64 = (0..3).map(|a| (q[a] as f64 - t[a]).powi(2)).sum();
                                        if d2 > 0.75 {
                                            continue;
                                        }
                                        let c: u32 = (0..3).map(|a| (q[a] - p[a]).unsigned_abs()).sum();
                                        if (c, d2) < (best.0, best.1) {
                                            best = (c, d2, q);
                                        }
                                    }
                                }
                            }
                            cur[g] = best.2;
                            for a in 0..3 {
                                l0[4].add(bucket(last) * 3 + a, cur[g][a] - p[a]);
                            }
                        }
                    } else {
                        for (a, &q) in qs.iter().enumerate() {
                            coarse[k].add(bucket(last) * 3 + a, q);
                        }
                        last = qs.iter().map(|x| x.unsigned_abs()).sum();
                        cur[g] = [0, 1, 2].map(|a| preds[0][a] + (qs[a] << s));
                        for a in 0..3 {
                            maxerr = maxerr.max((cur[g][a] as f64 - truth[g][a]).abs() / unit);
                        }
                    }
                }
            }
        }
        prev2 = std::mem::replace(&mut prev, cur);
    }
    let vf = n0 as f64 * (seq.frame_count() - 1) as f64;
    for (i, name) in names.iter().enumerate() {
        println!("level 0 {name:>12}: {:.2} bits/v/f order0, {:.2} with ctx", l0[i].bits(false) / vf, l0[i].bits(true) / vf);
    }
    let b3 = |b: usize| match b {
        0 => 0,
        1..=2 => 1,
        _ => 2,
    };
    let h = &l0[4];
    println!(
        "slack l0: axis {:.2} b6 {:.2} b3 {:.2} b3xaxis {:.2} b6xaxis {:.2}",
        h.bits_map(|c| c % 3) / vf,
        h.bits_map(|c| c / 3) / vf,
        h.bits_map(|c| b3(c / 3)) / vf,
        h.bits_map(|c| b3(c / 3) * 3 + c % 3) / vf,
        h.bits(true) / vf
    );
    let c0: f64 = coarse.iter().map(|h| h.bits(false)).sum::<f64>() / vf;
    let c1: f64 = coarse.iter().map(|h| h.bits(true)).sum::<f64>() / vf;
    println!(
        "coarse levels (shifts {shifts:?}): {c0:.2} bits/input v/f order0, {c1:.2} with ctx; per level {:?}",
        coarse.iter().map(|h| format!("{:.2}", h.bits(true) / vf)).collect::<Vec<_>>()
    );
}
