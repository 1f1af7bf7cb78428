//! SE(3) and SO(3) maths for the optimiser: exponential and logarithm maps, right Jacobians and their
//! inverses, and the adjoint, with tangent vectors `(ρ, φ)` (translation first).
//!
//! Closed forms follow Barfoot, "State Estimation for Robotics" (2017), §7.1 (the `Q` block of the SE(3)
//! Jacobian, eq. 7.86) and Solà, Deray & Atchuthan, "A micro Lie theory for state estimation in
//! robotics" (2018); near zero rotation the Taylor expansions are used.

use nalgebra::{Isometry3, Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};

use crate::group::PoseGroup;

/// Below this rotation angle (radians) series expansions replace the closed forms.
const SMALL_ANGLE_RAD: f64 = 1e-4;

/// The skew-symmetric matrix `v^` with `v^ w = v × w`.
pub fn hat(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The left Jacobian of SO(3) at `phi`; the right Jacobian is `so3_left_jacobian(-phi)`.
pub fn so3_left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = hat(phi);
    let (a, b) = if theta < SMALL_ANGLE_RAD {
        (0.5 - theta * theta / 24.0, 1.0 / 6.0 - theta * theta / 120.0)
    } else {
        let t2 = theta * theta;
        ((1.0 - theta.cos()) / t2, (theta - theta.sin()) / (t2 * theta))
    };
    Matrix3::identity() + k * a + k * k * b
}

/// The inverse of the left Jacobian of SO(3) at `phi`.
pub fn so3_left_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = hat(phi);
    let c = if theta < SMALL_ANGLE_RAD {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() - k * 0.5 + k * k * c
}

/// Barfoot's `Q(ρ, φ)`: the upper-right block of the left Jacobian of SE(3).
fn se3_q(rho: &Vector3<f64>, phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let (p, r) = (hat(phi), hat(rho));
    let (c1, c2, c3) = if theta < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        (
            1.0 / 6.0 - t2 / 120.0,
            1.0 / 24.0 - t2 / 720.0,
            1.0 / 120.0 - t2 / 2520.0,
        )
    } else {
        let (s, c) = theta.sin_cos();
        let t2 = theta * theta;
        (
            (theta - s) / (t2 * theta),
            (t2 + 2.0 * c - 2.0) / (2.0 * t2 * t2),
            (2.0 * theta - 3.0 * s + theta * c) / (2.0 * t2 * t2 * theta),
        )
    };
    let pr = p * r;
    let rp = r * p;
    let prp = pr * p;
    r * 0.5 + (pr + rp + prp) * c1 + (p * pr + rp * p - prp * 3.0) * c2 + (prp * p + p * prp) * c3
}

/// The inverse of the left Jacobian of SE(3) at `(ρ, φ)`.
pub fn se3_left_jacobian_inverse(xi: &Vector6<f64>) -> Matrix6<f64> {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    let j_inv = so3_left_jacobian_inverse(&phi);
    let q = se3_q(&rho, &phi);
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&j_inv);
    out.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-(j_inv * q * j_inv)));
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&j_inv);
    out
}

/// `Exp` of SO(3) as a unit quaternion.
pub fn so3_exp(phi: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_scaled_axis(*phi)
}

/// `Log` of SO(3): the rotation vector in `[0, π]`.
pub fn so3_log(rotation: &UnitQuaternion<f64>) -> Vector3<f64> {
    // Take the quaternion with w >= 0 so the angle lies in [0, π].
    let q = rotation.quaternion();
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let sin_half = v.norm();
    if sin_half < 1e-12 {
        // θ ≈ 2 sin(θ/2) / cos(θ/2) to second order.
        return v * (2.0 / w.max(1e-300));
    }
    let theta = 2.0 * sin_half.atan2(w);
    v * (theta / sin_half)
}

/// `Exp` of SE(3) from `(ρ, φ)`.
pub fn se3_exp(xi: &Vector6<f64>) -> Isometry3<f64> {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    let translation = so3_left_jacobian(&phi) * rho;
    Isometry3::from_parts(Translation3::from(translation), so3_exp(&phi))
}

/// `Log` of SE(3) as `(ρ, φ)`, `ρ = J_l(φ)⁻¹ t`.
pub fn se3_log(pose: &Isometry3<f64>) -> Vector6<f64> {
    let phi = so3_log(&pose.rotation);
    let rho = so3_left_jacobian_inverse(&phi) * pose.translation.vector;
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}

/// The adjoint of SE(3) in `(ρ, φ)` order: `[[R, t^ R], [0, R]]`.
pub fn se3_adjoint(pose: &Isometry3<f64>) -> Matrix6<f64> {
    let rotation = pose.rotation.to_rotation_matrix().into_inner();
    let skew_r = hat(&pose.translation.vector) * rotation;
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
    ad.fixed_view_mut::<3, 3>(0, 3).copy_from(&skew_r);
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&rotation);
    ad
}

