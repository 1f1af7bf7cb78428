//! Deterministic, seedable random numbers without global state.
//!
//! The generator is SplitMix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number generators",
//! OOPSLA 2014): tiny, fast and good enough for simulation noise. Streams are derived from keys with
//! [`mix`], so every ray of every scan of every robot draws from its own stream and results do not depend
//! on thread scheduling. Gaussian samples use the Box–Muller transform.

/// One round of the SplitMix64 finaliser: a strong 64-bit bit mixer.
pub const fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Combines a key with a further component into a new, well-mixed key.
pub const fn combine(key: u64, part: u64) -> u64 {
    mix(key ^ mix(part.wrapping_add(0x9e37_79b9_7f4a_7c15)))
}

/// A SplitMix64 stream.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A stream seeded by `seed` (any value, including 0, is fine).
    pub const fn new(seed: u64) -> Self {
        Self {
            state: mix(seed ^ 0x5851_f42d_4c95_7f2d),
        }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix(self.state)
    }

    /// A uniform sample in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform sample in [low, high).
    pub fn range(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.uniform()
    }

    /// A uniform integer in [0, n); `n` must be positive.
    pub fn below(&mut self, n: usize) -> usize {
        ((self.next_u64() >> 32) as usize * n) >> 32
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.uniform() < p
    }

    /// A standard normal sample (Box–Muller).
    pub fn gaussian(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// A sample of a power-law (Pareto-like) size distribution between `low` and `high` with exponent
    /// `alpha` > 1: small sizes are common, large ones rare, as for rocks and craters on planetary surfaces.
    pub fn power_law(&mut self, low: f64, high: f64, alpha: f64) -> f64 {
        let a = 1.0 - alpha;
        let u = self.uniform();
        (low.powf(a) + u * (high.powf(a) - low.powf(a))).powf(1.0 / a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_deterministic_and_distinct() {
        let a: Vec<u64> = (0..4)
            .map({
                let mut r = Rng::new(7);
                move |_| r.next_u64()
            })
            .collect();
        let mut r = Rng::new(7);
        assert_eq!(a, (0..4).map(|_| r.next_u64()).collect::<Vec<_>>());
        assert_ne!(Rng::new(7).next_u64(), Rng::new(8).next_u64());
    }

    #[test]
    fn gaussian_has_unit_variance() {
        let mut r = Rng::new(1);
        let n = 20_000;
        let samples: Vec<f64> = (0..n).map(|_| r.gaussian()).collect();
        let mean = samples.iter().sum::<f64>() / n as f64;
        let var = samples.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.03 && (var - 1.0).abs() < 0.05, "{mean} {var}");
    }

    #[test]
    fn power_law_stays_in_range() {
        let mut r = Rng::new(3);
        for _ in 0..1000 {
            let s = r.power_law(0.2, 3.0, 2.5);
            assert!((0.2..=3.0).contains(&s));
        }
    }
}
