//! The deterministic random numbers every sampled figure is reproducible from.

/// The workspace's one deterministic generator: splitmix64 (Steele, Lea & Flood, *Fast
/// Splittable Pseudorandom Number Generators*, 2014), one add and two multiply-xorshift rounds
/// per output. Statistically far better than its uses need, tiny, and fully reproducible from
/// the seed on every platform, which is what matters here: the same meshes and seed must give
/// the same reported figures.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator whose first output is the splitmix64 mix of `seed` plus the golden gamma
    /// (so `SplitMix64::new(x).next_u64()` is also a good 64-bit hash of `x`).
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1) with the full 53 bits of an `f64` mantissa.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_is_in_range_and_deterministic() {
        let mut a = SplitMix64::new(7);
        let mut b = SplitMix64::new(7);
        for _ in 0..10_000 {
            let x = a.unit();
            assert!((0.0..1.0).contains(&x));
            assert_eq!(x.to_bits(), b.unit().to_bits());
        }
    }
}
