//! Texture coordinates predicted from positions (proto/container.md, "Attributes, band 0 with
//! derived entries", *bind positions*): a corner x of a triangle whose edge (a, b) is known is
//! placed in texture space as its position lies against the edge in 3D, the ratio of its
//! projection along the edge and its distance from it carried over to the edge's texture
//! coordinates (Isenburg & Snoeyink, "Compressing texture coordinates with selective linear
//! predictions", 2003; Draco's texture-coordinate predictor projects the same way). In
//! integers only, so every decoder computes the same bits.

/// Coordinate differences at or beyond this make the projection fall back to the rule
/// without positions: i128 then still holds the squared cross product (below 2^116).
const LIMIT: u128 = 1 << 28;

/// The prediction of corner x's texture coordinates `[u, v]` from the edge (a, b): positions
/// `pa`, `pb`, `px`, texture coordinates `ua`, `ub`, and `side` (+1 or -1) the orientation of
/// the chart's triangles in texture space (x left of a -> b for +1). `None` for a degenerate
/// edge or differences of 2^28 or more.
///
/// With n = pb - pa, w = px - pa, d = ub - ua (integers): `u_x = ua + round((n.w d + side h
/// perp(d)) / n.n)`, h = isqrt(|n|^2 |w|^2 - (n.w)^2) (the cross product's length, scaled by
/// |n|) and perp(d) = (-d_v, d_u); round(y / m) = floor((2y + m) / (2m)).
pub fn predict(pa: [i64; 3], pb: [i64; 3], px: [i64; 3], ua: [i32; 2], ub: [i32; 2], side: i32) -> Option<[i32; 2]> {
    let n = [0, 1, 2].map(|k| pb[k] as i128 - pa[k] as i128);
    let w = [0, 1, 2].map(|k| px[k] as i128 - pa[k] as i128);
    if n.iter().chain(&w).any(|v| v.unsigned_abs() >= LIMIT) {
        return None;
    }
    let nn: i128 = n.iter().map(|v| v * v).sum();
    if nn == 0 {
        return None;
    }
    let dot: i128 = (0..3).map(|k| n[k] * w[k]).sum();
    let ww: i128 = w.iter().map(|v| v * v).sum();
    let h = isqrt((nn * ww - dot * dot).max(0)) * side.signum() as i128;
    let d = [ub[0] as i128 - ua[0] as i128, ub[1] as i128 - ua[1] as i128];
    let round = |y: i128| (2 * y + nn).div_euclid(2 * nn);
    // Wrapping to 32 bits, as every value of the traversal.
    let u = ua[0].wrapping_add(round(dot * d[0] - h * d[1]) as i32);
    let v = ua[1].wrapping_add(round(dot * d[1] + h * d[0]) as i32);
    Some([u, v])
}

/// The floor of the square root of `x` >= 0.
pub fn isqrt(x: i128) -> i128 {
    if x < 2 {
        return x.max(0);
    }
    // Newton's method from above: from a power of two at least the root, it decreases to the
    // floor and stops there.
    let mut r = 1i128 << (128 - x.leading_zeros()).div_ceil(2);
    loop {
        let next = (r + x / r) / 2;
        if next >= r {
            return r;
        }
        r = next;
    }
}

/// The orientation of three texture coordinates: the sign of the cross product of b - a and
/// c - a (+1 when c lies on the side [`predict`] takes for side +1), 0 when collinear.
pub fn orientation(a: [i32; 2], b: [i32; 2], c: [i32; 2]) -> i32 {
    let d = |p: [i32; 2]| [p[0] as i128 - a[0] as i128, p[1] as i128 - a[1] as i128];
    let (d1, d2) = (d(b), d(c));
    (d1[0] * d2[1] - d1[1] * d2[0]).signum() as i32
}

