//! Umeyama's closed-form least-squares alignment of two point sets (S. Umeyama, "Least-squares
//! estimation of transformation parameters between two point patterns", IEEE TPAMI 1991), in SE(3) or
//! Sim(3). The SKiD paper (Sec. "Multi-Robot Alignment Error") aligns each robot's estimate to ground
//! truth with it before computing the APE, as evo's `-a` / `-as` options do.

use nalgebra::{Matrix3, Rotation3, Similarity3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::EvalError;
use skid_core::Pose;

/// A singular value of the cross-covariance below this fraction of the largest counts as zero.
/// Exactly collinear points in `f64` give ratios near 1e-16; real, barely non-collinear
/// trajectories stay far above it.
pub const RANK_RELATIVE_TOLERANCE: f64 = 1e-12;

/// How an estimated trajectory is aligned to ground truth before its absolute error is measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlignmentKind {
    /// No alignment (evo without `-a`).
    None,
    /// Rotation and translation (evo `-a`); the paper's choice.
    #[default]
    Se3,
    /// Rotation, translation and scale (evo `-a -s`), for monocular-like estimates.
    Sim3,
    /// Scale only, with Umeyama's Sim(3) scale (evo `-s` without `-a`).
    ScaleOnly,
}

/// The similarity `target_from_source` (`y ≈ s·R·x + t`) minimising the mean squared distance between
/// the transformed `source` points and the `target` points.
///
/// With `with_scale == false`, `s = 1` (SE(3)). Needs at least three point pairs that are not all
/// collinear (the rotation about their common line would be undetermined); both are reported as errors,
/// as are NaN/Inf coordinates and sets of different sizes.
pub fn umeyama(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    with_scale: bool,
) -> Result<Similarity3<f64>, EvalError> {
    if source.len() != target.len() {
        return Err(EvalError::LengthMismatch {
            what: "Umeyama point sets",
            left: source.len(),
            right: target.len(),
        });
    }
    if source.len() < 3 {
        return Err(EvalError::TooFew {
            what: "Umeyama point pairs",
            needed: 3,
            got: source.len(),
        });
    }
    for (what, points) in [
        ("Umeyama source points", source),
        ("Umeyama target points", target),
    ] {
        if let Some(index) = points.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(EvalError::NonFinite { what, index });
        }
    }

    let n = source.len() as f64;
    let mean_source = source.iter().sum::<Vector3<f64>>() / n;
    let mean_target = target.iter().sum::<Vector3<f64>>() / n;
    let mut variance_source = 0.0;
    let mut covariance = Matrix3::zeros();
    for (x, y) in source.iter().zip(target) {
        let dx = x - mean_source;
        variance_source += dx.norm_squared();
        covariance += (y - mean_target) * dx.transpose();
    }
    variance_source /= n;
    covariance /= n;

    let svd = covariance.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(EvalError::Degenerate {
            reason: "SVD of the cross-covariance did not converge".into(),
        });
    };
    let singular = svd.singular_values;
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| singular[b].total_cmp(&singular[a]));
    let largest = singular[order[0]];
    if largest <= f64::MIN_POSITIVE || variance_source <= f64::MIN_POSITIVE {
        return Err(EvalError::Degenerate {
            reason: "all points coincide".into(),
        });
    }
    if singular[order[1]] <= RANK_RELATIVE_TOLERANCE * largest {
        return Err(EvalError::Degenerate {
            reason: format!(
                "points are collinear (cross-covariance singular values {:.3e}, {:.3e}, {:.3e})",
                singular[order[0]], singular[order[1]], singular[order[2]]
            ),
        });
    }

    // Flip the axis of the smallest singular value when U·Vᵀ would be a reflection (Umeyama eq. 43).
    let mut signs = Vector3::new(1.0, 1.0, 1.0);
    if u.determinant() * v_t.determinant() < 0.0 {
        signs[order[2]] = -1.0;
    }
    let rotation_matrix = u * Matrix3::from_diagonal(&signs) * v_t;
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation_matrix));
    let scale = if with_scale {
        singular.component_mul(&signs).sum() / variance_source
    } else {
        1.0
    };
    let translation = mean_target - scale * (rotation * mean_source);
    Ok(Similarity3::from_parts(
        Translation3::from(translation),
        rotation,
        scale,
    ))
}

/// The alignment `gt_from_est` of an estimated trajectory onto ground truth, from the positions of
/// already associated pose pairs (`gt[i]` and `est[i]` at the same time).
pub fn align_trajectory(
    gt: &[Pose],
    est: &[Pose],
    kind: AlignmentKind,
) -> Result<Similarity3<f64>, EvalError> {
    let gt_positions: Vec<Vector3<f64>> = gt.iter().map(|p| p.translation.vector).collect();
    let est_positions: Vec<Vector3<f64>> = est.iter().map(|p| p.translation.vector).collect();
    match kind {
        AlignmentKind::None => {
            if gt.len() != est.len() {
                return Err(EvalError::LengthMismatch {
                    what: "trajectory poses",
                    left: gt.len(),
                    right: est.len(),
                });
            }
            Ok(Similarity3::identity())
        }
        AlignmentKind::Se3 => umeyama(&est_positions, &gt_positions, false),
        AlignmentKind::Sim3 => umeyama(&est_positions, &gt_positions, true),
        AlignmentKind::ScaleOnly => {
            let sim = umeyama(&est_positions, &gt_positions, true)?;
            Ok(Similarity3::from_scaling(sim.scaling()))
        }
    }
}
