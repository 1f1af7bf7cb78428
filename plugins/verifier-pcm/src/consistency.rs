//! Pairwise consistency of two loop closures (Mangelson, Dominic, Eustice & Vasudevan, "Pairwise
//! consistent measurement set maximization for robust multi-robot map merging", ICRA 2018; eq. 9 of the
//! SKiD-SLAM paper).
//!
//! Two loops `a = (t_a ← s_a)` and `b = (t_b ← s_b)` between the same two robots (or within one robot)
//! close a cycle through the odometry of each side:
//! `P = z_a⁻¹ · odom(t_a → t_b) · z_b · odom(s_b → s_a)`, which is the identity when both loops and the
//! odometry are right. With `e = Log(P)` and `Σ_e` the first-order covariance of `e` from the
//! covariances of all four pieces, the loops are consistent when the squared Mahalanobis norm
//! `eᵀ Σ_e⁻¹ e` is below a χ² quantile with 6 degrees of freedom.
//!
//! Conventions: a loop's information is that of the residual `Log(Z⁻¹ T_t⁻¹ T_s)` (perturbation on the
//! right, in the source frame; the g2o/GTSAM convention). The graph's odometry covariance is that of
//! `target_from_source` perturbed on the left, expressed in the target keyframe's frame (what
//! `GraphView::odometry_between` reports); it is moved to the right convention before composition.
//! With right perturbations `X = X̄ Exp(ξ)`, the cycle perturbs as
//! `δe ≈ −Ad(P⁻¹) ξ_a + Ad((CD)⁻¹) ξ_b + Ad(D⁻¹) ξ_c + ξ_d` (`C = z_b`, `D = odom(s_b → s_a)`).

use nalgebra::Matrix6;
use skid_core::slots::{GraphView, LoopClosure};
use skid_core::{KeyframeId, LoopId, Pose, RobotId};

use crate::lie::{adjoint, inverse_covariance, left_to_right, se3_log, transport};

/// A loop closure as PCM keeps it: oriented so that the target robot is not after the source robot,
/// with the covariance of its measurement (right perturbation).
#[derive(Clone, Debug)]
pub struct PcmLoop {
    pub id: LoopId,
    pub target: KeyframeId,
    pub source: KeyframeId,
    pub target_from_source: Pose,
    pub covariance: Matrix6<f64>,
}

impl PcmLoop {
    /// Validates a closure and orients it; the error says why it cannot be used.
    pub fn from_closure(closure: &LoopClosure) -> Result<Self, String> {
        let pose = &closure.target_from_source;
        if !skid_core::pose::is_finite(pose) {
            return Err("the measured pose is not finite".into());
        }
        let information = closure.information;
        if information.iter().any(|v| !v.is_finite()) {
            return Err("the information matrix is not finite".into());
        }
        let symmetric = (information + information.transpose()) * 0.5;
        let cholesky = symmetric
            .cholesky()
            .ok_or("the information matrix is not positive definite")?;
        let covariance = cholesky.inverse();
        let mut pcm = Self {
            id: closure.id,
            target: closure.target,
            source: closure.source,
            target_from_source: *pose,
            covariance,
        };
        if pcm.target.robot > pcm.source.robot {
            pcm.covariance = inverse_covariance(&pcm.target_from_source, &pcm.covariance);
            pcm.target_from_source = pcm.target_from_source.inverse();
            std::mem::swap(&mut pcm.target, &mut pcm.source);
        }
        Ok(pcm)
    }

    /// The robot pair whose loops are compared with this one.
    pub fn group(&self) -> (RobotId, RobotId) {
        (self.target.robot, self.source.robot)
    }
}

