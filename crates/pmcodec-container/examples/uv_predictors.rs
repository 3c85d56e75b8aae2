//! A measurement, not a coding: what band 0's texture-coordinate residuals would cost with
//! predictions that use frame 0's decoded positions (issue 16's size bar), beside the
//! parallelogram rule the container uses (`traverse` in appearance/payload.rs).
//!
//! Every variant walks band 0 as the derived coding does (triangles in input order, each
//! one's corners in order, the representatives of band 1 known from the start) and differs
//! only where a corner's two edge neighbours are known:
//! - `parallelogram`: `a + b - o` across an earlier triangle's edge, else the edge's midpoint
//!   (the container's rule; Touma & Gotsman, "Triangle mesh compression", 1998).
//! - `positions, side from opposite`: the corner's 3D position projected onto the edge, the
//!   ratio along it and the perpendicular distance (relative to the edge length) carried into
//!   texture space, on the side of the edge away from the opposite corner o (Isenburg &
//!   Snoeyink, "Compressing texture coordinates with selective linear predictions", 2003,
//!   and Draco's texture-coordinate predictor work from the same projection); without o, the
//!   chart's orientation (below).
//! - `positions, side from chart`: the side from the orientation of the chart's last triangle
//!   whose three values are known (a chart is rarely mirrored within itself), whether or not o
//!   exists; +1 before any.
//! - `positions, ideal side + 1 bit`: the better side each time, plus one bit per prediction
//!   (an upper bound for coding the flip explicitly, as Draco does with its orientation bits).
//!
//! Every band below the top is measured the same way over its faces in frame 0 (`band_faces`;
//! entries no face reaches are left out, they are predicted from the band above alike), each
//! variant also with the band above's value of the corner's parent entry averaged in, as the
//! container's values across a band's faces (mode `| 64`) do.
//!
//! The cost is an estimate of the rANS residual section (`put_codes`): per channel the
//! empirical entropy of the residual codes' bit lengths plus their raw bits below the
//! highest; the stored chunk's own size is printed beside it.
//!
//! - `positions, side from chart, integers`: the same in integers only (`projected_int`), as a
//!   coding both decoders compute alike would.
//!
//! With `--bind`, the positions are a skinned file's bind positions (its Bind chunks, which
//! every skinned client reads) instead of frame 0's decoded ones (which a client starting at a
//! later keyframe would have to read besides its own: printed as "frame 0's position chunks").
//!
//! `target/debug/pmcodec encode -q IN.glb -o /tmp/a.pmc &&
//!  cargo run -p pmcodec-container --example uv_predictors -- /tmp/a.pmc [--bind]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use pmcodec_container::appearance::across::band_faces;
use pmcodec_container::appearance::payload::{Table, needs_above, read_band_bind, read_charts_with, read_table_across, representatives};
use pmcodec_container::appearance::project::predict;
use pmcodec_container::payload::{read_key, read_triangles, zigzag};
use pmcodec_container::{ChunkKind, Decoder, FileSource, Reader};

#[derive(Clone, Copy, PartialEq)]
enum Side {
    Parallelogram,
    Opposite,
    Chart,
    Ideal,
    /// Side from the chart, [`projected_int`] (integers only).
    ChartInt,
}

/// Estimated bytes of per-channel residual codes (bit-length entropy plus raw mantissa bits).
fn cost(residuals: &[Vec<u32>]) -> f64 {
    let mut bits = 0.0;
    for ch in residuals {
        let mut counts = [0usize; 33];
        for &z in ch {
            let b = 32 - z.leading_zeros();
            counts[b as usize] += 1;
            bits += b.saturating_sub(1) as f64;
        }
        let n = ch.len() as f64;
        bits += counts.iter().filter(|&&c| c > 0).map(|&c| -(c as f64) * (c as f64 / n).log2()).sum::<f64>();
    }
    bits / 8.0
}

fn round(x: f64) -> i64 {
    (x + 0.5).floor() as i64
}

/// The two position-based predictions of x across edge (a, b) (one per side), or None for a
/// degenerate edge.
fn projected(p: [[i64; 3]; 3], ua: [i64; 2], ub: [i64; 2]) -> Option<[[i64; 2]; 2]> {
    let [pa, pb, px] = p;
    let pn: Vec<i64> = (0..3).map(|k| pb[k] - pa[k]).collect();
    let cn: Vec<i64> = (0..3).map(|k| px[k] - pa[k]).collect();
    let pn2: i64 = pn.iter().map(|v| v * v).sum();
    if pn2 == 0 {
        return None;
    }
    let dot: i64 = (0..3).map(|k| pn[k] * cn[k]).sum();
    let cn2: i64 = cn.iter().map(|v| v * v).sum();
    let cross2 = (cn2 as i128 * pn2 as i128 - dot as i128 * dot as i128).max(0) as f64;
    let s = dot as f64 / pn2 as f64;
    let r = cross2.sqrt() / pn2 as f64;
    let d = [ub[0] - ua[0], ub[1] - ua[1]];
    let base = [ua[0] as f64 + s * d[0] as f64, ua[1] as f64 + s * d[1] as f64];
    let off = [-(d[1] as f64) * r, d[0] as f64 * r];
    Some([[round(base[0] + off[0]), round(base[1] + off[1])], [round(base[0] - off[0]), round(base[1] - off[1])]])
}

