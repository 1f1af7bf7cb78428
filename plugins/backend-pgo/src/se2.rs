//! SE(2) maths for planar pose graphs: exponential and logarithm maps, the inverse right Jacobian and
//! the adjoint, tangent vectors `(ρx, ρy, θ)` (the order of g2o's `EDGE_SE2` information and of GTSAM's
//! `Pose2`).
//!
//! Closed forms from Solà, Deray & Atchuthan, "A micro Lie theory for state estimation in robotics"
//! (2018), appendix C; near zero rotation the Taylor expansions are used.

use nalgebra::{Isometry2, Matrix2, Matrix3, UnitComplex, Vector2, Vector3};

use crate::group::PoseGroup;

/// Below this rotation angle (radians) series expansions replace the closed forms.
const SMALL_ANGLE_RAD: f64 = 1e-4;

/// `sin θ / θ` and `(1 − cos θ) / θ`, stable near zero.
fn sinc_terms(theta: f64) -> (f64, f64) {
    if theta.abs() < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        (1.0 - t2 / 6.0, theta / 2.0 - theta * t2 / 24.0)
    } else {
        (theta.sin() / theta, (1.0 - theta.cos()) / theta)
    }
}

/// `V(θ)`, the matrix with `t = V(θ) ρ` in `Exp`.
fn v_matrix(theta: f64) -> Matrix2<f64> {
    let (a, b) = sinc_terms(theta);
    Matrix2::new(a, -b, b, a)
}

/// `Exp` of SE(2) from `(ρx, ρy, θ)`.
pub fn se2_exp(xi: &Vector3<f64>) -> Isometry2<f64> {
    let translation = v_matrix(xi.z) * Vector2::new(xi.x, xi.y);
    Isometry2::from_parts(translation.into(), UnitComplex::new(xi.z))
}

/// `Log` of SE(2) as `(ρx, ρy, θ)` with `θ ∈ (−π, π]`.
pub fn se2_log(pose: &Isometry2<f64>) -> Vector3<f64> {
    let theta = pose.rotation.angle();
    let (a, b) = sinc_terms(theta);
    // V is a scaled rotation: its inverse is its transpose over its determinant.
    let det = a * a + b * b;
    let t = pose.translation.vector;
    let rho = Vector2::new(a * t.x + b * t.y, -b * t.x + a * t.y) / det;
    Vector3::new(rho.x, rho.y, theta)
}

/// The right Jacobian of SE(2) at `(ρx, ρy, θ)`.
pub fn se2_right_jacobian(xi: &Vector3<f64>) -> Matrix3<f64> {
    let (rho1, rho2, theta) = (xi.x, xi.y, xi.z);
    let (a, b) = sinc_terms(theta);
    // (θ − sin θ)/θ² and (1 − cos θ)/θ², stable near zero.
    let (c, d) = if theta.abs() < SMALL_ANGLE_RAD {
        let t2 = theta * theta;
        (theta / 6.0 - theta * t2 / 120.0, 0.5 - t2 / 24.0)
    } else {
        let t2 = theta * theta;
        ((theta - theta.sin()) / t2, (1.0 - theta.cos()) / t2)
    };
    Matrix3::new(
        a,
        b,
        rho1 * c - rho2 * d,
        -b,
        a,
        rho1 * d + rho2 * c,
        0.0,
        0.0,
        1.0,
    )
}

/// The adjoint of SE(2): `[[R, (t_y, −t_x)ᵀ], [0, 1]]`.
pub fn se2_adjoint(pose: &Isometry2<f64>) -> Matrix3<f64> {
    let r = pose.rotation.to_rotation_matrix().into_inner();
    let t = pose.translation.vector;
    Matrix3::new(
        r[(0, 0)],
        r[(0, 1)],
        t.y,
        r[(1, 0)],
        r[(1, 1)],
        -t.x,
        0.0,
        0.0,
        1.0,
    )
}

impl PoseGroup<3> for Isometry2<f64> {
    fn identity() -> Self {
        Isometry2::identity()
    }