/// The order band 0's traversal visits the triangles in with bind positions: breadth first
/// within each chart, as an Edgebreaker-like traversal goes, so that a corner finds its edge's
/// two corners known (the projection's case) far more often than in input order (Fox's band
/// 0, estimated: 461 -> 363 B). For each triangle s ascending not yet reached, s is reached
/// and queued; a triangle taken from the queue goes into the order, and for its edges (v0 v1,
/// v1 v2, v2 v0) in turn, every triangle not yet reached of the same chart with both of the
/// edge's vertices as corners, ascending, is reached and queued.
pub fn breadth_first(triangles: &[[u32; 3]], chart_of: &[u32]) -> Vec<u32> {
    let n = triangles.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
    // The triangles at each vertex, ascending, each once.
    let mut start = vec![0usize; n + 1];
    let distinct = |t: &[u32; 3], i: usize| !t[..i].contains(&t[i]);
    for t in triangles {
        for i in 0..3 {
            if distinct(t, i) {
                start[t[i] as usize + 1] += 1;
            }
        }
    }
    for v in 0..n {
        start[v + 1] += start[v];
    }
    let mut at = start.clone();
    let mut incident = vec![0u32; start[n]];
    for (j, t) in triangles.iter().enumerate() {
        for i in 0..3 {
            if distinct(t, i) {
                incident[at[t[i] as usize]] = j as u32;
                at[t[i] as usize] += 1;
            }
        }
    }
    let mut reached = vec![false; triangles.len()];
    let mut order = Vec::with_capacity(triangles.len());
    let mut queue = std::collections::VecDeque::new();
    for s in 0..triangles.len() {
        if reached[s] {
            continue;
        }
        reached[s] = true;
        queue.push_back(s);
        while let Some(i) = queue.pop_front() {
            order.push(i as u32);
            let f = triangles[i];
            for k in 0..3 {
                let (a, b) = (f[k] as usize, f[(k + 1) % 3]);
                for &j in &incident[start[a]..start[a + 1]] {
                    let j = j as usize;
                    if !reached[j] && chart_of.get(j) == chart_of.get(i) && triangles[j].contains(&b) {
                        reached[j] = true;
                        queue.push_back(j);
                    }
                }
            }
        }
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn breadth_first_grows_each_chart_over_its_edges() {
        // A strip 0-1-2-3 in input order 3, 0, 2, 1 (chart 0), then a lone triangle of chart 1
        // sharing an edge with the strip, and a degenerate one.
        let tris = [[3, 4, 5], [0, 1, 2], [2, 3, 4], [1, 2, 3], [4, 5, 6], [7, 7, 8]];
        let charts = [0, 0, 0, 0, 1, 0];
        // From 0 ([3 4 5]): edge 3 4 reaches 2; then from 2: edge 2 3 reaches 3; from 3: edge
        // 1 2 reaches 1. Triangle 4 is another chart's: it starts its own.
        assert_eq!(breadth_first(&tris, &charts), vec![0, 2, 3, 1, 4, 5]);
        assert!(breadth_first(&[], &[]).is_empty());
    }

    #[test]
    fn isqrt_is_the_floor_of_the_root() {
        for x in (0..5000i128).chain([(1 << 100) - 1, 1 << 100, (1 << 116) + 12345, i128::MAX]) {
            let r = isqrt(x);
            assert!(r * r <= x && (r + 1).checked_mul(r + 1).is_none_or(|s| s > x), "isqrt({x}) = {r}");
        }
    }

    #[test]
    fn a_right_triangle_maps_to_its_texture_image() {
        // An isometric unwrap (texture = 2 x position in the xy plane): x lands exactly.
        let (pa, pb, px) = ([0, 0, 0], [10, 0, 0], [3, 4, 0]);
        let (ua, ub) = ([100, 100], [120, 100]);
        // x = (3, 4) lies left of a -> b (counter-clockwise): side +1.
        assert_eq!(orientation([0, 0], [10, 0], [3, 4]), 1);
        assert_eq!(predict(pa, pb, px, ua, ub, 1), Some([106, 108]));
        assert_eq!(predict(pa, pb, px, ua, ub, -1), Some([106, 92]));
        // The same in 3D tilted out of the plane: only lengths and the ratio count.
        assert_eq!(predict([0, 0, 0], [6, 0, 8], [0, 4, 0], [0, 0], [0, 10], 1), Some([-4, 0]));
        // Degenerate or out-of-range edges fall back.
        assert_eq!(predict(pa, pa, px, ua, ub, 1), None);
        assert_eq!(predict(pa, [1 << 28, 0, 0], px, ua, ub, 1), None);
    }
}