/// [`projected`] in integers only, as the decoders compute it (the library's
/// `appearance::project::predict`, the *bind positions* coding), for both sides of the edge.
fn projected_int(p: [[i64; 3]; 3], ua: [i64; 2], ub: [i64; 2]) -> Option<[[i64; 2]; 2]> {
    let (ua, ub) = (ua.map(|x| x as i32), ub.map(|x| x as i32));
    let side = |s: i32| predict(p[0], p[1], p[2], ua, ub, s).map(|u| u.map(i64::from));
    Some([side(1)?, side(-1)?])
}

fn orient(u: [[i64; 2]; 3]) -> i64 {
    ((u[1][0] - u[0][0]) * (u[2][1] - u[0][1]) - (u[1][1] - u[0][1]) * (u[2][0] - u[0][0])).signum()
}

/// Band 0's residuals under `side` (see the header), representatives `known` from the start.
/// Only the first two channels (the texture coordinates) are measured: `c` is the stride.
#[allow(clippy::too_many_arguments)]
fn residuals(
    t: &Table,
    c: usize,
    tris: &[[u32; 3]],
    chart_of: &[u32],
    pos: &[[i32; 3]],
    known0: &[bool],
    side: Side,
    (base, parent): (usize, Option<(&[u32], &Table)>),
) -> (Vec<Vec<u32>>, usize, usize) {
    let mut known = known0.to_vec();
    let v = |x: usize| [t.values[c * x] as i64, t.values[c * x + 1] as i64];
    let mut opposite = std::collections::HashMap::new();
    let key = |a: usize, b: usize| ((a.min(b) as u64) << 32) | a.max(b) as u64;
    let charts = chart_of.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
    let mut chart_orient = vec![1i64; charts];
    let mut chart_last: Vec<Option<[i64; 2]>> = vec![None; charts];
    let mut last = [0i64; 2];
    let mut out = vec![Vec::new(), Vec::new()];
    let mut flips = 0;
    let mut against = 0;
    for (ti, tri) in tris.iter().enumerate() {
        let chart = chart_of[ti] as usize;
        let e: Vec<usize> = tri.iter().map(|&n| t.find(n, chart as u32).unwrap()).collect();
        for i in 0..3 {
            let x = e[i];
            if known[x] {
                continue;
            }
            let (a, b) = (e[(i + 1) % 3], e[(i + 2) % 3]);
            let o = opposite.get(&key(a, b)).copied();
            // The band above's value of the corner's parent entry (averaged in, as the
            // container's values across a band's faces do).
            let pv =
                parent.and_then(|(par, above)| above.get(*par.get(tri[i] as usize)?, chart as u32, c)).map(|w| [w[0] as i64, w[1] as i64]);
            let pred: [i64; 2] = match (known[a], known[b]) {
                (true, true) => {
                    let (ua, ub) = (v(a), v(b));
                    let p = [tri[(i + 1) % 3], tri[(i + 2) % 3], tri[i]].map(|n| pos[base + n as usize].map(i64::from));
                    let proj = if side == Side::ChartInt { projected_int(p, ua, ub) } else { projected(p, ua, ub) };
                    match (side, proj) {
                        (Side::Parallelogram, _) | (_, None) => match o {
                            Some(o) => [0, 1].map(|q| ua[q] + ub[q] - v(o)[q]),
                            None => [0, 1].map(|q| (ua[q] + ub[q]) >> 1),
                        },
                        (Side::Ideal, Some(c)) => {
                            flips += 1;
                            let err = |p: [i64; 2]| (p[0] - v(x)[0]).abs() + (p[1] - v(x)[1]).abs();
                            let first = err(c[0]) <= err(c[1]);
                            if first != (chart_orient[chart] >= 0) && err(c[0]) != err(c[1]) {
                                against += 1;
                            }
                            if first { c[0] } else { c[1] }
                        }
                        (Side::Opposite, Some(c)) if o.is_some() => {
                            let uo = v(o.unwrap());
                            // The side of (a, b, o) in texture space; x lies on the other.
                            if orient([ua, ub, uo]) > 0 { c[1] } else { c[0] }
                        }
                        (_, Some(c)) => {
                            if chart_orient[chart] >= 0 {
                                c[0]
                            } else {
                                c[1]
                            }
                        }
                    }
                }
                (true, false) => v(a),
                (false, true) => v(b),
                (false, false) => pv.or(chart_last[chart]).unwrap_or(last),
            };
            let pred = match pv {
                Some(p) if known[a] || known[b] => [0, 1].map(|q| (pred[q] + p[q]) >> 1),
                _ => pred,
            };
            for q in 0..2 {
                out[q].push(zigzag((v(x)[q] - pred[q]) as i32));
            }
            known[x] = true;
            last = v(x);
            chart_last[chart] = Some(v(x));
        }
        if e[0] != e[1] && e[1] != e[2] && e[2] != e[0] {
            let o = orient([v(e[0]), v(e[1]), v(e[2])]);
            if o != 0 {
                chart_orient[chart] = o;
            }
            for i in 0..3 {
                opposite.entry(key(e[i], e[(i + 1) % 3])).or_insert(e[(i + 2) % 3]);
            }
        }
    }
    (out, flips, against)
}