/// The squared Mahalanobis norm of the cycle closed by `a` and `b` (same group), or `None` when the
/// graph cannot provide the odometry between their keyframes.
pub fn squared_mahalanobis(a: &PcmLoop, b: &PcmLoop, graph: &dyn GraphView) -> Option<f64> {
    let odom_target = graph.odometry_between(a.target, b.target)?;
    let odom_source = graph.odometry_between(b.source, a.source)?;
    let (za, zb) = (&a.target_from_source, &b.target_from_source);
    let (ob, od) = (&odom_target.target_from_source, &odom_source.target_from_source);
    let cd = zb * od;
    let cycle = za.inverse() * ob * cd;
    let error = se3_log(&cycle);
    let sigma_b = left_to_right(ob, &odom_target.covariance);
    let sigma_d = left_to_right(od, &odom_source.covariance);
    let covariance = transport(&adjoint(&cycle.inverse()), &a.covariance)
        + transport(&adjoint(&cd.inverse()), &sigma_b)
        + transport(&adjoint(&od.inverse()), &b.covariance)
        + sigma_d;
    let symmetric = (covariance + covariance.transpose()) * 0.5;
    if symmetric.iter().any(|v| !v.is_finite()) || error.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let cholesky = symmetric.cholesky()?;
    let whitened = cholesky.l().solve_lower_triangular(&error)?;
    Some(whitened.norm_squared())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use skid_core::Information;
    use skid_core::slots::RelativePose;

    /// Two robots on parallel straight lines with exact odometry of small covariance.
    struct Lines;

    fn truth(id: KeyframeId) -> Pose {
        Pose::new(
            Vector3::new(f64::from(id.index) * 2.0, f64::from(id.robot.0) * 4.0, 0.0),
            Vector3::new(0.0, 0.0, 0.02 * f64::from(id.index)),
        )
    }

    impl GraphView for Lines {
        fn pose(&self, id: KeyframeId) -> Option<Pose> {
            Some(truth(id))
        }
        fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
            (target.robot == source.robot).then(|| RelativePose {
                target_from_source: truth(target).inverse() * truth(source),
                covariance: Information::identity() * 1e-4 * f64::from(target.index.abs_diff(source.index)),
            })
        }
        fn keyframes(&self) -> Vec<KeyframeId> {
            Vec::new()
        }
        fn loops(&self) -> Vec<LoopClosure> {
            Vec::new()
        }
    }

    fn closure(id: u64, target: KeyframeId, source: KeyframeId, error: Pose) -> LoopClosure {
        LoopClosure {
            id: LoopId(id),
            target,
            source,
            target_from_source: truth(target).inverse() * truth(source) * error,
            information: Information::identity() * 100.0,
        }
    }

    /// A loop measured to 1 cm and 0.06°.
    fn precise(id: u64, target: KeyframeId, source: KeyframeId, error: Pose) -> LoopClosure {
        LoopClosure {
            information: Information::identity() * 1e4,
            ..closure(id, target, source, error)
        }
    }

    #[test]
    fn consistent_loops_pass_and_a_wrong_one_fails() {
        let k = KeyframeId::new;
        let good_a = PcmLoop::from_closure(&precise(1, k(0, 2), k(1, 3), Pose::identity())).unwrap();
        // Given from robot 1's side: it is re-oriented into the same group.
        let good_b = PcmLoop::from_closure(&precise(2, k(1, 9), k(0, 7), Pose::identity())).unwrap();
        assert_eq!(good_a.group(), good_b.group());
        let bad = PcmLoop::from_closure(&precise(
            3,
            k(0, 5),
            k(1, 5),
            Pose::new(Vector3::new(3.0, 0.0, 0.0), Vector3::zeros()),
        ))
        .unwrap();
        let d_good = squared_mahalanobis(&good_a, &good_b, &Lines).unwrap();
        assert!(d_good < 1e-12, "{d_good}");
        assert!(squared_mahalanobis(&good_a, &bad, &Lines).unwrap() > 100.0);
        assert!(squared_mahalanobis(&bad, &good_b, &Lines).unwrap() > 100.0);
    }

    #[test]
    fn a_small_error_scores_as_its_mahalanobis_norm() {
        // With exact odometry of negligible covariance, the score of a loop that is off by δ against an
        // exact one is about δᵀ (Σ_a + Σ_b)⁻¹ δ = |δ|² · 100 / 2.
        let k = KeyframeId::new;
        let exact = PcmLoop::from_closure(&closure(1, k(0, 4), k(1, 4), Pose::identity())).unwrap();
        let off = PcmLoop::from_closure(&closure(
            2,
            k(0, 4),
            k(1, 4),
            Pose::new(Vector3::new(0.1, 0.0, 0.0), Vector3::zeros()),
        ))
        .unwrap();
        let d = squared_mahalanobis(&exact, &off, &Lines).unwrap();
        assert!((d - 0.5).abs() < 1e-3, "{d}");
        let mut bad_information = closure(3, k(0, 1), k(1, 1), Pose::identity());
        bad_information.information[(2, 2)] = -1.0;
        assert!(PcmLoop::from_closure(&bad_information).is_err());
    }
}
