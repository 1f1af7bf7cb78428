//! Inter-robot registration accuracy as the SKiD paper reports it (Sec. "RTE, RRE, and Success Rate"):
//! a registration succeeds when its translation error is below 2 m and its rotation error below 5°;
//! the success rate is the fraction of successes, and RTE/RRE are averaged over the successful pairs
//! only.
//!
//! Per pair, the translation error is `‖t_gt − t̂‖` and the rotation error
//! `acos((trace(R̂ᵀ R_gt) − 1) / 2)` (computed stably from the quaternion of `R̂ᵀ R_gt`). The paper's
//! printed RTE formula squares the difference and multiplies by 100 while its table reports RTE in cm,
//! and its RRE formula carries a stray π/180 while the table reports degrees; we read them as the mean
//! Euclidean translation error (reported in metres and in centimetres) and the mean rotation angle in
//! degrees.

use serde::{Deserialize, Serialize};

use crate::error::EvalError;
use crate::geometry::{pose_is_finite, rotation_angle_deg};
use skid_core::Pose;

/// Success thresholds (strict: an error equal to the threshold is a failure).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RegistrationThresholds {
    pub max_translation_m: f64,
    pub max_rotation_deg: f64,
}

impl Default for RegistrationThresholds {
    /// The paper's 2 m and 5°.
    fn default() -> Self {
        Self {
            max_translation_m: 2.0,
            max_rotation_deg: 5.0,
        }
    }
}

/// One registration attempt: the estimated and the true `target_from_source`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegistrationPair {
    /// `None` when the registration gave no result (not converged, rejected); counts as a failure.
    pub estimated: Option<Pose>,
    pub ground_truth: Pose,
}

/// Errors of one registration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegistrationError {
    pub translation_m: f64,
    pub rotation_deg: f64,
}

/// Translation and rotation error of an estimated transform against the true one.
pub fn registration_error(estimated: &Pose, ground_truth: &Pose) -> RegistrationError {
    RegistrationError {
        translation_m: (ground_truth.translation.vector - estimated.translation.vector).norm(),
        rotation_deg: rotation_angle_deg(&(estimated.rotation.inverse() * ground_truth.rotation)),
    }
}

/// Success rate, RTE and RRE over a set of registrations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegistrationStats {
    pub thresholds: RegistrationThresholds,
    pub pairs: usize,
    pub successes: usize,
    /// `successes / pairs`, in `[0, 1]`.
    pub success_rate: f64,
    /// Mean translation error over the successes, metres (`None` without a success).
    pub rte_m: Option<f64>,
    /// The same in centimetres, the paper's unit.
    pub rte_cm: Option<f64>,
    /// Mean rotation error over the successes, degrees (`None` without a success).
    pub rre_deg: Option<f64>,
    /// Per pair, its errors (`None` for a registration without result).
    pub errors: Vec<Option<RegistrationError>>,
}

/// Evaluates `pairs` against `thresholds`. No pair, non-finite poses or thresholds are errors.
pub fn registration_stats(
    pairs: &[RegistrationPair],
    thresholds: &RegistrationThresholds,
) -> Result<RegistrationStats, EvalError> {
    if pairs.is_empty() {
        return Err(EvalError::TooFew {
            what: "registration pairs",
            needed: 1,
            got: 0,
        });
    }
    for (name, value) in [
        ("max_translation_m", thresholds.max_translation_m),
        ("max_rotation_deg", thresholds.max_rotation_deg),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(EvalError::InvalidOption {
                name,
                reason: format!("{value} is not a positive number"),
            });
        }
    }
    for (index, pair) in pairs.iter().enumerate() {
        let bad_estimate = pair.estimated.as_ref().is_some_and(|p| !pose_is_finite(p));
        if bad_estimate || !pose_is_finite(&pair.ground_truth) {
            return Err(EvalError::NonFinite {
                what: "registration pair",
                index,
            });
        }
    }
    let errors: Vec<Option<RegistrationError>> = pairs
        .iter()
        .map(|p| p.estimated.map(|est| registration_error(&est, &p.ground_truth)))
        .collect();
    let successful: Vec<&RegistrationError> = errors
        .iter()
        .flatten()
        .filter(|e| {
            e.translation_m < thresholds.max_translation_m && e.rotation_deg < thresholds.max_rotation_deg
        })
        .collect();
    let successes = successful.len();
    let mean = |f: fn(&RegistrationError) -> f64| {
        (successes > 0).then(|| successful.iter().map(|e| f(e)).sum::<f64>() / successes as f64)
    };
    let rte_m = mean(|e| e.translation_m);
    Ok(RegistrationStats {
        thresholds: *thresholds,
        pairs: pairs.len(),
        successes,
        success_rate: successes as f64 / pairs.len() as f64,
        rte_m,
        rte_cm: rte_m.map(|m| m * 100.0),
        rre_deg: mean(|e| e.rotation_deg),
        errors,
    })
}
