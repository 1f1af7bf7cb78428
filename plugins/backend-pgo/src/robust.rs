//! Robust kernels for loop-closure edges: Huber, Cauchy and truncated least squares (TLS), applied to the
//! squared Mahalanobis norm `s = rᵀ Ω r` by iteratively reweighted least squares (the kernels of
//! g2o and GTSAM; see Zhang, "Parameter estimation techniques: a tutorial with application to conic
//! fitting", 1997, for the weights). The cost of an edge is `½ ρ(s)`, with `ρ(s) = s` for plain least
//! squares, so costs stay in GTSAM's convention when no kernel is active.

use serde::{Deserialize, Serialize};

/// The loss applied to the loop-closure edges.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RobustLoss {
    /// Plain least squares.
    #[default]
    None,
    /// Quadratic up to `width`, linear beyond.
    Huber,
    /// `width² ln(1 + s / width²)`.
    Cauchy,
    /// Truncated least squares: quadratic up to `width`, constant beyond (non-convex; best used through
    /// graduated non-convexity, see [`crate::gnc`]).
    Tls,
}

impl RobustLoss {
    /// Parses the names used on the command line and in configuration files.
    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "none" | "l2" => Some(Self::None),
            "huber" => Some(Self::Huber),
            "cauchy" => Some(Self::Cauchy),
            "tls" => Some(Self::Tls),
            _ => None,
        }
    }

    /// The name used on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Huber => "huber",
            Self::Cauchy => "cauchy",
            Self::Tls => "tls",
        }
    }
}

/// A loss with its width on the Mahalanobis norm `√s` (dimensionless: in standard deviations).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    pub loss: RobustLoss,
    pub width: f64,
}

impl Default for Kernel {
    fn default() -> Self {
        Self {
            loss: RobustLoss::None,
            width: 1.0,
        }
    }
}

impl Kernel {
    /// A kernel, refusing widths that are not finite and positive.
    pub fn new(loss: RobustLoss, width: f64) -> Result<Self, String> {
        if loss != RobustLoss::None && !(width.is_finite() && width > 0.0) {
            return Err(format!(
                "the {} kernel width must be finite and positive, got {width}",
                loss.name()
            ));
        }
        Ok(Self { loss, width })
    }

    /// `ρ(s)` for a squared Mahalanobis norm `s`.
    pub fn rho(&self, s: f64) -> f64 {
        let k2 = self.width * self.width;
        match self.loss {
            RobustLoss::None => s,
            RobustLoss::Huber => {
                if s <= k2 {
                    s
                } else {
                    2.0 * self.width * s.sqrt() - k2
                }
            }
            RobustLoss::Cauchy => k2 * (s / k2).ln_1p(),
            RobustLoss::Tls => s.min(k2),
        }
    }

    /// The IRLS weight `ρ'(s)` for a squared Mahalanobis norm `s`.
    pub fn weight(&self, s: f64) -> f64 {
        let k2 = self.width * self.width;
        match self.loss {
            RobustLoss::None => 1.0,
            RobustLoss::Huber => {
                if s <= k2 {
                    1.0
                } else {
                    self.width / s.sqrt()
                }
            }
            RobustLoss::Cauchy => 1.0 / (1.0 + s / k2),
            RobustLoss::Tls => {
                if s <= k2 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// `ln Γ(a)` for `a > 0` (Lanczos approximation, g = 7, 9 terms; relative error below 1e-13).
fn ln_gamma(a: f64) -> f64 {
    const COEFFICIENTS: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if a < 0.5 {
        // Reflection formula.
        return (std::f64::consts::PI / (std::f64::consts::PI * a).sin()).ln() - ln_gamma(1.0 - a);
    }
    let a = a - 1.0;
    let t = a + 7.5;
    let sum = COEFFICIENTS[1..]
        .iter()
        .enumerate()
        .fold(COEFFICIENTS[0], |s, (k, c)| s + c / (a + k as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (a + 0.5) * t.ln() - t + sum.ln()
}

/// The regularised lower incomplete gamma function `P(a, x)`.
fn lower_gamma_regularized(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let log_prefix = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        // Series.
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (sum.ln() + log_prefix).exp().min(1.0)
    } else {
        // Continued fraction for Q(a, x) (modified Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (1.0 - (log_prefix.exp() * h)).max(0.0)
    }
}

/// The `probability` quantile of the χ² distribution with `dof` degrees of freedom (bisection on the
/// distribution function); e.g. 16.81 for 6 degrees of freedom at 0.99.
pub fn chi2_quantile(dof: usize, probability: f64) -> f64 {
    let probability = probability.clamp(1e-12, 1.0 - 1e-12);
    let a = dof.max(1) as f64 / 2.0;
    let (mut low, mut high) = (0.0f64, 1.0f64);
    while lower_gamma_regularized(a, high / 2.0) < probability && high < 1e6 {
        high *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (low + high);
        if lower_gamma_regularized(a, mid / 2.0) < probability {
            low = mid;
        } else {
            high = mid;
        }
    }
    0.5 * (low + high)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_the_derivatives_of_the_losses() {
        for loss in [
            RobustLoss::None,
            RobustLoss::Huber,
            RobustLoss::Cauchy,
            RobustLoss::Tls,
        ] {
            let kernel = Kernel::new(loss, 1.5).unwrap();
            for s in [0.1, 1.0, 2.0, 5.0, 40.0] {
                if loss == RobustLoss::Tls && (s - 2.25f64).abs() < 0.5 {
                    continue;
                }
                let h = 1e-6;
                let numeric = (kernel.rho(s + h) - kernel.rho(s - h)) / (2.0 * h);
                assert!((numeric - kernel.weight(s)).abs() < 1e-6, "{loss:?} at {s}");
            }
        }
    }

    #[test]
    fn chi2_quantiles_match_tables() {
        // Values from standard χ² tables.
        for (dof, p, expected) in [
            (6, 0.01, 0.872),
            (6, 0.5, 5.348),
            (6, 0.99, 16.812),
            (3, 0.95, 7.815),
            (1, 0.95, 3.841),
        ] {
            let q = chi2_quantile(dof, p);
            assert!((q - expected).abs() < 2e-3, "dof {dof} p {p}: {q} vs {expected}");
        }
    }

    #[test]
    fn robust_losses_grow_slower_than_least_squares() {
        for loss in [RobustLoss::Huber, RobustLoss::Cauchy, RobustLoss::Tls] {
            let kernel = Kernel::new(loss, 1.0).unwrap();
            assert!(kernel.rho(100.0) < 100.0 / 4.0, "{loss:?}");
            assert!(
                (kernel.rho(0.25) - 0.25).abs() < 0.05,
                "{loss:?} is quadratic near zero"
            );
        }
        assert!(Kernel::new(RobustLoss::Huber, f64::NAN).is_err());
    }
}
