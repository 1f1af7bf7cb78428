//! The SKiD paper's multi-robot alignment metric (Sec. "Multi-Robot Alignment Error"): robot α is judged
//! by its APE after Umeyama alignment `T^GT_α`; robot β is judged by how well it sits in α's frame,
//!
//! `T_β,APE = (T^GT_β)⁻¹ · T^GT_α · T^α_β`,
//!
//! where `T^GT_β` is β's own Umeyama alignment to its ground truth and `T^α_β` the distributed back-end's
//! estimate of β's frame in α's frame. With a perfect inter-robot estimate `T_β,APE` is the identity.
//! Besides that single transform, the β trajectory mapped into the ground-truth frame through α's
//! alignment (`T^GT_α · T^α_β`) is compared pose by pose with β's ground truth, which is the APE a tool
//! like evo reports for β when β is placed with α's alignment instead of its own.

use nalgebra::Similarity3;
use serde::Serialize;

use crate::ape::{AlignmentSummary, ApeResult, align, ape_of_aligned};
use crate::error::EvalError;
use crate::geometry::{apply_similarity, pose_is_finite, rotation_angle_deg};
use crate::umeyama::AlignmentKind;
use skid_core::Pose;

/// The inputs of the α/β metric: associated ground-truth/estimate pairs for each robot and the
/// estimated inter-robot transform.
#[derive(Clone, Copy, Debug)]
pub struct AlphaBetaInput<'a> {
    pub gt_alpha: &'a [Pose],
    /// α's estimate, in α's map frame.
    pub est_alpha: &'a [Pose],
    pub gt_beta: &'a [Pose],
    /// β's estimate, in β's map frame.
    pub est_beta: &'a [Pose],
    /// `T^α_β`: maps β's map frame into α's map frame (identity when β's estimate is already in α's frame).
    pub alpha_from_beta: Pose,
}

/// The error transform `T_β,APE` as numbers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TransformError {
    /// Norm of the translation, metres.
    pub translation_m: f64,
    /// Rotation angle, degrees.
    pub rotation_deg: f64,
    /// Scale (1 unless Sim(3) alignment was used).
    pub scale: f64,
}

/// Result of the α/β metric.
#[derive(Clone, Debug, Serialize)]
pub struct AlphaBetaResult {
    /// α's APE after its own Umeyama alignment `T^GT_α`.
    pub alpha: ApeResult,
    /// The paper's `T_β,APE = (T^GT_β)⁻¹ · T^GT_α · T^α_β`.
    pub beta_alignment_error: TransformError,
    /// β's estimate mapped through `T^GT_α · T^α_β`, compared with β's ground truth (no alignment of its own).
    pub beta_in_alpha: ApeResult,
    /// β's APE after its own alignment `T^GT_β` (trajectory shape only, for reference).
    pub beta_own: ApeResult,
    /// `T_β,APE` itself.
    #[serde(skip)]
    pub beta_error_transform: Similarity3<f64>,
}

/// Computes the α/β metric. `alignment` is the Umeyama variant for both robots (the paper uses SE(3)).
pub fn alpha_beta(
    input: &AlphaBetaInput<'_>,
    alignment: AlignmentKind,
) -> Result<AlphaBetaResult, EvalError> {
    if !pose_is_finite(&input.alpha_from_beta) {
        return Err(EvalError::NonFinite {
            what: "alpha_from_beta transform",
            index: 0,
        });
    }
    let alpha = align(input.gt_alpha, input.est_alpha, alignment)?;
    let beta = align(input.gt_beta, input.est_beta, alignment)?;
    let alpha_from_beta = Similarity3::from_isometry(input.alpha_from_beta, 1.0);
    let gt_from_beta_via_alpha = alpha.gt_from_est * alpha_from_beta;
    let error = beta.gt_from_est.inverse() * gt_from_beta_via_alpha;

    let beta_in_alpha_poses: Vec<Pose> = input
        .est_beta
        .iter()
        .map(|p| apply_similarity(&gt_from_beta_via_alpha, p))
        .collect();
    Ok(AlphaBetaResult {
        alpha: ape_of_aligned(
            input.gt_alpha,
            alpha.est_aligned,
            AlignmentSummary::new(alignment, &alpha.gt_from_est),
        )?,
        beta_alignment_error: TransformError {
            translation_m: error.isometry.translation.vector.norm(),
            rotation_deg: rotation_angle_deg(&error.isometry.rotation),
            scale: error.scaling(),
        },
        beta_in_alpha: ape_of_aligned(
            input.gt_beta,
            beta_in_alpha_poses,
            AlignmentSummary::new(alignment, &gt_from_beta_via_alpha),
        )?,
        beta_own: ape_of_aligned(
            input.gt_beta,
            beta.est_aligned,
            AlignmentSummary::new(alignment, &beta.gt_from_est),
        )?,
        beta_error_transform: error,
    })
}

