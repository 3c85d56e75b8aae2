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

/// How far (in the band's grid steps, squared) a coarse node stored by [`on_surface_grid`] may
/// stray from its cluster's surface: a root-mean-square distance to the cluster's planes of
/// 0.3 steps more than at its true position. Measured on horse, samba, cat and their open
/// versions (issue 15): the frame-0 error of the coarse levels came within 1-3% of their
/// unquantized error, where the cheapest point within reach (of [`on_grid`]) lost up to 10%.
pub(crate) const SURFACE_TOLERANCE2: f64 = 0.09;

/// A candidate's rank in [`on_surface_grid`]: (outside the tolerance, cost, excess, distance).
type Rank = (bool, u64, f64, f64);

/// A coarse node's stored position as [`on_grid`] chooses it, but kept on its cluster's
/// surface: among the grid points (multiples of `2^shift` quanta from the prediction `p`)
/// within `sqrt(radius2)` grid steps of the true position `t`, those whose mean squared
/// distance to the cluster's planes exceeds that of `t` by at most [`SURFACE_TOLERANCE2`]
/// grid steps squared are taken first, the cheapest of them (smallest residuals) nearest the
/// surface on ties; if none is, the one nearest the surface. `excess(x)` is that excess of a
/// point `x` (in quanta) in quanta squared: the node's quadric error increase over `t` per
/// unit area (Garland & Heckbert, "Surface simplification using quadric error metrics",
/// 1997: the quadric is the area-weighted sum of squared distances to the cluster's planes).
///
/// The plain cheapest point may sit a step off the surface (most visibly across a thin part or
/// on a coarse level, whose grid is up to 2^j quanta), which raises the level's error far more
/// than a step along the surface does. Only the encoder's choice changes: the residuals are
/// decoded as [`on_grid`]'s are.
pub(crate) fn on_surface_grid(
    t: [f64; 3],
    p: [i32; 3],
    shift: u32,
    radius2: f64,
    excess: impl Fn([f64; 3]) -> f64,
) -> ([i32; 3], [i32; 3]) {
    let unit = (1u64 << shift) as f64;
    let u = [0, 1, 2].map(|a| (t[a] - p[a] as f64) / unit);
    let near = u.map(|x| x.round() as i32);
    // (taken within the tolerance, cost, excess, distance): a smaller tuple is better, a
    // point within the tolerance before any other.
    let cost_of = |r: [i32; 3]| -> u64 { r.iter().map(|&x| x.unsigned_abs() as u64).sum() };
    let excess_of = |r: [i32; 3]| {
        let q = [0, 1, 2].map(|a| p[a] as f64 + r[a] as f64 * unit);
        let e = excess(q) / (unit * unit);
        // NaN (a degenerate quadric) is never within the tolerance, and ranks last.
        if e.is_nan() { f64::INFINITY } else { e }
    };
    // The centre (the nearest grid point) is always a candidate: evaluated first, its rank
    // bounds the others'. A candidate costing more than a point known to be within the
    // tolerance ranks after it whatever its excess, so its quadric is not evaluated (the
    // choice is the same as evaluating all 27 in order: see the test against that).
    let centre = excess_of(near);
    let mut bound = (centre <= SURFACE_TOLERANCE2).then(|| cost_of(near));
    let mut best: Option<(Rank, [i32; 3])> = None;
    for dx in -1..=1 {
        for dy in -1..=1 {
            for dz in -1..=1 {
                let r = [near[0] + dx, near[1] + dy, near[2] + dz];
                let d2: f64 = (0..3).map(|a| (r[a] as f64 - u[a]).powi(2)).sum();
                let is_centre = (dx, dy, dz) == (0, 0, 0);
                if d2 > radius2 && !is_centre {
                    continue;
                }
                let cost = cost_of(r);
                if bound.is_some_and(|b| cost > b) {
                    continue;
                }
                let e = if is_centre { centre } else { excess_of(r) };
                let within = e <= SURFACE_TOLERANCE2;
                let key = if within { (false, cost, e, d2) } else { (true, 0, e, d2) };
                if best.as_ref().is_none_or(|(k, _)| key.partial_cmp(k) == Some(std::cmp::Ordering::Less)) {
                    best = Some((key, r));
                    if within {
                        bound = Some(bound.map_or(cost, |b| b.min(cost)));
                    }
                }
            }
        }
    }
    let r = best.map_or(near, |(_, r)| r);
    ([0, 1, 2].map(|a| p[a].wrapping_add(r[a].wrapping_shl(shift))), r)
}

