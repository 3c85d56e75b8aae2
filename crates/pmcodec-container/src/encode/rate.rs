//! About what a coarse node's residuals will cost in its band's Positions chunk, learnt from the
//! band's residuals as stored in earlier frames: what the surface grid weighs against a
//! point's distance from its cluster's surface ([`crate::grid::on_surface_grid_rated`]).
//!
//! Why: the bits a residual costs depend on the band's distribution. Where skinning predicts a
//! band almost exactly (a glTF's own skin), nearly every node's residual is zero and a node
//! moved off its cheapest grid point to reach the surface costs a whole listed node of the
//! sparse coding (about 20 bits) in every frame; where the prediction leaves residuals of tens
//! of steps (a coarse band without skinning), a step more or less costs a fraction of a bit.
//! A residual's length alone (an Elias gamma code) cannot tell the two apart.

use crate::payload::zigzag;

/// Zigzag residuals below this have a bucket each; larger ones one per bit length.
const EXACT: u32 = 16;
/// Buckets: `EXACT` exact values, then bit lengths 5 to 32.
const BUCKETS: usize = EXACT as usize + 28;
/// Krichevsky & Trofimov's estimator ("The performance of universal encoding", 1981): half a
/// count added to every outcome, so an unseen one costs a finite number of bits.
const PRIOR: f64 = 0.5;

/// A residual component's bucket and the raw bits that tell it apart within its bucket.
fn bucket(r: i32) -> (usize, u32) {
    let z = zigzag(r);
    if z < EXACT {
        (z as usize, 0)
    } else {
        let len = 32 - z.leading_zeros();
        (EXACT as usize + (len - 5) as usize, len - 1)
    }
}

/// Counts of a band's stored residuals: how many nodes were all zero, and per axis the
/// buckets of the other nodes' components. The sparse coding lists only the nonzero nodes
/// (rANS codes every component, for about the same entropy where few nodes are zero).
#[derive(Clone, Debug)]
pub(super) struct RateModel {
    nodes: f64,
    zero: f64,
    axes: [[f64; BUCKETS]; 3],
}

impl Default for RateModel {
    fn default() -> Self {
        RateModel { nodes: 0.0, zero: 0.0, axes: [[0.0; BUCKETS]; 3] }
    }
}

impl RateModel {
    /// Counts a band's stored residuals, the earlier bands' counted at half their weight (a
    /// band's distribution drifts with the motion).
    pub(super) fn add(&mut self, residuals: &[[i32; 3]]) {
        self.nodes *= 0.5;
        self.zero *= 0.5;
        for c in self.axes.iter_mut().flatten() {
            *c *= 0.5;
        }
        for r in residuals {
            self.nodes += 1.0;
            if *r == [0; 3] {
                self.zero += 1.0;
                continue;
            }
            for (a, &x) in r.iter().enumerate() {
                self.axes[a][bucket(x).0] += 1.0;
            }
        }
    }

    /// Bit costs from these counts, or None before any band was counted.
    pub(super) fn rates(&self) -> Option<Rates> {
        if self.nodes <= 0.0 {
            return None;
        }
        let listed = self.nodes - self.zero;
        let p0 = (self.zero + PRIOR) / (self.nodes + 2.0 * PRIOR);
        let axes = self.axes.map(|counts| counts.map(|c| -((c + PRIOR) / (listed + PRIOR * BUCKETS as f64)).log2()));
        Some(Rates { zero: -p0.log2(), listed: -(1.0 - p0).log2(), axes, listed_share: listed / self.nodes })
    }
}

/// Bits a node's residuals cost under a [`RateModel`]'s counts.
#[derive(Clone, Debug)]
pub(crate) struct Rates {
    zero: f64,
    listed: f64,
    axes: [[f64; BUCKETS]; 3],
    /// The share of nodes whose residuals were not all zero.
    listed_share: f64,
}

impl Rates {
    /// Bits a grid step squared of excess is worth in this band
    /// ([`crate::grid::on_surface_grid_rated`]): [`crate::grid::BITS_PER_EXCESS`] per node
    /// whose residuals are not all zero, the nodes a finer grid would cost bits for. Where
    /// skinning predicts most nodes exactly, a finer grid costs little and the surface is worth
    /// as little (a generated skinned character at its 25% level: the surface lowered the
    /// error 3% for 12% more bytes, a finer grid 5% for 5%).
    pub(crate) fn excess_worth(&self) -> f64 {
        crate::grid::BITS_PER_EXCESS * self.listed_share
    }

    /// About the bits of residuals `r`.
    pub(crate) fn bits(&self, r: [i32; 3]) -> f64 {
        if r == [0; 3] {
            return self.zero;
        }
        let mut bits = self.listed;
        for (a, &x) in r.iter().enumerate() {
            let (b, raw) = bucket(x);
            bits += self.axes[a][b] + raw as f64;
        }
        bits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_cover_every_residual() {
        assert_eq!(bucket(0), (0, 0));
        assert_eq!(bucket(-1), (1, 0));
        assert_eq!(bucket(7), (14, 0));
        assert_eq!(bucket(8), (EXACT as usize, 4), "zigzag 16: 5 bits long");
        assert_eq!(bucket(i32::MIN).0, BUCKETS - 1);
        assert_eq!(bucket(i32::MAX).0, BUCKETS - 1);
    }

    /// A band of zeros but for a few nodes makes a nonzero node expensive and a zero one nearly
    /// free; a band of wide residuals makes a step more or less nearly free.
    #[test]
    fn costs_follow_the_band_s_distribution() {
        assert!(RateModel::default().rates().is_none());
        let mut sparse = RateModel::default();
        let band: Vec<[i32; 3]> = (0..1000).map(|i| if i % 50 == 0 { [1, 0, -1] } else { [0; 3] }).collect();
        sparse.add(&band);
        let r = sparse.rates().expect("counted");
        assert!(r.bits([0; 3]) < 0.1, "{}", r.bits([0; 3]));
        assert!(r.bits([1, 0, 0]) > 6.0, "{}", r.bits([1, 0, 0]));
        let mut wide = RateModel::default();
        let band: Vec<[i32; 3]> = (0..1000).map(|i: i32| [i % 23 - 11, (i * 7) % 19 - 9, (i * 13) % 21 - 10]).collect();
        wide.add(&band);
        let r = wide.rates().expect("counted");
        let step = (r.bits([4, -3, 2]) - r.bits([5, -3, 2])).abs();
        assert!(step < 0.5, "{step}");
        // Halved history: a band of zeros after the wide one makes zeros cheaper than before.
        let before = r.bits([0; 3]);
        wide.add(&[[0; 3]; 1000]);
        assert!(wide.rates().expect("counted").bits([0; 3]) < before);
    }
}
