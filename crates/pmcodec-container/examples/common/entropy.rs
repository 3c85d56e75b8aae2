//! What the development probes measure residuals with.
use std::collections::HashMap;

/// Bits of a static per-axis code for these residuals (one table per axis, as a positions
/// chunk's rANS has; the tables' own size not counted).
pub fn entropy(res: &[[i32; 3]]) -> f64 {
    let mut bits = 0.0;
    for a in 0..3 {
        let mut h: HashMap<i32, usize> = HashMap::new();
        for r in res {
            *h.entry(r[a]).or_default() += 1;
        }
        let n = res.len() as f64;
        bits += h.values().map(|&k| -(k as f64) * (k as f64 / n).log2()).sum::<f64>();
    }
    bits
}
