//! Summary statistics of an error sequence, with evo's definitions (evo `PE.get_statistic`):
//! RMSE = √(mean of squares), mean, median (mean of the two middle values for an even count), population
//! standard deviation (divide by n, like `numpy.std`), min, max and the sum of squares (SSE).

use serde::{Deserialize, Serialize};

use crate::error::EvalError;

/// Statistics of a sequence of non-negative errors (metres or degrees, as the field using it says).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Number of errors summarised.
    pub count: usize,
    pub rmse: f64,
    pub mean: f64,
    pub median: f64,
    /// Population standard deviation (divides by `count`).
    pub std: f64,
    pub min: f64,
    pub max: f64,
    /// Sum of squared errors.
    pub sse: f64,
}

impl ErrorStats {
    /// Summarises `errors`; an empty or non-finite sequence is an error.
    pub fn from_errors(what: &'static str, errors: &[f64]) -> Result<Self, EvalError> {
        if errors.is_empty() {
            return Err(EvalError::TooFew {
                what,
                needed: 1,
                got: 0,
            });
        }
        if let Some(index) = errors.iter().position(|e| !e.is_finite()) {
            return Err(EvalError::NonFinite { what, index });
        }
        let n = errors.len() as f64;
        let sse: f64 = errors.iter().map(|e| e * e).sum();
        let mean = errors.iter().sum::<f64>() / n;
        let variance = errors.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / n;
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let middle = sorted.len() / 2;
        let median = if sorted.len() % 2 == 1 {
            sorted[middle]
        } else {
            0.5 * (sorted[middle - 1] + sorted[middle])
        };
        Ok(Self {
            count: errors.len(),
            rmse: (sse / n).sqrt(),
            mean,
            median,
            std: variance.sqrt(),
            min: sorted[0],
            max: sorted[sorted.len() - 1],
            sse,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_hand_computation() {
        // errors 1, 2, 2, 5: sse = 1+4+4+25 = 34, rmse = √8.5, mean = 2.5, median = 2,
        // variance = (2.25+0.25+0.25+6.25)/4 = 2.25 → std = 1.5.
        let s = ErrorStats::from_errors("e", &[2.0, 5.0, 1.0, 2.0]).unwrap();
        assert_eq!(s.count, 4);
        assert!((s.rmse - 8.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(
            (s.mean, s.median, s.std, s.min, s.max, s.sse),
            (2.5, 2.0, 1.5, 1.0, 5.0, 34.0)
        );
        let odd = ErrorStats::from_errors("e", &[3.0, 1.0, 2.0]).unwrap();
        assert_eq!(odd.median, 2.0);
        assert!(matches!(
            ErrorStats::from_errors("e", &[]),
            Err(EvalError::TooFew { .. })
        ));
        assert!(matches!(
            ErrorStats::from_errors("e", &[1.0, f64::NAN]),
            Err(EvalError::NonFinite { index: 1, .. })
        ));
    }
}
