//! The few SE(3) operations pairwise consistency needs: the logarithm with translation first
//! (`ρ = J_l(φ)⁻¹ t`), the adjoint, and covariance transport between the left and right perturbation
//! conventions (Barfoot, "State Estimation for Robotics", 2017, §7.1), plus the χ² quantile that turns a
//! probability into a Mahalanobis threshold.

use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector3, Vector6};
use skid_core::Pose;

/// The skew-symmetric matrix `v^`.
fn hat(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `Log` of SO(3), angle in `[0, π]`.
fn so3_log(rotation: &UnitQuaternion<f64>) -> Vector3<f64> {
    let q = rotation.quaternion();
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let sin_half = v.norm();
    if sin_half < 1e-12 {
        return v * (2.0 / w.max(1e-300));
    }
    v * (2.0 * sin_half.atan2(w) / sin_half)
}

/// `Log` of SE(3) as `(ρ, φ)`.
pub fn se3_log(pose: &Pose) -> Vector6<f64> {
    let phi = so3_log(&pose.rotation);
    let theta = phi.norm();
    let k = hat(&phi);
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    let rho = (Matrix3::identity() - k * 0.5 + k * k * c) * pose.translation.vector;
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}

/// The adjoint in `(ρ, φ)` order: `X · Exp(δ) = Exp(Ad(X) δ) · X`.
pub fn adjoint(pose: &Pose) -> Matrix6<f64> {
    let rotation = pose.rotation.to_rotation_matrix().into_inner();
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
    ad.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(hat(&pose.translation.vector) * rotation));
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&rotation);
    ad
}

/// `A Σ Aᵀ`.
pub fn transport(a: &Matrix6<f64>, covariance: &Matrix6<f64>) -> Matrix6<f64> {
    a * covariance * a.transpose()
}

/// The covariance of `X = X̄ · Exp(ξ)` (right perturbation) from that of `X = Exp(ξ) · X̄` (left).
pub fn left_to_right(pose: &Pose, left_covariance: &Matrix6<f64>) -> Matrix6<f64> {
    transport(&adjoint(&pose.inverse()), left_covariance)
}

/// The right-perturbation covariance of `X⁻¹` from the right-perturbation covariance of `X`.
pub fn inverse_covariance(pose: &Pose, right_covariance: &Matrix6<f64>) -> Matrix6<f64> {
    transport(&adjoint(pose), right_covariance)
}

/// `ln Γ(a)` (Lanczos, g = 7).
fn ln_gamma(a: f64) -> f64 {
    const C: [f64; 9] = [
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
    let a = a - 1.0;
    let t = a + 7.5;
    let sum = C[1..]
        .iter()
        .enumerate()
        .fold(C[0], |s, (k, c)| s + c / (a + k as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (a + 0.5) * t.ln() - t + sum.ln()
}

/// The χ² distribution function with `dof` degrees of freedom at `x` (series of the regularised lower
/// incomplete gamma function; adequate for the thresholds used here, `x` up to a few hundred).
pub fn chi2_cdf(dof: usize, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let a = dof.max(1) as f64 / 2.0;
    let half = x / 2.0;
    let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
    for _ in 0..10_000 {
        n += 1.0;
        term *= half / n;
        sum += term;
        if term < sum * 1e-17 {
            break;
        }
    }
    (sum.ln() + a * half.ln() - half - ln_gamma(a)).exp().min(1.0)
}

/// The `probability` quantile of χ² with `dof` degrees of freedom.
pub fn chi2_quantile(dof: usize, probability: f64) -> f64 {
    let p = probability.clamp(1e-12, 1.0 - 1e-12);
    let (mut low, mut high) = (0.0f64, 1.0f64);
    while chi2_cdf(dof, high) < p && high < 1e5 {
        high *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (low + high);
        if chi2_cdf(dof, mid) < p {
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
    fn quantiles_match_the_tables() {
        for (p, expected) in [
            (0.01, 0.872),
            (0.05, 1.635),
            (0.1, 2.204),
            (0.5, 5.348),
            (0.75, 7.840),
            (0.99, 16.812),
        ] {
            assert!((chi2_quantile(6, p) - expected).abs() < 2e-3, "p = {p}");
        }
    }

    #[test]
    fn log_of_a_pure_translation_is_the_translation() {
        let pose = Pose::new(Vector3::new(1.0, 2.0, 3.0), Vector3::zeros());
        assert!((se3_log(&pose) - Vector6::new(1.0, 2.0, 3.0, 0.0, 0.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn adjoint_moves_perturbations() {
        let pose = Pose::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.2, 0.4, -1.0));
        let delta = Vector6::new(0.01, 0.02, -0.01, 0.003, -0.002, 0.004);
        let exp = |d: &Vector6<f64>| {
            // First-order exponential is enough to compare the two sides to O(δ²).
            Pose::new(Vector3::new(d[0], d[1], d[2]), Vector3::new(d[3], d[4], d[5]))
        };
        let left = exp(&(adjoint(&pose) * delta)) * pose;
        let right = pose * exp(&delta);
        assert!((left.inverse() * right).translation.vector.norm() < 1e-3);
    }
}
