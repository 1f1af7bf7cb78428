//! Trajectory accuracy as the evaluation of the SKiD paper defines it: the absolute trajectory error
//! (ATE) after an SE(3) Umeyama alignment (Umeyama, TPAMI 1991) of the estimate to the ground truth,
//! and the end-point drift as a percentage of the distance travelled.

use nalgebra::{Matrix3, Point3, Vector3};
use serde::Serialize;
use skid_core::Pose;

/// Accuracy of an estimated trajectory against ground truth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TrajectoryErrors {
    /// Root mean square position error after the best rigid alignment, metres.
    pub ate_rmse_m: f64,
    /// Final position error with both trajectories starting at the identity (no alignment), metres.
    pub final_translation_error_m: f64,
    /// Final rotation error, degrees.
    pub final_rotation_error_deg: f64,
    /// Distance travelled along the ground truth, metres.
    pub path_length_m: f64,
    /// `final_translation_error_m` as a percentage of `path_length_m` (0 when the path is empty).
    pub drift_percent: f64,
}

/// The rigid transform `target_from_source` minimising Σ‖target_i − T · source_i‖² (Umeyama without
/// scale). Needs at least one pair; with fewer than three non-collinear pairs the rotation about the
/// degenerate axis is arbitrary but the residuals are still minimal.
pub fn umeyama_rigid(source: &[Point3<f64>], target: &[Point3<f64>]) -> Option<Pose> {
    if source.is_empty() || source.len() != target.len() {
        return None;
    }
    let n = source.len() as f64;
    let mean = |points: &[Point3<f64>]| points.iter().fold(Vector3::zeros(), |sum, p| sum + p.coords) / n;
    let (mean_source, mean_target) = (mean(source), mean(target));
    let covariance = source.iter().zip(target).fold(Matrix3::zeros(), |sum, (s, t)| {
        sum + (t.coords - mean_target) * (s.coords - mean_source).transpose()
    }) / n;
    let svd = covariance.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut sign = Matrix3::identity();
    if (u.determinant() * v_t.determinant()) < 0.0 {
        sign[(2, 2)] = -1.0;
    }
    let rotation = nalgebra::Rotation3::from_matrix_unchecked(u * sign * v_t);
    let translation = mean_target - rotation * mean_source;
    let pose = Pose::from_parts(
        translation.into(),
        nalgebra::UnitQuaternion::from_rotation_matrix(&rotation),
    );
    pose.to_homogeneous()
        .iter()
        .all(|v| v.is_finite())
        .then_some(pose)
}

/// Errors of `estimate` against `ground_truth` (same length, pose i of each at the same scan). The
/// ground truth is first expressed relative to its first pose, as the odometry starts at the identity.
pub fn trajectory_errors(estimate: &[Pose], ground_truth: &[Pose]) -> Option<TrajectoryErrors> {
    if estimate.is_empty() || estimate.len() != ground_truth.len() {
        return None;
    }
    let origin_inverse = ground_truth[0].inverse();
    let truth: Vec<Pose> = ground_truth.iter().map(|pose| origin_inverse * pose).collect();
    let start_inverse = estimate[0].inverse();
    let estimate: Vec<Pose> = estimate.iter().map(|pose| start_inverse * pose).collect();
    let position = |pose: &Pose| Point3::from(pose.translation.vector);
    let estimated_positions: Vec<_> = estimate.iter().map(position).collect();
    let true_positions: Vec<_> = truth.iter().map(position).collect();
    let alignment = umeyama_rigid(&estimated_positions, &true_positions)?;
    let sum_sq: f64 = estimated_positions
        .iter()
        .zip(&true_positions)
        .map(|(e, t)| (alignment * e - t).norm_squared())
        .sum();
    let path_length_m: f64 = true_positions
        .windows(2)
        .map(|pair| (pair[1] - pair[0]).norm())
        .sum();
    let (last_estimate, last_truth) = (estimate[estimate.len() - 1], truth[truth.len() - 1]);
    let final_error = last_truth.inverse() * last_estimate;
    let final_translation_error_m = (last_estimate.translation.vector - last_truth.translation.vector).norm();
    Some(TrajectoryErrors {
        ate_rmse_m: (sum_sq / estimate.len() as f64).sqrt(),
        final_translation_error_m,
        final_rotation_error_deg: final_error.rotation.angle().to_degrees(),
        path_length_m,
        drift_percent: if path_length_m > 0.0 {
            100.0 * final_translation_error_m / path_length_m
        } else {
            0.0
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path() -> Vec<Pose> {
        (0..20)
            .map(|i| {
                Pose::new(
                    Vector3::new(f64::from(i), (f64::from(i) * 0.3).sin(), 0.1 * f64::from(i)),
                    Vector3::new(0.0, 0.0, 0.05 * f64::from(i)),
                )
            })
            .collect()
    }

    #[test]
    fn umeyama_recovers_a_rigid_transform() {
        let transform = Pose::new(Vector3::new(3.0, -2.0, 1.0), Vector3::new(0.1, -0.2, 0.7));
        let source: Vec<_> = path()
            .iter()
            .map(|p| Point3::from(p.translation.vector))
            .collect();
        let target: Vec<_> = source.iter().map(|p| transform * p).collect();
        let found = umeyama_rigid(&source, &target).unwrap();
        assert!((found.to_homogeneous() - transform.to_homogeneous()).abs().max() < 1e-9);
    }

    #[test]
    fn a_perfect_estimate_has_no_error_and_a_stopped_one_drifts_fully() {
        let truth: Vec<Pose> = path()
            .iter()
            .map(|p| Pose::translation(5.0, 5.0, 0.0) * p)
            .collect();
        let estimate: Vec<Pose> = path().iter().map(|p| path()[0].inverse() * p).collect();
        let errors = trajectory_errors(&estimate, &truth).unwrap();
        assert!(
            errors.ate_rmse_m < 1e-9 && errors.drift_percent < 1e-9,
            "{errors:?}"
        );
        let stopped = vec![Pose::identity(); truth.len()];
        let errors = trajectory_errors(&stopped, &truth).unwrap();
        assert!(
            errors.drift_percent > 50.0 && errors.ate_rmse_m > 1.0,
            "{errors:?}"
        );
        assert!(trajectory_errors(&stopped[..3], &truth).is_none());
    }
}
