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
