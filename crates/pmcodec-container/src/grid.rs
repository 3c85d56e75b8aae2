//! Stored positions on the quantization grid: among the grid points within the error bound of
//! a vertex's true position, the one whose residuals from the prediction cost the fewest bits
//! (the encoder's freedom within the bound, spent on the entropy coder).

/// The radius (in quanta) input vertices may move from their true position: the bound the
/// quantization states, |error| <= sqrt(3)/2 step (the farthest rounding goes), less a margin
/// for the f32 arithmetic of dequantization.
pub(crate) const SLACK2: f64 = 0.72;

/// An input vertex's stored position: among the grid points within `sqrt(radius2)` quanta of
/// its true position `t`, the one whose residuals from the prediction `p` are smallest (they
/// cost the fewest bits), nearer to `t` on ties; the nearest grid point if none is closer.
/// Returns the point and its residuals.
pub(crate) fn choose(t: [f64; 3], p: [i32; 3], radius2: f64) -> ([i32; 3], [i32; 3]) {
    // The prediction itself within reach: its zero residuals cost least, and no other point
    // costs nothing, so the search below would return it (it is among the 27 candidates: within
    // a radius under 1.5 of `t`, each coordinate is within 1 of `t`'s nearest grid point). Where
    // skinning predicts exactly (a glTF's own skin) this is most vertices of most frames.
    if (0..3).map(|a| (p[a] as f64 - t[a]).powi(2)).sum::<f64>() <= radius2 && radius2 < 2.25 {
        return (p, [0; 3]);
    }
    let near = t.map(|x| x.round() as i32);
    // Per axis, the three grid offsets' squared distances and residual costs: each of the 27
    // candidates' distance and cost is a sum of these, the same values added in the same
    // order as computing each candidate whole (this runs for every vertex of every frame).
    let axis = |a: usize| {
        [-1, 0, 1].map(|d| {
            let q = near[a] + d;
            (q, (q as f64 - t[a]).powi(2), q.wrapping_sub(p[a]).unsigned_abs() as u64)
        })
    };
    let (x, y, z) = (axis(0), axis(1), axis(2));
    let mut best = (u64::MAX, f64::INFINITY, near);
    for (i, &(qx, sx, cx)) in x.iter().enumerate() {
        for (j, &(qy, sy, cy)) in y.iter().enumerate() {
            let sxy = sx + sy;
            if sxy > radius2 && (i, j) != (1, 1) {
                // Squares are never negative: every z offset is out of reach too (the centre,
                // kept whatever its distance, has i = j = 1).
                continue;
            }
            for (l, &(qz, sz, cz)) in z.iter().enumerate() {
                let d2 = sxy + sz;
                if d2 > radius2 && (i, j, l) != (1, 1, 1) {
                    continue;
                }
                let cost = cx + cy + cz;
                if (cost, d2) < (best.0, best.1) {
                    best = (cost, d2, [qx, qy, qz]);
                }
            }
        }
    }
    let q = best.2;
    (q, [0, 1, 2].map(|a| q[a].wrapping_sub(p[a])))
}

/// A coarse node's stored position: the prediction plus a multiple of `2^shift` quanta per
/// axis, chosen as input vertices are (the smallest residuals within `sqrt(radius2)` grid
/// steps of the true offset), so its error stays within what rounding to the grid gives.
pub(crate) fn on_grid(t: [f64; 3], p: [i32; 3], shift: u32, radius2: f64) -> ([i32; 3], [i32; 3]) {
    let unit = (1u64 << shift) as f64;
    let (r, _) = choose([0, 1, 2].map(|a| (t[a] - p[a] as f64) / unit), [0; 3], radius2);
    ([0, 1, 2].map(|a| p[a].wrapping_add(r[a].wrapping_shl(shift))), r)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`choose`] as first written: each of the 27 candidates computed whole.
    fn choose_whole(t: [f64; 3], p: [i32; 3], radius2: f64) -> ([i32; 3], [i32; 3]) {
        let near = t.map(|x| x.round() as i32);
        let mut best = (u64::MAX, f64::INFINITY, near);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let q = [near[0] + dx, near[1] + dy, near[2] + dz];
                    let d2: f64 = (0..3).map(|a| (q[a] as f64 - t[a]).powi(2)).sum();
                    if d2 > radius2 && (dx, dy, dz) != (0, 0, 0) {
                        continue;
                    }
                    let cost: u64 = (0..3).map(|a| q[a].wrapping_sub(p[a]).unsigned_abs() as u64).sum();
                    if (cost, d2) < (best.0, best.1) {
                        best = (cost, d2, q);
                    }
                }
            }
        }
        let q = best.2;
        (q, [0, 1, 2].map(|a| q[a].wrapping_sub(p[a])))
    }

    #[test]
    fn choose_by_axes_is_choose_whole() {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let mut differs_from_nearest = 0;
        for i in 0..20_000 {
            let t = [0; 3].map(|_| (next() % 4000) as f64 / 7.0 - 280.0);
            // Predictions near and far, and grid-aligned truths (ties) now and then.
            let p = t.map(|x| x.round() as i32 + (next() % 7) as i32 - 3);
            let t = if i % 5 == 0 { t.map(|x| (x * 2.0).round() / 2.0) } else { t };
            for radius2 in [0.0, 0.25, 0.72, 1.0, 3.0] {
                let got = choose(t, p, radius2);
                assert_eq!(got, choose_whole(t, p, radius2), "t {t:?} p {p:?} radius2 {radius2}");
                differs_from_nearest += (got.0 != t.map(|x| x.round() as i32)) as u32;
            }
        }
        assert!(differs_from_nearest > 1000, "the slack was hardly ever used: {differs_from_nearest}");
    }
}
