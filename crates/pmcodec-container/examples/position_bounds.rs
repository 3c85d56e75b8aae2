//! Development probe: how far band 0's position coding (the input vertices, on frames that are
//! not keyframes) is from what its predictors could reach, to see which changes could pay.
//! Entropies are of per-frame, per-axis static tables, as the container's rANS codes them.
//!
//! - closed loop: the container's own predictors (`Mean`, `Affine`) and choice of grid point;
//! - breadth first: the same with band 0 decoded breadth first over the triangles' edges;
//! - exact references: the affine fit given the true positions of the previous frame and of the
//!   neighbours (what the predictor's model misses, without the quantization noise that decoded
//!   references carry);
//! - bidirectional: the affine fit from the interpolation of the decoded frames `s` before and
//!   after, for each span `s` a hierarchy of B-frames would use.
//!
//! `cargo run --release -p pmcodec-container --example position_bounds -- DIR [bits]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::VertexOrder;
use pmcodec_container::predict::{AffineFits, Band0Motion, LowerNeighbours, Siblings, StencilWeights, predict};
#[path = "common/entropy.rs"]
mod entropy;
use entropy::entropy;

/// The grid point within the error bound cheapest to code from `p`, as the encoder picks.
fn choose(t: [f64; 3], p: [i32; 3]) -> [i32; 3] {
    let near = t.map(|x| x.round() as i32);
    let mut best = (u64::MAX, f64::INFINITY, near);
    for d in 0..27 {
        let q = [near[0] + d % 3 - 1, near[1] + d / 3 % 3 - 1, near[2] + d / 9 - 1];
        let d2: f64 = (0..3).map(|a| (q[a] as f64 - t[a]).powi(2)).sum();
        if d2 > 0.72 && q != near {
            continue;
        }
        let cost: u64 = (0..3).map(|a| (q[a] - p[a]).unsigned_abs() as u64).sum();
        if (cost, d2) < (best.0, best.1) {
            best = (cost, d2, q);
        }
    }
    best.2
}

/// Codes frame `t` in closed loop from the reference `reference` (decoded positions), band 0
/// in input order: returns the decoded frame and the residuals' bits. Affine motion is fitted
/// on the reference unless keyframe `weights` are given.
fn code(
    lower: &LowerNeighbours,
    affine: bool,
    weights: Option<&StencilWeights>,
    reference: &[[i32; 3]],
    t: &[[f64; 3]],
) -> (Vec<[i32; 3]>, f64) {
    let n = t.len();
    let mut fits = AffineFits::default();
    fits.prepare(lower, reference, n);
    let motion = match (affine, weights) {
        (false, _) => Band0Motion::Mean,
        (true, None) => Band0Motion::Affine(&fits),
        (true, Some(w)) => Band0Motion::KeyframeAffine(w),
    };
    let siblings = Siblings::default();
    let mut cur = vec![[0i32; 3]; n];
    let mut res = Vec::with_capacity(n);
    for v in 0..n {
        let mut p = predict(0, v, v, v.checked_sub(1), None, lower, motion, &siblings, false, &cur, reference);
        // A vertex with no lower neighbour moves, in the container, as its decoded siblings
        // do; here (no hierarchy) as the vertex decoded before it.
        if lower.row(v).is_empty() && v > 0 {
            p = [0, 1, 2].map(|a| reference[v][a] + cur[v - 1][a] - reference[v - 1][a]);
        }
        cur[v] = choose(t[v], p);
        res.push([0, 1, 2].map(|a| cur[v][a] - p[a]));
    }
    let bits = entropy(&res);
    (cur, bits)
}