impl PoseGroup<6> for Isometry3<f64> {
    fn identity() -> Self {
        Isometry3::identity()
    }

    fn compose(&self, other: &Self) -> Self {
        self * other
    }

    fn inverse(&self) -> Self {
        Isometry3::inverse(self)
    }

    fn retract(&self, delta: &Vector6<f64>) -> Self {
        let mut out = self * se3_exp(delta);
        out.rotation.renormalize_fast();
        out
    }

    fn log(&self) -> Vector6<f64> {
        se3_log(self)
    }

    fn right_jacobian_inverse(xi: &Vector6<f64>) -> Matrix6<f64> {
        // J_r(ξ) = J_l(−ξ).
        se3_left_jacobian_inverse(&(-xi))
    }

    fn adjoint(&self) -> Matrix6<f64> {
        se3_adjoint(self)
    }

    fn is_finite(&self) -> bool {
        let q = self.rotation.quaternion();
        self.translation
            .vector
            .iter()
            .chain(q.coords.iter())
            .all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_pose(seed: f64) -> Isometry3<f64> {
        Isometry3::new(
            Vector3::new(1.5 * seed, -0.7 + seed, 2.0 - seed),
            Vector3::new(0.3 * seed, -0.9 * seed.sin(), 1.1 + 0.2 * seed),
        )
    }

    #[test]
    fn exp_and_log_are_inverse() {
        for k in 0..8 {
            let pose = sample_pose(f64::from(k) * 0.37);
            let back = se3_exp(&se3_log(&pose));
            assert!((back.inverse() * pose).translation.vector.norm() < 1e-12);
            assert!((back.inverse() * pose).rotation.angle() < 1e-12);
        }
        let tiny = Vector6::new(1e-3, -2e-3, 5e-4, 1e-9, -3e-9, 2e-9);
        assert!((se3_log(&se3_exp(&tiny)) - tiny).norm() < 1e-15);
    }

    #[test]
    fn right_jacobian_inverse_matches_finite_differences() {
        // Log(Exp(ξ) Exp(δ)) ≈ ξ + J_r(ξ)⁻¹ δ.
        for (k, scale) in [1.0, 1e-5, 2.5].iter().enumerate() {
            let xi = Vector6::new(0.4, -1.2, 0.8, 0.5, -0.3, 0.9) * *scale + Vector6::repeat(0.01 * k as f64);
            let analytic = <Isometry3<f64> as PoseGroup<6>>::right_jacobian_inverse(&xi);
            let h = 1e-6;
            for c in 0..6 {
                let mut delta = Vector6::zeros();
                delta[c] = h;
                let plus = se3_log(&(se3_exp(&xi) * se3_exp(&delta)));
                let minus = se3_log(&(se3_exp(&xi) * se3_exp(&(-delta))));
                let numeric = (plus - minus) / (2.0 * h);
                assert!(
                    (numeric - analytic.column(c)).norm() < 1e-6,
                    "column {c} scale {scale}"
                );
            }
        }
    }

    #[test]
    fn between_jacobians_match_finite_differences() {
        let measured = sample_pose(0.8);
        let (pi, pj) = (sample_pose(0.2), sample_pose(1.3));
        let zinv = measured.inverse();
        let (r, ji, jj) = <Isometry3<f64> as PoseGroup<6>>::between_linearized(&zinv, &pi, &pj);
        assert!((r - se3_log(&(zinv * pi.inverse() * pj))).norm() < 1e-12);
        let h = 1e-6;
        for c in 0..6 {
            let mut delta = Vector6::zeros();
            delta[c] = h;
            let res = |a: &Isometry3<f64>, b: &Isometry3<f64>| se3_log(&(zinv * a.inverse() * b));
            let di = (res(&(pi * se3_exp(&delta)), &pj) - res(&(pi * se3_exp(&(-delta))), &pj)) / (2.0 * h);
            let dj = (res(&pi, &(pj * se3_exp(&delta))) - res(&pi, &(pj * se3_exp(&(-delta))))) / (2.0 * h);
            assert!((di - ji.column(c)).norm() < 1e-6, "J_i column {c}");
            assert!((dj - jj.column(c)).norm() < 1e-6, "J_j column {c}");
        }
    }

    #[test]
    fn adjoint_moves_perturbations_across() {
        let pose = sample_pose(0.6);
        let delta = Vector6::new(0.01, -0.02, 0.03, 0.004, 0.002, -0.005);
        let left = se3_exp(&(se3_adjoint(&pose) * delta)) * pose;
        let right = pose * se3_exp(&delta);
        assert!((left.inverse() * right).translation.vector.norm() < 1e-12);
    }
}
