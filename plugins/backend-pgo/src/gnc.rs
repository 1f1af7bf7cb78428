//! Graduated non-convexity with the truncated-least-squares loss (GNC-TLS; Yang, Antonante, Tzoumas &
//! Carlone, "Graduated non-convexity for robust spatial perception", RA-L 2020), applied to the
//! loop-closure factors of a pose graph.
//!
//! The TLS loss `min(s, c̄²)` on the squared Mahalanobis norm `s` is approached through the surrogates
//! of a control parameter `μ`, starting almost convex (`μ = c̄² / (2 s_max − c̄²)`) and growing by a
//! factor each outer step until the weights are binary. Each outer step solves the weighted least-
//! squares problem by Levenberg-Marquardt (warm-started) and then updates each weight in closed form:
//! `w = 1` when `s ≤ μ/(μ+1) c̄²`, `w = 0` when `s ≥ (μ+1)/μ c̄²`, and `w = c̄ √(μ(μ+1)/s) − μ` between.
//! Odometry factors keep weight 1.

use crate::error::PgoError;
use crate::group::PoseGroup;
use crate::lm::{FixedWeights, LmOutcome, LmSettings, StopReason, SystemCache, optimize};
use crate::problem::Problem;

/// Parameters of GNC-TLS.
#[derive(Clone, Copy, Debug)]
pub struct GncSettings {
    /// Squared Mahalanobis norm `c̄²` beyond which a loop closure is an outlier.
    pub threshold_squared: f64,
    /// Factor by which `μ` grows each outer step (1.4 in the reference implementation).
    pub mu_factor: f64,
    /// Most outer steps.
    pub max_outer_iterations: usize,
    /// Levenberg-Marquardt settings of each inner solve.
    pub inner: LmSettings,
}

/// What a GNC run did.
#[derive(Clone, Debug)]
pub struct GncOutcome {
    /// The final inner solve (its costs are the weighted least-squares costs).
    pub last: LmOutcome,
    /// Cost of the starting poses in plain least squares.
    pub initial_cost: f64,
    pub outer_iterations: usize,
    /// Inner Levenberg-Marquardt steps summed over every solve.
    pub total_iterations: usize,
    pub factorizations: usize,
    /// Final weight of every factor (1 for odometry).
    pub weights: Vec<f64>,
}

/// The GNC-TLS weight of a factor with squared norm `s` at control parameter `mu`.
fn tls_weight(s: f64, threshold_squared: f64, mu: f64) -> f64 {
    if s <= mu / (mu + 1.0) * threshold_squared {
        1.0
    } else if s >= (mu + 1.0) / mu * threshold_squared {
        0.0
    } else {
        (threshold_squared.sqrt() * (mu * (mu + 1.0) / s).sqrt() - mu).clamp(0.0, 1.0)
    }
}

/// Runs GNC-TLS on `problem`, moving its free poses; robust factors end with weight 0 (outlier) or 1.
pub fn gnc_tls<G: PoseGroup<D>, const D: usize>(
    problem: &mut Problem<G, D>,
    settings: &GncSettings,
    cache: &mut SystemCache<D>,
) -> Result<GncOutcome, PgoError> {
    if !(settings.threshold_squared.is_finite()
        && settings.threshold_squared > 0.0
        && settings.mu_factor > 1.0)
    {
        return Err(PgoError::Option(
            "GNC needs a positive threshold and a mu factor above 1".into(),
        ));
    }
    let mut weights = vec![1.0; problem.factors.len()];
    // Start from the least-squares solution with every factor.
    let mut last = optimize(problem, &FixedWeights(&weights), &settings.inner, cache)?;
    let initial_cost = last.initial_cost;
    let (mut total_iterations, mut factorizations) = (last.iterations, last.factorizations);
    let robust: Vec<bool> = problem.factors.iter().map(|f| f.robust).collect();
    let norms = problem.squared_norms();
    let s_max = norms
        .iter()
        .zip(&robust)
        .filter(|(_, r)| **r)
        .map(|(s, _)| *s)
        .fold(0.0f64, f64::max);
    let c2 = settings.threshold_squared;
    let mut outer = 0;
    if 2.0 * s_max > c2 {
        let mut mu = c2 / (2.0 * s_max - c2);
        while outer < settings.max_outer_iterations {
            outer += 1;
            let norms = problem.squared_norms();
            let mut changed = 0.0;
            for k in 0..weights.len() {
                if robust[k] {
                    let w = tls_weight(norms[k], c2, mu);
                    changed += (w - weights[k]).abs();
                    weights[k] = w;
                }
            }
            last = optimize(problem, &FixedWeights(&weights), &settings.inner, cache)?;
            total_iterations += last.iterations;
            factorizations += last.factorizations;
            let binary = weights.iter().all(|w| *w == 0.0 || *w == 1.0);
            if binary && changed == 0.0 && outer > 1 {
                break;
            }
            mu *= settings.mu_factor;
        }
        // Final classification and a polish with binary weights.
        let norms = problem.squared_norms();
        for k in 0..weights.len() {
            if robust[k] {
                weights[k] = if norms[k] <= c2 && weights[k] > 0.5 {
                    1.0
                } else {
                    0.0
                };
            }
        }
        let mut polish = settings.inner;
        polish.max_iterations = polish.max_iterations.max(50);
        last = optimize(problem, &FixedWeights(&weights), &polish, cache)?;
        total_iterations += last.iterations;
        factorizations += last.factorizations;
    }
    if last.stop == StopReason::NothingToDo {
        last.stop = StopReason::Converged;
    }
    Ok(GncOutcome {
        last,
        initial_cost,
        outer_iterations: outer,
        total_iterations,
        factorizations,
        weights,
    })
}

#[cfg(test)]
mod tests {
    use super::tls_weight;

    #[test]
    fn weights_go_from_convex_to_binary() {
        let c2 = 9.0;
        // Small mu: the surrogate is nearly quadratic, a large residual keeps some weight.
        assert!(tls_weight(12.0, c2, 0.5) > 0.0);
        // Large mu: the weights are binary around the threshold.
        assert_eq!(tls_weight(8.0, c2, 1e6), 1.0);
        assert_eq!(tls_weight(10.0, c2, 1e6), 0.0);
        let mid = tls_weight(9.0, c2, 2.0);
        assert!(mid > 0.0 && mid < 1.0);
    }
}