/// The affine fit of the crate's predictor in plain f64, from any reference and current
/// positions (for the exact-reference bound).
fn affine_exact(stencil: &[u32], v: usize, r: &[[f64; 3]], c: &[[f64; 3]]) -> [f64; 3] {
    let m = stencil.len() as f64;
    let (mut sa, mut sb) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    let (mut saa, mut sba) = (glam::DMat3::ZERO, glam::DMat3::ZERO);
    let o = glam::DVec3::from_array(r[v]);
    for &w in stencil {
        let a = glam::DVec3::from_array(r[w as usize]) - o;
        let b = glam::DVec3::from_array(c[w as usize]) - glam::DVec3::from_array(r[w as usize]);
        sa += a;
        sb += b;
        saa += glam::DMat3::from_cols(a * a.x, a * a.y, a * a.z);
        sba += glam::DMat3::from_cols(b * a.x, b * a.y, b * a.z);
    }
    let outer = |x: glam::DVec3, y: glam::DVec3| glam::DMat3::from_cols(x * y.x, x * y.y, x * y.z);
    let scatter = saa * m - outer(sa, sa);
    let t = (scatter.x_axis.x + scatter.y_axis.y + scatter.z_axis.z) / m / 64.0 + m;
    let d = (sba * m - outer(sb, sa)) * (scatter + glam::DMat3::from_diagonal(glam::DVec3::splat(t))).inverse();
    (o + sb / m - d * (sa / m)).to_array()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seq = pmcodec_mesh::obj::load_obj_sequence(std::path::Path::new(&args[1]), 30.0).expect("load");
    let bits: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(12);
    let (lo, hi) = seq.bounds().expect("bounds");
    let step = ((hi - lo).max_element() / ((1u32 << bits) - 1) as f32) as f64;
    let n = seq.vertex_count();
    let frames: Vec<Vec<[f64; 3]>> =
        seq.frames.iter().map(|f| f.iter().map(|p| ((*p - lo).as_dvec3() / step).to_array()).collect()).collect();
    let nf = frames.len();
    let per = |b: f64, count: usize| b / (n * count) as f64;

    // Breadth-first order: relabel the vertices so that input order is that order.
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in &seq.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
    }
    adj.iter_mut().for_each(|a| {
        a.sort_unstable();
        a.dedup()
    });
    let mut seen = vec![false; n];
    let mut bfs = Vec::with_capacity(n);
    for s in 0..n {
        if !seen[s] {
            seen[s] = true;
            let mut head = bfs.len();
            bfs.push(s);
            while head < bfs.len() {
                let v = bfs[head];
                head += 1;
                for &u in &adj[v] {
                    if !std::mem::replace(&mut seen[u as usize], true) {
                        bfs.push(u as usize);
                    }
                }
            }
        }
    }
    let mut rank = vec![0u32; n];
    for (k, &v) in bfs.iter().enumerate() {
        rank[v] = k as u32;
    }
    let relabelled: Vec<[u32; 3]> = seq.triangles.iter().map(|t| t.map(|v| rank[v as usize])).collect();
    let bfs_frames: Vec<Vec<[f64; 3]>> = frames.iter().map(|f| bfs.iter().map(|&v| f[v]).collect()).collect();

    let input = LowerNeighbours::new(n, &seq.triangles, VertexOrder::Input);
    let breadth = LowerNeighbours::new(n, &relabelled, VertexOrder::Input);
    let alone = |l: &LowerNeighbours| (0..n).filter(|&v| l.row(v).is_empty()).count();
    println!("vertices without a lower neighbour: {} in input order, {} breadth first", alone(&input), alone(&breadth));
    println!("{}: {n} vertices, {nf} frames, {bits}-bit grid; band 0, frames 1.. in closed loop (bits/vertex/frame)", args[1]);
    let mut decoded: Vec<Vec<[i32; 3]>> = Vec::new();
    for (name, lower, fr) in [("input order", &input, &frames), ("breadth first", &breadth, &bfs_frames)] {
        for affine in [false, true] {
            let mut prev: Vec<[i32; 3]> = fr[0].iter().map(|p| p.map(|x| x.round() as i32)).collect();
            let mut total = 0.0;
            let mut out = vec![prev.clone()];
            for t in &fr[1..] {
                let (cur, b) = code(lower, affine, None, &prev, t);
                total += b;
                out.push(cur.clone());
                prev = cur;
            }
            println!("  {name}, {}: {:.2}", if affine { "affine" } else { "mean" }, per(total, nf - 1));
            if affine && name == "input order" {
                decoded = out;
            }
        }
    }

    // The affine predictor given exact references: its model error alone.
    let mut exact = 0.0;
    for f in 1..nf {
        let (r, c) = (&frames[f - 1], &frames[f]);
        let res: Vec<[i32; 3]> = (0..n)
            .map(|v| {
                let st = input.stencil(v);
                let p = match (st.is_empty(), v.checked_sub(1)) {
                    (false, _) => affine_exact(st, v, r, c),
                    (true, Some(u)) => [0, 1, 2].map(|a| r[v][a] + c[u][a] - r[u][a]),
                    (true, None) => r[v],
                };
                [0, 1, 2].map(|a| (c[v][a] - p[a]).round() as i32)
            })
            .collect();
        exact += entropy(&res);
    }
    println!("  input order, affine, exact references (no quantization noise): {:.2}", per(exact, nf - 1));

    // Keyframe affine motion: the fit's weights taken from an earlier frame's geometry.
    for every in [1usize, 4, 16, 0] {
        let mut prev: Vec<[i32; 3]> = frames[0].iter().map(|p| p.map(|x| x.round() as i32)).collect();
        let mut weights = StencilWeights::default();
        weights.compute(&input, &prev, n);
        let mut total = 0.0;
        for (f, t) in frames.iter().enumerate().skip(1) {
            if every > 0 && (f - 1) % every == 0 {
                weights.compute(&input, &prev, n);
            }
            let (cur, b) = code(&input, true, Some(&weights), &prev, t);
            total += b;
            prev = cur;
        }
        let from = if every == 0 { "frame 0".to_string() } else { format!("the frame before, every {every} frames") };
        println!("  input order, affine, weights from {from}: {:.2}", per(total, nf - 1));
    }

    // Residuals on a grid centred on the unrounded prediction (positions then off the fixed
    // grid, in 1/256 of a quantum), so a vertex whose prediction is good adds no rounding
    // noise to the references of the ones after it.
    for centred in [false, true] {
        let mut prev: Vec<[f64; 3]> = frames[0].iter().map(|p| p.map(f64::round)).collect();
        let mut total = 0.0;
        for t in &frames[1..] {
            let mut cur = vec![[0f64; 3]; n];
            let mut res = Vec::with_capacity(n);
            for v in 0..n {
                let st = input.stencil(v);
                let p = match (st.is_empty(), v.checked_sub(1)) {
                    (false, _) => affine_exact(st, v, &prev, &cur),
                    (true, Some(u)) => [0, 1, 2].map(|a| prev[v][a] + cur[u][a] - prev[u][a]),
                    (true, None) => prev[v],
                };
                let p = p.map(|x| if centred { (x * 256.0).round() / 256.0 } else { (x + 0.5).floor() });
                // The cheapest residual whose point lies within the bound.
                let near = [0, 1, 2].map(|a| (t[v][a] - p[a]).round() as i32);
                let mut best = (u32::MAX, f64::INFINITY, near);
                for d in 0..27 {
                    let r = [near[0] + d % 3 - 1, near[1] + d / 3 % 3 - 1, near[2] + d / 9 - 1];
                    let d2: f64 = (0..3).map(|a| (p[a] + r[a] as f64 - t[v][a]).powi(2)).sum();
                    let cost = r.iter().map(|x| x.unsigned_abs()).sum::<u32>();
                    if (d2 <= 0.72 || r == near) && (cost, d2) < (best.0, best.1) {
                        best = (cost, d2, r);
                    }
                }
                cur[v] = [0, 1, 2].map(|a| p[a] + best.2[a] as f64);
                res.push(best.2);
            }
            total += entropy(&res);
            prev = cur;
        }
        println!(
            "  input order, affine in f64, residuals on a grid {}: {:.2}",
            if centred { "centred on the prediction" } else { "of whole quanta" },
            per(total, nf - 1)
        );
    }

    // Bidirectional: the reference is the interpolation of the decoded frames s before and after.
    for s in [1usize, 2, 4, 8] {
        let (mut b_bits, mut p_bits, mut count) = (0.0, 0.0, 0);
        for f in s..nf.saturating_sub(s) {
            let mid: Vec<[i32; 3]> =
                (0..n).map(|v| [0, 1, 2].map(|a| (decoded[f - s][v][a] + decoded[f + s][v][a] + 1).div_euclid(2))).collect();
            b_bits += code(&input, true, None, &mid, &frames[f]).1;
            p_bits += code(&input, true, None, &decoded[f - 1], &frames[f]).1;
            count += 1;
        }
        println!(
            "  input order, affine, from the mean of the decoded frames {s} before and after: {:.2} (from the frame before: {:.2})",
            per(b_bits, count),
            per(p_bits, count)
        );
    }
}
