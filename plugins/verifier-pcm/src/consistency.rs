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
use skid_core::slots::{GraphView, LoopClosure, RelativePose};
use skid_core::{KeyframeId, LoopId, Pose, RobotId};

use crate::lie::{adjoint, inverse_covariance, se3_log, transport};

/// A loop closure as PCM keeps it: oriented so that the target robot is not after the source robot,
/// with the covariance of its measurement (right perturbation).
#[derive(Clone, Debug)]
pub struct PcmLoop {
    pub id: LoopId,
    pub target: KeyframeId,
    pub source: KeyframeId,
    pub target_from_source: Pose,
    pub covariance: Matrix6<f64>,
    /// The scans of the loop's two keyframes show each robot's body where the loop puts it at that
    /// moment ([`crate::peer_seen::Sighting::Seen`]): evidence beyond the places' looks.
    pub sighted: bool,
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
            sighted: false,
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
    let odometry = CycleOdometry::between(a, b, graph)?;
    cycle_squared_mahalanobis(a, b, &odometry)
}

/// The odometry a cycle of two loops runs along: from `a`'s target keyframe to `b`'s, and from `b`'s
/// source keyframe to `a`'s.
#[derive(Clone, Debug)]
pub struct CycleOdometry {
    pub targets: RelativePose,
    pub sources: RelativePose,
}

impl CycleOdometry {
    /// Asks the graph for the odometry of the cycle `a` and `b` close; `None` when it lacks either part.
    pub fn between(a: &PcmLoop, b: &PcmLoop, graph: &dyn GraphView) -> Option<Self> {
        Some(Self {
            targets: graph.odometry_between(a.target, b.target)?,
            sources: graph.odometry_between(b.source, a.source)?,
        })
    }
}

/// [`squared_mahalanobis`] on odometry already fetched from the graph (a test gives it odometry of its
/// own, with no graph).
///
/// The first-order covariance of `e` (module doc) is expressed in the frame the adjoint of the cycle
/// `P` moves it to: the norm is the same in any frame, and `Ad(P) e = e` since `e = Log(P)`. There,
/// with `A = z_a⁻¹` and `B = z_a⁻¹ · odom(t_a → t_b) · z_b`, it is
/// `Σ_a + Ad(A) Σ_ta→tb Ad(A)ᵀ + Ad(B) (Σ_b + Σ_sb→sa) Ad(B)ᵀ`, the odometry's covariances taken as the
/// graph reports them (left-perturbed, in their target frames): two transports where composing the
/// four pieces one by one takes five, and the same value up to rounding.
pub fn cycle_squared_mahalanobis(a: &PcmLoop, b: &PcmLoop, odometry: &CycleOdometry) -> Option<f64> {
    let (odom_target, odom_source) = (&odometry.targets, &odometry.sources);
    let (za, zb) = (&a.target_from_source, &b.target_from_source);
    let (ob, od) = (&odom_target.target_from_source, &odom_source.target_from_source);
    let za_inverse = za.inverse();
    let through_b = za_inverse * ob * zb;
    let cycle = through_b * od;
    let error = se3_log(&cycle);
    let covariance = a.covariance
        + transport(&adjoint(&za_inverse), &odom_target.covariance)
        + transport(&adjoint(&through_b), &(b.covariance + odom_source.covariance));
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

    /// The cycle's norm composed piece by piece in the cycle's first frame (the module doc's formula,
    /// five transports), as a reference for the two-transport form.
    fn composed_piece_by_piece(a: &PcmLoop, b: &PcmLoop, odometry: &CycleOdometry) -> f64 {
        use crate::lie::left_to_right;
        let (ob, od) = (
            &odometry.targets.target_from_source,
            &odometry.sources.target_from_source,
        );
        let cd = b.target_from_source * od;
        let cycle = a.target_from_source.inverse() * ob * cd;
        let covariance = transport(&adjoint(&cycle.inverse()), &a.covariance)
            + transport(
                &adjoint(&cd.inverse()),
                &left_to_right(ob, &odometry.targets.covariance),
            )
            + transport(&adjoint(&od.inverse()), &b.covariance)
            + left_to_right(od, &odometry.sources.covariance);
        let symmetric = (covariance + covariance.transpose()) * 0.5;
        let whitened = symmetric
            .cholesky()
            .unwrap()
            .l()
            .solve_lower_triangular(&se3_log(&cycle))
            .unwrap();
        whitened.norm_squared()
    }

    #[test]
    fn the_two_transport_form_equals_the_piece_by_piece_one() {
        // Loops and odometry far from the identity, with full covariances, so that every frame matters.
        let pose = |k: f64| {
            Pose::new(
                Vector3::new(3.0 * k, -2.0 + k, 0.5 * k),
                Vector3::new(0.1 * k, -0.2, 0.7 * k),
            )
        };
        let covariance = |k: f64| {
            let m = nalgebra::Matrix6::from_fn(|i, j| ((i * 7 + j * 3) as f64 * k).sin());
            m * m.transpose() * 1e-3 + Information::identity() * 1e-4
        };
        for k in [0.3, 1.1, 2.7] {
            let loop_of = |id: u64, z: Pose, c: nalgebra::Matrix6<f64>| PcmLoop {
                id: LoopId(id),
                target: KeyframeId::new(0, id as u32),
                source: KeyframeId::new(1, id as u32),
                target_from_source: z,
                covariance: c,
                sighted: false,
            };
            let a = loop_of(1, pose(k), covariance(k));
            let b = loop_of(2, pose(k + 0.4) * pose(0.2), covariance(k + 1.0));
            let odometry = CycleOdometry {
                targets: RelativePose {
                    target_from_source: pose(-k),
                    covariance: covariance(2.0 * k),
                },
                sources: RelativePose {
                    target_from_source: pose(0.5 * k),
                    covariance: covariance(3.0 * k),
                },
            };
            let reference = composed_piece_by_piece(&a, &b, &odometry);
            let fast = cycle_squared_mahalanobis(&a, &b, &odometry).unwrap();
            assert!(
                (fast - reference).abs() <= 1e-9 * reference.max(1.0),
                "{fast} vs {reference}"
            );
        }
    }
}