/// The error of β's frame as placed in α's, judged at the two robots' anchors: each robot's map frame is
/// fixed by its first pose (the back-end holds it with a prior), so the true `T^α_β` is
/// `(T^GT_α(0) · T̂_α(0)⁻¹)⁻¹ · T^GT_β(0) · T̂_β(0)⁻¹` and the error is the estimate against it.
///
/// Unlike `T_β,APE`, which takes each robot's frame from an Umeyama alignment of its whole trajectory,
/// this is defined for any trajectory: a straight route leaves the rotation about its own line
/// unobservable to Umeyama (see [`crate::conditioning`]), and `T_β,APE` then reports an arbitrary
/// rotation for a frame placed correctly. The price is that drift between a robot's start and the places
/// where the robots met enters the error; over the routes a merge is judged on it is small.
pub fn anchored_frame_error(
    (gt_alpha_first, est_alpha_first): (&Pose, &Pose),
    (gt_beta_first, est_beta_first): (&Pose, &Pose),
    alpha_from_beta: &Pose,
) -> TransformError {
    let true_alpha_from_beta =
        (gt_alpha_first * est_alpha_first.inverse()).inverse() * (gt_beta_first * est_beta_first.inverse());
    let error = true_alpha_from_beta.inverse() * alpha_from_beta;
    TransformError {
        translation_m: error.translation.vector.norm(),
        rotation_deg: rotation_angle_deg(&error.rotation),
        scale: 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    use crate::geometry::planar_pose as pose;

    /// Two straight routes, each robot's estimate in its own frame (its first pose at the origin).
    fn straight(start: Pose, count: usize) -> (Vec<Pose>, Vec<Pose>) {
        let truth: Vec<Pose> = (0..count).map(|i| start * pose(i as f64, 0.0, 0.0)).collect();
        let estimate = truth.iter().map(|t| truth[0].inverse() * t).collect();
        (truth, estimate)
    }

    #[test]
    fn a_correct_frame_has_no_anchored_error_even_where_umeyama_is_blind() {
        let (gt_a, est_a) = straight(pose(0.0, 0.0, 0.0), 50);
        let (gt_b, est_b) = straight(pose(10.0, 5.0, 90.0), 50);
        let alpha_from_beta = gt_a[0].inverse() * gt_b[0];
        let anchored = anchored_frame_error((&gt_a[0], &est_a[0]), (&gt_b[0], &est_b[0]), &alpha_from_beta);
        assert!(anchored.translation_m < 1e-9 && anchored.rotation_deg < 1e-9);

        // Off by 3 m and 10°: reported as such.
        let wrong = alpha_from_beta * pose(3.0, 0.0, 10.0);
        let anchored = anchored_frame_error((&gt_a[0], &est_a[0]), (&gt_b[0], &est_b[0]), &wrong);
        assert!((anchored.translation_m - 3.0).abs() < 1e-9);
        assert!((anchored.rotation_deg - 10.0).abs() < 1e-9);
    }

    #[test]
    fn the_anchored_error_does_not_depend_on_where_each_map_frame_starts() {
        let (gt_a, _) = straight(pose(0.0, 0.0, 0.0), 20);
        let (gt_b, _) = straight(pose(-4.0, 8.0, 30.0), 20);
        // Each robot's estimate in a frame of its own choosing.
        let frame_a = Pose::new(Vector3::new(1.0, 2.0, 0.5), Vector3::new(0.1, 0.0, 0.4));
        let frame_b = Pose::new(Vector3::new(-3.0, 0.0, 1.0), Vector3::new(0.0, 0.2, -1.0));
        let est_a: Vec<Pose> = gt_a.iter().map(|t| frame_a * t).collect();
        let est_b: Vec<Pose> = gt_b.iter().map(|t| frame_b * t).collect();
        let alpha_from_beta = frame_a * frame_b.inverse();
        let anchored = anchored_frame_error((&gt_a[0], &est_a[0]), (&gt_b[0], &est_b[0]), &alpha_from_beta);
        assert!(
            anchored.translation_m < 1e-9 && anchored.rotation_deg < 1e-6,
            "{anchored:?}"
        );
    }
}
