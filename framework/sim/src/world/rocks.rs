//! Rock size–frequency distributions after Golombek and Rapp, "Size-frequency distributions of rocks on
//! Mars and Earth analog sites" (JGR 1997): the cumulative fractional area covered by rocks of diameter
//! D or larger is `F_k(D) = k · exp(−q(k) · D)` with `q(k) = 1.79 + 0.152 / k`, where `k` is the total
//! rock abundance (about 0.05–0.10 at the Viking and Pathfinder sites, less on lunar maria). A rock of
//! diameter D covers `π D² / 4`, so the number of rocks per square metre per metre of diameter is
//! `n(D) = −F'(D) / (π D² / 4) = 4 k q exp(−q D) / (π D²)`.

use crate::rng::Rng;

/// Steps of the tabulated cumulative count between the smallest and largest diameter.
const TABLE_STEPS: usize = 2048;

/// A Golombek–Rapp rock population between two diameters, sampled by inverting its tabulated
/// cumulative count.
#[derive(Clone, Debug)]
pub struct RockPopulation {
    min_diameter_m: f64,
    step_m: f64,
    /// Rocks per square metre with a diameter in [min, min + i · step].
    cumulative_per_m2: Vec<f64>,
}

impl RockPopulation {
    /// The population of abundance `k` (0 < k < 1) with diameters in [`min_diameter_m`, `max_diameter_m`].
    pub fn new(k: f64, min_diameter_m: f64, max_diameter_m: f64) -> Self {
        let q = 1.79 + 0.152 / k;
        let density = |d: f64| 4.0 * k * q * (-q * d).exp() / (std::f64::consts::PI * d * d);
        let step_m = (max_diameter_m - min_diameter_m) / TABLE_STEPS as f64;
        let mut cumulative_per_m2 = Vec::with_capacity(TABLE_STEPS + 1);
        let mut total = 0.0;
        cumulative_per_m2.push(0.0);
        for i in 0..TABLE_STEPS {
            let (a, b) = (
                min_diameter_m + i as f64 * step_m,
                min_diameter_m + (i + 1) as f64 * step_m,
            );
            total += 0.5 * (density(a) + density(b)) * step_m;
            cumulative_per_m2.push(total);
        }
        Self {
            min_diameter_m,
            step_m,
            cumulative_per_m2,
        }
    }

    /// Rocks per square metre in the diameter range.
    pub fn per_m2(&self) -> f64 {
        self.cumulative_per_m2.last().copied().unwrap_or(0.0)
    }

    /// A diameter drawn from the population.
    pub fn sample_diameter_m(&self, rng: &mut Rng) -> f64 {
        let wanted = rng.uniform() * self.per_m2();
        let upper = self.cumulative_per_m2.partition_point(|&c| c < wanted).max(1);
        let (below, above) = (self.cumulative_per_m2[upper - 1], self.cumulative_per_m2[upper]);
        let fraction = if above > below {
            (wanted - below) / (above - below)
        } else {
            0.0
        };
        self.min_diameter_m + (upper as f64 - 1.0 + fraction) * self.step_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_follow_the_cumulative_area_law() {
        // The area of rocks between 0.5 and 1.0 m per square metre must equal F(0.5) - F(1.0).
        let k = 0.05;
        let population = RockPopulation::new(k, 0.5, 1.0);
        let mut rng = Rng::new(3);
        let samples = 200_000;
        let mean_area_m2: f64 = (0..samples)
            .map(|_| {
                let d = population.sample_diameter_m(&mut rng);
                std::f64::consts::PI * d * d / 4.0
            })
            .sum::<f64>()
            / f64::from(samples);
        let q = 1.79 + 0.152 / k;
        let expected = k * ((-q * 0.5f64).exp() - (-q * 1.0f64).exp());
        let measured = mean_area_m2 * population.per_m2();
        assert!(
            (measured - expected).abs() < 0.01 * expected,
            "area fraction {measured} vs {expected}"
        );
    }

    #[test]
    fn diameters_stay_in_range_and_small_ones_dominate() {
        let population = RockPopulation::new(0.05, 0.5, 3.0);
        let mut rng = Rng::new(9);
        let diameters: Vec<f64> = (0..10_000)
            .map(|_| population.sample_diameter_m(&mut rng))
            .collect();
        assert!(diameters.iter().all(|d| (0.5..=3.0).contains(d)));
        let small = diameters.iter().filter(|d| **d < 1.0).count();
        assert!(small > 9_000, "{small} of 10000 below 1 m");
    }
}
