//! Relative pose error (RPE) over pose pairs a fixed number of frames or metres apart, with evo's
//! definitions (`evo_rpe`, following Sturm et al., "A benchmark for the evaluation of RGB-D SLAM
//! systems", IROS 2012): for a pair (i, j) the error pose is `E = (Q_i⁻¹ Q_j)⁻¹ (P_i⁻¹ P_j)` with `Q` the
//! ground truth and `P` the estimate; the translation error is `‖t(E)‖` and the rotation error the angle
//! of `R(E)` in degrees.

use serde::{Deserialize, Serialize};

use crate::ape::check_pairs;
use crate::error::EvalError;
use crate::geometry::rotation_angle_deg;
use crate::stats::ErrorStats;
use skid_core::Pose;

/// Unit of the RPE step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeltaUnit {
    /// Pairs `delta` poses apart.
    #[default]
    Frames,
    /// Pairs about `delta` metres of travelled path apart.
    Metres,
}

/// Which pose pairs the RPE compares.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RpeOptions {
    /// Step between the two poses of a pair, in `unit`s (evo `--delta`, default 1).
    pub delta: f64,
    pub unit: DeltaUnit,
    /// Every pair `(i, i + delta)` instead of consecutive, non-overlapping pairs (evo `--all_pairs`);
    /// frames only.
    pub all_pairs: bool,
    /// Measure path lengths on the ground truth instead of the (aligned) estimate (evo
    /// `--pairs_from_reference`); only matters for metres.
    pub pairs_from_reference: bool,
}

impl Default for RpeOptions {
    fn default() -> Self {
        Self {
            delta: 1.0,
            unit: DeltaUnit::Frames,
            all_pairs: false,
            pairs_from_reference: false,
        }
    }
}

/// Relative pose errors of one trajectory.
#[derive(Clone, Debug, Serialize)]
pub struct RpeResult {
    pub options: RpeOptions,
    /// Number of pairs compared.
    pub pairs: usize,
    /// Statistics of `‖t(E)‖`, metres.
    pub translation_m: ErrorStats,
    /// Statistics of the angle of `R(E)`, degrees.
    pub rotation_deg: ErrorStats,
    /// The compared pairs (indices into the associated poses).
    #[serde(skip)]
    pub pair_indices: Vec<(usize, usize)>,
}

/// The index pairs evo's RPE compares for these options, chosen on `poses`.
///
/// Frames: `(0, d), (d, 2d), …` or, with `all_pairs`, every `(i, i + d)`. Metres: the poses where the
/// path travelled since the previous chosen pose first reaches `delta` are chosen, starting the count at
/// pose 0 (so, like evo, pose 0 itself is not chosen), and consecutive chosen poses form the pairs.
pub fn rpe_pairs(poses: &[Pose], options: &RpeOptions) -> Result<Vec<(usize, usize)>, EvalError> {
    if !(options.delta.is_finite() && options.delta > 0.0) {
        return Err(EvalError::InvalidOption {
            name: "delta",
            reason: format!("{} is not a positive number", options.delta),
        });
    }
    let n = poses.len();
    let pairs: Vec<(usize, usize)> = match options.unit {
        DeltaUnit::Frames => {
            if options.delta.fract() != 0.0 || options.delta > n as f64 {
                return Err(EvalError::InvalidOption {
                    name: "delta",
                    reason: format!(
                        "{} frames is not a whole number of frames within the {n} poses",
                        options.delta
                    ),
                });
            }
            let step = options.delta as usize;
            if options.all_pairs {
                (0..n.saturating_sub(step)).map(|i| (i, i + step)).collect()
            } else {
                let ids: Vec<usize> = (0..n).step_by(step).collect();
                ids.windows(2).map(|w| (w[0], w[1])).collect()
            }
        }
        DeltaUnit::Metres => {
            if options.all_pairs {
                return Err(EvalError::InvalidOption {
                    name: "all_pairs",
                    reason: "supported for frame deltas only".into(),
                });
            }
            let mut ids = Vec::new();
            let mut path_m = 0.0;
            for i in 0..n {
                if i > 0 {
                    path_m += (poses[i].translation.vector - poses[i - 1].translation.vector).norm();
                }
                if path_m >= options.delta {
                    ids.push(i);
                    path_m = 0.0;
                }
            }
            ids.windows(2).map(|w| (w[0], w[1])).collect()
        }
    };
    if pairs.is_empty() {
        return Err(EvalError::TooFew {
            what: "RPE pose pairs for this delta (try a smaller delta)",
            needed: 1,
            got: 0,
        });
    }
    Ok(pairs)
}

/// RPE of the associated (and, if wanted, already aligned) estimate `est` against `gt`.
pub fn rpe(gt: &[Pose], est: &[Pose], options: &RpeOptions) -> Result<RpeResult, EvalError> {
    check_pairs(gt, est)?;
    let pair_indices = rpe_pairs(if options.pairs_from_reference { gt } else { est }, options)?;
    let mut translation = Vec::with_capacity(pair_indices.len());
    let mut rotation = Vec::with_capacity(pair_indices.len());
    for &(i, j) in &pair_indices {
        let gt_motion = gt[i].inverse() * gt[j];
        let est_motion = est[i].inverse() * est[j];
        let error = gt_motion.inverse() * est_motion;
        translation.push(error.translation.vector.norm());
        rotation.push(rotation_angle_deg(&error.rotation));
    }
    Ok(RpeResult {
        options: *options,
        pairs: pair_indices.len(),
        translation_m: ErrorStats::from_errors("RPE translation errors", &translation)?,
        rotation_deg: ErrorStats::from_errors("RPE rotation errors", &rotation)?,
        pair_indices,
    })
}
