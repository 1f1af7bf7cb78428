//! Absolute pose error (ATE/ARE) after Umeyama alignment, with evo's definitions (the tool the SKiD
//! paper used, Sec. "Multi-Robot Alignment Error"): the translation error of pose i is
//! `‖t_est_aligned,i − t_gt,i‖` in metres, the rotation error the angle of `R_gt,i⁻¹ · R_est_aligned,i`
//! in degrees, each summarised by [`ErrorStats`].

use nalgebra::Similarity3;
use serde::{Deserialize, Serialize};

use crate::error::EvalError;
use crate::geometry::{apply_similarity, check_poses, rotation_angle_deg};
use crate::stats::ErrorStats;
use crate::umeyama::{AlignmentKind, align_trajectory};
use skid_core::Pose;

/// The alignment applied to an estimate, in a form that serialises plainly.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlignmentSummary {
    pub kind: AlignmentKind,
    /// Rotation of `gt_from_est` as a quaternion `[x, y, z, w]`.
    pub rotation_xyzw: [f64; 4],
    /// Angle of that rotation in degrees.
    pub rotation_angle_deg: f64,
    /// Translation of `gt_from_est` in metres.
    pub translation_m: [f64; 3],
    /// Scale of `gt_from_est` (1 for SE(3) and no alignment).
    pub scale: f64,
}

impl AlignmentSummary {
    pub fn new(kind: AlignmentKind, gt_from_est: &Similarity3<f64>) -> Self {
        let q = gt_from_est.isometry.rotation;
        let t = gt_from_est.isometry.translation.vector;
        Self {
            kind,
            rotation_xyzw: [q.i, q.j, q.k, q.w],
            rotation_angle_deg: rotation_angle_deg(&q),
            translation_m: [t.x, t.y, t.z],
            scale: gt_from_est.scaling(),
        }
    }
}

/// An estimate aligned onto ground truth.
#[derive(Clone, Debug)]
pub struct Aligned {
    pub gt_from_est: Similarity3<f64>,
    /// `est` with the alignment applied, pose by pose.
    pub est_aligned: Vec<Pose>,
}

/// Aligns the associated estimate `est` onto `gt` (pairs `gt[i]`, `est[i]`).
pub fn align(gt: &[Pose], est: &[Pose], kind: AlignmentKind) -> Result<Aligned, EvalError> {
    check_pairs(gt, est)?;
    let gt_from_est = align_trajectory(gt, est, kind)?;
    let est_aligned = est.iter().map(|p| apply_similarity(&gt_from_est, p)).collect();
    Ok(Aligned {
        gt_from_est,
        est_aligned,
    })
}

/// Absolute pose errors of one trajectory.
#[derive(Clone, Debug, Serialize)]
pub struct ApeResult {
    pub alignment: AlignmentSummary,
    /// ATE: statistics of `‖t_est_aligned − t_gt‖`, metres.
    pub translation_m: ErrorStats,
    /// ARE: statistics of the angle of `R_gt⁻¹ · R_est_aligned`, degrees.
    pub rotation_deg: ErrorStats,
    /// The per-pose translation errors, metres.
    #[serde(skip)]
    pub translation_errors_m: Vec<f64>,
    /// The per-pose rotation errors, degrees.
    #[serde(skip)]
    pub rotation_errors_deg: Vec<f64>,
    /// The aligned estimate, for plots.
    #[serde(skip)]
    pub est_aligned: Vec<Pose>,
}

/// ATE and ARE of the associated estimate `est` against `gt` after the given alignment.
pub fn ape(gt: &[Pose], est: &[Pose], alignment: AlignmentKind) -> Result<ApeResult, EvalError> {
    let aligned = align(gt, est, alignment)?;
    ape_of_aligned(
        gt,
        aligned.est_aligned,
        AlignmentSummary::new(alignment, &aligned.gt_from_est),
    )
}

/// ATE and ARE of an estimate already expressed in the ground-truth frame.
pub fn ape_of_aligned(
    gt: &[Pose],
    est_aligned: Vec<Pose>,
    alignment: AlignmentSummary,
) -> Result<ApeResult, EvalError> {
    check_pairs(gt, &est_aligned)?;
    let translation_errors_m: Vec<f64> = gt
        .iter()
        .zip(&est_aligned)
        .map(|(g, e)| (e.translation.vector - g.translation.vector).norm())
        .collect();
    let rotation_errors_deg: Vec<f64> = gt
        .iter()
        .zip(&est_aligned)
        .map(|(g, e)| rotation_angle_deg(&(g.rotation.inverse() * e.rotation)))
        .collect();
    Ok(ApeResult {
        alignment,
        translation_m: ErrorStats::from_errors("APE translation errors", &translation_errors_m)?,
        rotation_deg: ErrorStats::from_errors("APE rotation errors", &rotation_errors_deg)?,
        translation_errors_m,
        rotation_errors_deg,
        est_aligned,
    })
}

/// Checks that two associated pose sequences pair up and hold finite poses.
pub(crate) fn check_pairs(gt: &[Pose], est: &[Pose]) -> Result<(), EvalError> {
    if gt.len() != est.len() {
        return Err(EvalError::LengthMismatch {
            what: "associated trajectories",
            left: gt.len(),
            right: est.len(),
        });
    }
    if gt.is_empty() {
        return Err(EvalError::TooFew {
            what: "associated poses",
            needed: 1,
            got: 0,
        });
    }
    check_poses("ground-truth trajectory", gt)?;
    check_poses("estimated trajectory", est)
}