/// `faces` (with charts `chart_of`) reordered: charts in order of their first face, each
/// chart's faces breadth first over shared edges from its first face (then any left, likewise).
fn breadth_first(faces: &[[u32; 3]], chart_of: &[u32]) -> (Vec<[u32; 3]>, Vec<u32>) {
    let mut by_edge: std::collections::HashMap<(u32, u32, u32), Vec<usize>> = Default::default();
    for (i, f) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b), chart_of[i])).or_default().push(i);
        }
    }
    let mut seen = vec![false; faces.len()];
    let (mut out, mut out_c) = (Vec::new(), Vec::new());
    for start in 0..faces.len() {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        let mut queue = std::collections::VecDeque::from([start]);
        while let Some(i) = queue.pop_front() {
            out.push(faces[i]);
            out_c.push(chart_of[i]);
            let f = faces[i];
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                for &j in &by_edge[&(a.min(b), a.max(b), chart_of[i])] {
                    if !seen[j] {
                        seen[j] = true;
                        queue.push_back(j);
                    }
                }
            }
        }
    }
    (out, out_c)
}

/// A skinned file's bind positions of the level-0 nodes (band 0 may predict from them).
fn bind0(path: &str) -> Option<Vec<[i64; 3]>> {
    let mut d = pmcodec_container::Decoder::new(Reader::open(FileSource::open(std::path::Path::new(path)).ok()?).ok()?, 0).ok()?;
    d.seek(0).ok()?;
    let n = d.reader().header().level_sizes[0] as usize;
    d.skin().map(|(nodes, _)| nodes[..n].iter().map(|s| s.bind).collect())
}