/// Bits that a grid step squared of a coarse node's excess (its squared distance from its
/// cluster's surface) is worth, per node whose residuals are not all zero: what the band's
/// next finer grid would pay for as much. A coarse band's grid is a power of two quanta
/// (`crate::coarse_shift`); halving its step `d` costs about a bit per axis of each node whose
/// residuals are not all zero (they double; a node predicted exactly stays at zero) and takes
/// three quarters of the rounding's squared error along a normal, `d^2 / 12`, away: `d^2 / 16`
/// for 3 bits, 48 bits per `d^2`. Sullivan & Wiegand ("Rate-distortion optimization for video
/// compression", 1998) weigh a coding choice's bits against its squared error at the slope
/// of the quantizer's own rate-distortion curve the same way.
pub(crate) const BITS_PER_EXCESS: f64 = 48.0;

/// [`on_surface_grid`] weighing each point's distance from the surface against what its
/// residuals cost: among the grid points within reach, the one of least
/// `bits(r) + worth * max(0, excess - SURFACE_TOLERANCE2)`, nearer the surface, then nearer the
/// true position, on ties (`bits` in bits, `worth` in bits per grid step squared). Within the
/// tolerance this is the cheapest point, as in [`on_surface_grid`] (which counts a residual's
/// steps where this counts its bits); beyond it a node stays off the surface where reaching
/// it costs more bits than its excess is worth: where skinning predicts a band almost exactly,
/// a residual where there would be none costs a listed node of the sparse coding (about 20
/// bits) in every frame, and the node stays a fraction of a step off the surface.
pub(crate) fn on_surface_grid_rated(
    t: [f64; 3],
    p: [i32; 3],
    shift: u32,
    radius2: f64,
    excess: impl Fn([f64; 3]) -> f64,
    (bits, worth): (impl Fn([i32; 3]) -> f64, f64),
) -> ([i32; 3], [i32; 3]) {
    let unit = (1u64 << shift) as f64;
    let u = [0, 1, 2].map(|a| (t[a] - p[a] as f64) / unit);
    let near = u.map(|x| x.round() as i32);
    // (bits plus the excess's worth, excess, distance): smaller is better.
    let mut best: Option<((f64, f64, f64), [i32; 3])> = None;
    for dx in -1..=1 {
        for dy in -1..=1 {
            for dz in -1..=1 {
                let r = [near[0] + dx, near[1] + dy, near[2] + dz];
                let d2: f64 = (0..3).map(|a| (r[a] as f64 - u[a]).powi(2)).sum();
                if d2 > radius2 && (dx, dy, dz) != (0, 0, 0) {
                    continue;
                }
                let b = bits(r);
                // The excess's worth is never negative: a point whose bits alone exceed the
                // best total cannot win, and its quadric is not evaluated.
                if best.as_ref().is_some_and(|((j, _, _), _)| b > *j) {
                    continue;
                }
                let q = [0, 1, 2].map(|a| p[a] as f64 + r[a] as f64 * unit);
                let e = excess(q) / (unit * unit);
                // NaN (a degenerate quadric) ranks last.
                let e = if e.is_nan() { f64::INFINITY } else { e };
                let key = (b + worth * (e - SURFACE_TOLERANCE2).max(0.0), e, d2);
                if best.as_ref().is_none_or(|(k, _)| key.partial_cmp(k) == Some(std::cmp::Ordering::Less)) {
                    best = Some((key, r));
                }
            }
        }
    }
    let r = best.map_or(near, |(_, r)| r);
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

    /// [`on_surface_grid`] as first written: all 27 candidates' excesses evaluated in order.
    fn on_surface_grid_whole(t: [f64; 3], p: [i32; 3], shift: u32, radius2: f64, excess: impl Fn([f64; 3]) -> f64) -> ([i32; 3], [i32; 3]) {
        let unit = (1u64 << shift) as f64;
        let u = [0, 1, 2].map(|a| (t[a] - p[a] as f64) / unit);
        let near = u.map(|x| x.round() as i32);
        let mut best: Option<(Rank, [i32; 3])> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let r = [near[0] + dx, near[1] + dy, near[2] + dz];
                    let d2: f64 = (0..3).map(|a| (r[a] as f64 - u[a]).powi(2)).sum();
                    if d2 > radius2 && (dx, dy, dz) != (0, 0, 0) {
                        continue;
                    }
                    let q = [0, 1, 2].map(|a| p[a] as f64 + r[a] as f64 * unit);
                    let e = excess(q) / (unit * unit);
                    let e = if e.is_nan() { f64::INFINITY } else { e };
                    let within = e <= SURFACE_TOLERANCE2;
                    let cost: u64 = r.iter().map(|&x| x.unsigned_abs() as u64).sum();
                    let key = if within { (false, cost, e, d2) } else { (true, 0, e, d2) };
                    if best.as_ref().is_none_or(|(k, _)| key.partial_cmp(k) == Some(std::cmp::Ordering::Less)) {
                        best = Some((key, r));
                    }
                }
            }
        }
        let r = best.map_or(near, |(_, r)| r);
        ([0, 1, 2].map(|a| p[a].wrapping_add(r[a].wrapping_shl(shift))), r)
    }

    /// A random case of the surface searches' tests: a truth (on the half-quantum lattice every
    /// fifth case, for ties), a prediction a few quanta off, a grid shift, and a plane through a
    /// point near the truth of a random normal (a tolerance's worth off it now and then, so that
    /// no candidate is within it); NaN excesses every 97th case.
    struct Case {
        t: [f64; 3],
        p: [i32; 3],
        shift: u32,
        n: [f64; 3],
        len: f64,
        off: f64,
        nan: bool,
    }

    impl Case {
        fn new(next: &mut impl FnMut() -> u64, i: usize) -> Case {
            let t = [0; 3].map(|_| (next() % 4000) as f64 / 7.0 - 280.0);
            let t = if i.is_multiple_of(5) { t.map(|x| (x * 2.0).round() / 2.0) } else { t };
            let p = t.map(|x| x.round() as i32 + (next() % 9) as i32 - 4);
            let shift = (next() % 3) as u32;
            let n = [0; 3].map(|_| (next() % 200) as f64 / 100.0 - 1.0);
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-3);
            let off = (next() % 5) as f64 * 0.4;
            Case { t, p, shift, n, len, off, nan: i.is_multiple_of(97) }
        }

        /// The squared distance of `x` from the plane, less the truth's.
        fn excess(&self, x: [f64; 3]) -> f64 {
            let (t, n) = (self.t, self.n);
            let d = ((x[0] - t[0]) * n[0] + (x[1] - t[1]) * n[1] + (x[2] - t[2]) * n[2]) / self.len - self.off;
            if self.nan { f64::NAN } else { d.powi(2) - self.off * self.off }
        }
    }

    /// The pruned search (candidates costing more than a point within the tolerance are not
    /// evaluated) chooses what evaluating every candidate chose: on random truths, predictions,
    /// planes and grids, grid-aligned truths (ties) among them, and NaN excesses.
    #[test]
    fn surface_grid_pruned_is_surface_grid_whole() {
        let mut s = 0x5851_f42d_4c95_7f2du64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let (mut evaluated, mut whole, mut moved) = (0usize, 0usize, 0usize);
        for i in 0..20_000 {
            let case = Case::new(&mut next, i);
            let (t, p, shift) = (case.t, case.p, case.shift);
            let excess = |x: [f64; 3]| case.excess(x);
            for radius2 in [0.25, SLACK2, 1.0, 3.0] {
                let calls = std::cell::Cell::new(0);
                let counted = |x: [f64; 3]| {
                    calls.set(calls.get() + 1);
                    excess(x)
                };
                let got = on_surface_grid(t, p, shift, radius2, counted);
                evaluated += calls.get();
                let all = std::cell::Cell::new(0);
                let want = on_surface_grid_whole(t, p, shift, radius2, |x| {
                    all.set(all.get() + 1);
                    excess(x)
                });
                whole += all.get();
                assert_eq!(got, want, "t {t:?} p {p:?} shift {shift} radius2 {radius2}");
                moved += (got.1 != [0, 1, 2].map(|a| ((t[a] - p[a] as f64) / (1u64 << shift) as f64).round() as i32)) as usize;
            }
        }
        assert!(moved > 1000, "the search hardly ever left the nearest point: {moved}");
        assert!(evaluated * 10 < whole * 9, "pruning evaluated {evaluated} of {whole}");
    }

    /// A flat cluster in the plane z = 0.5 quanta (excess: squared height over it, less the true
    /// position's).
    #[test]
    fn surface_grid_stays_on_the_surface() {
        let plane = |z0: f64| move |x: [f64; 3]| (x[2] - z0).powi(2);
        // True position on the plane, prediction far below it: the cheapest point within reach
        // is one step down, 0.6 off the surface; the surface choice takes the one 0.4 above.
        let t = [10.2, 10.0, 10.6];
        let p = [0, 0, 0];
        let (plain, _) = on_grid(t, p, 0, SLACK2);
        let (kept, r) = on_surface_grid(t, p, 0, SLACK2, plane(10.6));
        assert_eq!(plain, [10, 10, 10], "on_grid takes the cheaper point below");
        assert_eq!(kept, [10, 10, 11]);
        assert_eq!(kept, [0, 1, 2].map(|a| p[a] + r[a]));
        // A tilted plane x + z = 20.8 through t: (10, 10, 11) is 0.14 off it, within the
        // tolerance, and cheaper than anything nearer the plane.
        let tilted = |x: [f64; 3]| (x[0] + x[2] - 20.8).powi(2) / 2.0;
        assert_eq!(on_surface_grid(t, p, 0, SLACK2, tilted).0, [10, 10, 11]);
        // On a coarser band, in units of 4 quanta.
        let t = [40.0, 41.0, 37.0];
        let (q, r) = on_surface_grid(t, [1, 1, 1], 2, SLACK2, plane(37.0));
        assert_eq!(q, [0, 1, 2].map(|a| 1 + 4 * r[a]));
        assert!((q[2] as f64 - 37.0).abs() <= 2.0, "{q:?}");
    }

    /// [`on_surface_grid_rated`] without its pruning: every candidate's excess evaluated.
    fn rated_whole(
        t: [f64; 3],
        p: [i32; 3],
        shift: u32,
        excess: impl Fn([f64; 3]) -> f64,
        bits: impl Fn([i32; 3]) -> f64,
        worth: f64,
    ) -> [i32; 3] {
        let unit = (1u64 << shift) as f64;
        let u = [0, 1, 2].map(|a| (t[a] - p[a] as f64) / unit);
        let near = u.map(|x| x.round() as i32);
        let mut best: Option<((f64, f64, f64), [i32; 3])> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let r = [near[0] + dx, near[1] + dy, near[2] + dz];
                    let d2: f64 = (0..3).map(|a| (r[a] as f64 - u[a]).powi(2)).sum();
                    if d2 > SLACK2 && (dx, dy, dz) != (0, 0, 0) {
                        continue;
                    }
                    let e = excess([0, 1, 2].map(|a| p[a] as f64 + r[a] as f64 * unit)) / (unit * unit);
                    let e = if e.is_nan() { f64::INFINITY } else { e };
                    let key = (bits(r) + worth * (e - SURFACE_TOLERANCE2).max(0.0), e, d2);
                    if best.as_ref().is_none_or(|(k, _)| key.partial_cmp(k) == Some(std::cmp::Ordering::Less)) {
                        best = Some((key, r));
                    }
                }
            }
        }
        best.map_or(near, |(_, r)| r)
    }

    /// The rated search's pruning changes no choice, and where steps are its bits and the
    /// excess is worth more than any bits, it chooses what [`on_surface_grid`] chooses whenever
    /// that is within the tolerance.
    #[test]
    fn rated_surface_grid_is_its_whole_search_and_the_plain_one_at_steps() {
        let mut s = 0x0123_4567_89ab_cdefu64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let (mut same_as_plain, mut moved) = (0, 0);
        for i in 0..20_000 {
            let case = Case::new(&mut next, i);
            let (t, p, shift) = (case.t, case.p, case.shift);
            let excess = |x: [f64; 3]| case.excess(x);
            // Bits of a skewed code: zero nearly free, each axis's steps dearer on x.
            let skew = |r: [i32; 3]| {
                if r == [0; 3] { 0.05 } else { 3.0 + 2.5 * r[0].unsigned_abs() as f64 + (r[1].unsigned_abs() + r[2].unsigned_abs()) as f64 }
            };
            let steps = |r: [i32; 3]| r.iter().map(|x| x.unsigned_abs() as f64).sum::<f64>();
            for worth in [0.0, 4.0, 48.0] {
                let (_, r) = on_surface_grid_rated(t, p, shift, SLACK2, excess, (skew, worth));
                assert_eq!(r, rated_whole(t, p, shift, excess, skew, worth), "t {t:?} p {p:?} shift {shift} worth {worth}");
                moved += (r != [0, 1, 2].map(|a| ((t[a] - p[a] as f64) / (1u64 << shift) as f64).round() as i32)) as u32;
            }
            let (plain, r) = on_surface_grid(t, p, shift, SLACK2, excess);
            let unit = (1u64 << shift) as f64;
            if excess(plain.map(f64::from)) / (unit * unit) <= SURFACE_TOLERANCE2 {
                assert_eq!(on_surface_grid_rated(t, p, shift, SLACK2, excess, (steps, 1e12)).1, r, "t {t:?} p {p:?} shift {shift}");
                same_as_plain += 1;
            }
        }
        assert!(same_as_plain > 5000 && moved > 1000, "{same_as_plain} within the tolerance, {moved} moved");
    }

    /// A node whose prediction is a step below its flat cluster's surface: where every residual
    /// costs about the same bits, it moves onto the surface; where a zero residual is nearly
    /// free and any other costs 20 bits, it stays at the prediction unless the excess is worth
    /// more than those bits.
    #[test]
    fn rated_surface_grid_weighs_the_surface_against_bits() {
        let plane = |x: [f64; 3]| (x[2] - 10.6).powi(2);
        let (t, p) = ([10.2, 10.0, 10.6], [10, 10, 10]);
        let wide = |r: [i32; 3]| 6.0 + 0.1 * r.iter().map(|x| x.unsigned_abs() as f64).sum::<f64>();
        let sparse = |r: [i32; 3]| if r == [0; 3] { 0.1 } else { 20.0 };
        assert_eq!(on_surface_grid(t, p, 0, SLACK2, plane).0, [10, 10, 11], "the surface choice");
        assert_eq!(on_surface_grid_rated(t, p, 0, SLACK2, plane, (wide, BITS_PER_EXCESS)).0, [10, 10, 11]);
        // 0.6 below: 0.36 - 0.09 steps squared over the tolerance, 13 bits at 48 per step
        // squared, 2.6 at a fifth of the nodes listed.
        assert_eq!(on_surface_grid_rated(t, p, 0, SLACK2, plane, (sparse, BITS_PER_EXCESS)).0, p);
        assert_eq!(on_surface_grid_rated(t, p, 0, SLACK2, plane, (sparse, 0.2 * BITS_PER_EXCESS)).0, p);
        assert_eq!(on_surface_grid_rated(t, p, 0, SLACK2, plane, (sparse, 100.0)).0, [10, 10, 11], "27 bits of excess");
    }

    #[test]
    fn surface_grid_without_a_surface_is_the_cheapest_point_within_the_tolerance() {
        // No excess anywhere: every point is on the "surface", and the choice is on_grid's
        // cost order (ties may break differently, by distance after cost in both).
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        for _ in 0..5000 {
            let t = [0; 3].map(|_| (next() % 4000) as f64 / 7.0 - 280.0);
            let p = t.map(|x| x.round() as i32 + (next() % 9) as i32 - 4);
            let shift = (next() % 3) as u32;
            let (a, ra) = on_grid(t, p, shift, SLACK2);
            let (b, rb) = on_surface_grid(t, p, shift, SLACK2, |_| 0.0);
            let cost = |r: [i32; 3]| r.iter().map(|x| x.unsigned_abs()).sum::<u32>();
            assert_eq!(cost(ra), cost(rb), "t {t:?} p {p:?}: {a:?} vs {b:?}");
        }
        // A NaN excess (degenerate quadric) still stores a point: the nearest.
        let (q, _) = on_surface_grid([3.4, 5.6, 7.5], [0; 3], 0, SLACK2, |_| f64::NAN);
        assert_eq!(q[0], 3);
    }
}