    fn compose(&self, other: &Self) -> Self {
        self * other
    }

    fn inverse(&self) -> Self {
        Isometry2::inverse(self)
    }

    fn retract(&self, delta: &Vector3<f64>) -> Self {
        let mut out = self * se2_exp(delta);
        out.rotation.renormalize();
        out
    }

    fn log(&self) -> Vector3<f64> {
        se2_log(self)
    }

    fn right_jacobian_inverse(xi: &Vector3<f64>) -> Matrix3<f64> {
        // Block inverse of [[A, b], [0, 1]] with A a scaled rotation.
        let jr = se2_right_jacobian(xi);
        let a = jr.fixed_view::<2, 2>(0, 0).into_owned();
        let det = a[(0, 0)] * a[(1, 1)] - a[(0, 1)] * a[(1, 0)];
        let a_inv = Matrix2::new(a[(1, 1)], -a[(0, 1)], -a[(1, 0)], a[(0, 0)]) / det;
        let b = a_inv * Vector2::new(jr[(0, 2)], jr[(1, 2)]);
        Matrix3::new(
            a_inv[(0, 0)],
            a_inv[(0, 1)],
            -b.x,
            a_inv[(1, 0)],
            a_inv[(1, 1)],
            -b.y,
            0.0,
            0.0,
            1.0,
        )
    }

    fn adjoint(&self) -> Matrix3<f64> {
        se2_adjoint(self)
    }

    fn is_finite(&self) -> bool {
        let c = self.rotation.complex();
        self.translation
            .vector
            .iter()
            .chain([c.re, c.im].iter())
            .all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(x: f64, y: f64, theta: f64) -> Isometry2<f64> {
        Isometry2::new(Vector2::new(x, y), theta)
    }

    #[test]
    fn exp_and_log_are_inverse() {
        for (x, y, t) in [
            (1.0, 2.0, 0.3),
            (-3.0, 0.5, 2.9),
            (0.1, -0.2, 1e-7),
            (4.0, 1.0, -3.0),
        ] {
            let p = pose(x, y, t);
            let back = se2_exp(&se2_log(&p));
            assert!((back.inverse() * p).translation.vector.norm() < 1e-12);
            assert!((back.inverse() * p).rotation.angle().abs() < 1e-12);
        }
    }

    #[test]
    fn between_jacobians_match_finite_differences() {
        let (z, pi, pj) = (pose(1.0, 0.2, 0.4), pose(0.3, -1.0, 2.0), pose(1.1, 0.4, -2.5));
        let zinv = z.inverse();
        let (r, ji, jj) = <Isometry2<f64> as PoseGroup<3>>::between_linearized(&zinv, &pi, &pj);
        let res = |a: &Isometry2<f64>, b: &Isometry2<f64>| se2_log(&(zinv * a.inverse() * b));
        assert!((r - res(&pi, &pj)).norm() < 1e-12);
        let h = 1e-6;
        for c in 0..3 {
            let mut d = Vector3::zeros();
            d[c] = h;
            let di = (res(&(pi * se2_exp(&d)), &pj) - res(&(pi * se2_exp(&(-d))), &pj)) / (2.0 * h);
            let dj = (res(&pi, &(pj * se2_exp(&d))) - res(&pi, &(pj * se2_exp(&(-d))))) / (2.0 * h);
            assert!(
                (di - ji.column(c)).norm() < 1e-6,
                "J_i column {c}: {di} vs {}",
                ji.column(c)
            );
            assert!(
                (dj - jj.column(c)).norm() < 1e-6,
                "J_j column {c}: {dj} vs {}",
                jj.column(c)
            );
        }
    }

    #[test]
    fn adjoint_moves_perturbations_across() {
        let p = pose(2.0, -1.0, 0.7);
        let d = Vector3::new(0.01, 0.02, -0.03);
        let left = se2_exp(&(se2_adjoint(&p) * d)) * p;
        let right = p * se2_exp(&d);
        assert!((left.inverse() * right).translation.vector.norm() < 1e-12);
    }
}