fn main() {
    let bind = std::env::args().any(|a| a == "--bind");
    for path in std::env::args().skip(1).filter(|a| a != "--bind") {
        let reader = Reader::open(FileSource::open(std::path::Path::new(&path)).unwrap()).unwrap();
        let h = reader.header().clone();
        let Some(info) = h.appearance.clone() else { continue };
        let c = info.channels();
        if info.uv_sets == 0 {
            continue;
        }
        let te = reader.index().chunks.iter().find(|e| e.kind == ChunkKind::Triangles).unwrap();
        let tris = read_triangles(&reader.read_chunk(te).unwrap(), "t", h.triangle_count, h.vertex_count, reader.version()).unwrap();
        let ce = reader.find(ChunkKind::Charts, 0, 0).unwrap();
        let charts = read_charts_with(&reader.read_chunk(ce).unwrap(), &info, h.triangle_count, Some(&tris)).unwrap();
        let key = |i: usize| {
            read_key(
                &reader.read_chunk(reader.find(ChunkKind::Key, 0, i as u32).unwrap()).unwrap(),
                "k",
                &h.level_sizes,
                i,
                reader.version(),
            )
            .unwrap()
        };
        // Every band's table, top down, as the decoder reads them.
        let mut tables: Vec<Option<Table>> = vec![None; h.levels()];
        let mut stored = vec![0u64; h.levels()];
        for j in (0..h.levels()).rev() {
            let e = reader.find(ChunkKind::Attributes, 0, j as u32).unwrap();
            stored[j] = e.stored_len as u64;
            let raw = reader.read_chunk(e).unwrap();
            let parent = needs_above(&raw).then(|| key(j));
            let above_of = parent.as_ref().and_then(|p| tables.get(j + 1).and_then(Option::as_ref).map(|t| (&p[..], t)));
            let t = if j > 0 {
                let parents: Vec<Vec<u32>> = (0..j).map(key).collect();
                let refs: Vec<&[u32]> = parents.iter().map(Vec::as_slice).collect();
                let (f, fc) = band_faces(&tris, &charts.triangle_chart, &refs).unwrap();
                read_table_across(&raw, "t", h.level_sizes[j], &info, h.triangle_count, above_of, Some((&f, &fc))).unwrap()
            } else {
                read_band_bind(
                    &raw,
                    "t",
                    h.level_sizes[j],
                    &info,
                    (h.triangle_count, Some((&tris, &charts.triangle_chart))),
                    above_of,
                    bind0(&path).as_deref(),
                )
                .unwrap()
            };
            tables[j] = Some(t);
        }
        // Frame 0 at level 0: every level's node positions (global ids, level 0 first).
        let mut d = Decoder::new(Reader::open(FileSource::open(std::path::Path::new(&path)).unwrap()).unwrap(), 0).unwrap();
        d.seek(0).unwrap();
        let pos: Vec<[i32; 3]> = if bind {
            // Bind positions (skinned files): every skinned client reads them, frame 0's or not.
            let Some((nodes, _)) = d.skin() else { continue };
            nodes.iter().map(|n| n.bind.map(|x| x as i32)).collect()
        } else {
            d.quantized().to_vec()
        };
        // What a client starting at a later keyframe would read more to have frame 0's positions.
        let frame0: u64 = reader
            .index()
            .chunks
            .iter()
            .filter(|e| e.frame == 0 && matches!(e.kind, ChunkKind::Positions | ChunkKind::Pose | ChunkKind::Palette | ChunkKind::Joints))
            .map(|e| e.stored_len as u64)
            .sum();
        println!("  frame 0's position (or pose) chunks, every band: {frame0} B");
        println!("{path}: {c} channels, the first two (texture coordinates) measured; the band's faces in frame 0 only");
        for j in 0..h.levels() - 1 {
            let (t, up) = (tables[j].as_ref().unwrap(), tables[j + 1].as_ref().unwrap());
            let par = key(j);
            let known: Vec<bool> = representatives(t, &par, up).iter().map(Option::is_some).collect();
            let parents: Vec<Vec<u32>> = (0..j).map(key).collect();
            let refs: Vec<&[u32]> = parents.iter().map(Vec::as_slice).collect();
            let (f, fc) = band_faces(&tris, &charts.triangle_chart, &refs).unwrap();
            let base_node: usize = h.level_sizes[..j].iter().map(|&n| n as usize).sum();
            println!(
                "  band {j}: stored {} B, {} entries, {} representatives, {} faces",
                stored[j],
                t.len(),
                known.iter().filter(|&&k| k).count(),
                f.len()
            );
            let run = |side, avg: bool| {
                let (r, flips, against) = residuals(t, c, &f, &fc, &pos, &known, side, (base_node, avg.then_some((&par[..], up))));
                (cost(&r) + flips as f64 / 8.0, flips, against)
            };
            let base = run(Side::Parallelogram, false).0;
            // The same faces in a breadth-first order within each chart (charts by first face,
            // each grown from its first face over shared edges), as an Edgebreaker-like
            // traversal visits them: more corners find their edge known with an opposite.
            let (bf, bfc) = breadth_first(&f, &fc);
            let bfs = |side| cost(&residuals(t, c, &bf, &bfc, &pos, &known, side, (base_node, None)).0);
            for (name, side) in
                [("parallelogram, faces breadth first", Side::Parallelogram), ("positions, faces breadth first", Side::Chart)]
            {
                let v = bfs(side);
                println!("    {name:45} ~{v:6.0} B ({:+.1}%)", 100.0 * (v - base) / base);
            }
            // How many of the coded (non-representative) entries the faces reach at all.
            let on_faces = residuals(t, c, &f, &fc, &pos, &known, Side::Parallelogram, (base_node, None)).0[0].len();
            println!("    {on_faces} of {} coded entries on a face of frame 0", known.iter().filter(|&&k| !k).count());
            for avg in [false, true] {
                for (name, side) in [
                    ("parallelogram", Side::Parallelogram),
                    ("positions, side from opposite", Side::Opposite),
                    ("positions, side from chart", Side::Chart),
                    ("positions, side from chart, integers", Side::ChartInt),
                    ("positions, ideal side + 1 bit", Side::Ideal),
                ] {
                    let (c, flips, against) = run(side, avg);
                    let name = format!("{name}{}", if avg { ", with parent" } else { "" });
                    let note = if flips > 0 {
                        format!("; {against} of {flips} best sides against the chart's orientation")
                    } else {
                        String::new()
                    };
                    println!("    {name:45} ~{c:6.0} B ({:+.1}%{note})", 100.0 * (c - base) / base);
                }
            }
        }
    }
}
