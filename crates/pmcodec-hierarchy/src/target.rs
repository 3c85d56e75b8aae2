//! What a cut is chosen by, with its units explicit: one type for the split-order prefixes a
//! decoder shows ([`crate::split_order::SplitOrder::prefix`]), the greedy cuts and measured
//! approximations of `pmcodec-eval` (`select_cut`, `approximate`), the server's LOD requests
//! and the CLI.

/// A distance, in model units or relative to the model's bounding-box diagonal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distance {
    /// In model units.
    Absolute(f64),
    /// A fraction of the bounding-box diagonal (what the CLI's `--max-error` and the HTTP API's
    /// `max_error` take, so that one number suits models of any size).
    DiagonalFraction(f64),
}

impl Distance {
    /// This distance in model units, for a model whose bounding-box diagonal is `diagonal`.
    pub fn in_model_units(self, diagonal: f64) -> f64 {
        match self {
            Distance::Absolute(d) => d,
            Distance::DiagonalFraction(f) => f * diagonal,
        }
    }

    /// Whether the value is a distance at all: finite and not negative.
    pub fn is_valid(self) -> bool {
        let (Distance::Absolute(d) | Distance::DiagonalFraction(d)) = self;
        d.is_finite() && d >= 0.0
    }
}

/// What a cut should satisfy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CutTarget {
    /// The largest cut showing at most this many triangles, refined greedily by node error.
    Triangles(u32),
    /// The largest cut with at most this many vertices (cut nodes), refined greedily.
    Vertices(u32),
    /// Every node of this level (0 = the input mesh).
    Level(usize),
    /// Refine every node whose error (its error distance, see
    /// [`crate::NodeState::error_distance`], or its split priority in a split order) exceeds
    /// this distance.
    MaxError(Distance),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_convert_by_their_unit() {
        assert_eq!(Distance::Absolute(0.5).in_model_units(10.0), 0.5);
        assert_eq!(Distance::DiagonalFraction(0.01).in_model_units(200.0), 2.0);
        assert!(Distance::DiagonalFraction(0.0).is_valid());
        assert!(!Distance::Absolute(-1.0).is_valid());
        assert!(!Distance::DiagonalFraction(f64::NAN).is_valid());
        assert!(!Distance::Absolute(f64::INFINITY).is_valid());
    }
}
