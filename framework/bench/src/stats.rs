//! Timing statistics of repeated measurements.

use serde::Serialize;

/// Summary of a set of durations in milliseconds.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timing {
    pub samples: usize,
    pub median_ms: f64,
    pub p90_ms: f64,
    pub mean_ms: f64,
    pub min_ms: f64,
    pub max_ms: f64,
}

impl Timing {
    /// Statistics of `durations_ms` (all zero when empty).
    pub fn from_ms(durations_ms: &[f64]) -> Self {
        if durations_ms.is_empty() {
            return Self::default();
        }
        let mut sorted = durations_ms.to_vec();
        sorted.sort_by(f64::total_cmp);
        let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
        Self {
            samples: sorted.len(),
            median_ms: at(0.5),
            p90_ms: at(0.9),
            mean_ms: sorted.iter().sum::<f64>() / sorted.len() as f64,
            min_ms: sorted[0],
            max_ms: sorted[sorted.len() - 1],
        }
    }
}

/// Median of `values` (the upper one of an even count; NaN when empty).
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Runs `work` and returns its result and the elapsed milliseconds.
pub fn time_ms<T>(work: impl FnOnce() -> T) -> (T, f64) {
    let started = std::time::Instant::now();
    let value = work();
    (value, started.elapsed().as_secs_f64() * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_known_set() {
        let timing = Timing::from_ms(&[5.0, 1.0, 3.0, 2.0, 4.0]);
        assert_eq!(timing.median_ms, 3.0);
        assert_eq!(timing.min_ms, 1.0);
        assert_eq!(timing.max_ms, 5.0);
        assert_eq!(timing.mean_ms, 3.0);
        assert_eq!(Timing::from_ms(&[]).samples, 0);
    }
}
