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
    /// Every pair `(i, j)` `delta` apart instead of consecutive, non-overlapping pairs (evo `--all_pairs`).
    pub all_pairs: bool,
    /// With `all_pairs` in metres, a pair is kept when its path length is within `rel_delta_tol · delta`
    /// of `delta` (evo's `rel_delta_tol`, 0.1).
    pub rel_delta_tol: f64,
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
            rel_delta_tol: 0.1,
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
/// Frames: `(0, d), (d, 2d), …` or, with `all_pairs`, every `(i, i + d)`. Metres: pose 0 and then
/// every pose where the path travelled since the previous chosen pose first reaches `delta` are chosen,
/// and consecutive chosen poses form the pairs; with `all_pairs`, every pose `i` is paired with the
/// later pose whose path distance from `i` is nearest to `delta` (the first one on ties), if that is
/// within `rel_delta_tol · delta`. This is evo 1.38's `filter_pairs_by_path`.
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
            let mut distance_m = Vec::with_capacity(n);
            for i in 0..n {
                let step = if i == 0 {
                    0.0
                } else {
                    (poses[i].translation.vector - poses[i - 1].translation.vector).norm()
                };
                distance_m.push(distance_m.last().map_or(0.0, |d| d + step));
            }
            if options.all_pairs {
                if !(options.rel_delta_tol.is_finite() && options.rel_delta_tol >= 0.0) {
                    return Err(EvalError::InvalidOption {
                        name: "rel_delta_tol",
                        reason: format!("{} is not a non-negative number", options.rel_delta_tol),
                    });
                }
                let tolerance_m = options.delta * options.rel_delta_tol;
                (0..n.saturating_sub(1))
                    .filter_map(|i| {
                        let later = &distance_m[i + 1..];
                        let miss = |k: usize| (later[k] - distance_m[i] - options.delta).abs();
                        // The path length never decreases: the best match is the last pose below
                        // `delta` (taken at the first pose of its run of equal lengths) or the first at
                        // or above it.
                        let split = later.partition_point(|d| d - distance_m[i] < options.delta);
                        let below = split
                            .checked_sub(1)
                            .map(|k| later.partition_point(|d| *d < later[k]));
                        let above = (split < later.len()).then_some(split);
                        let best = match (below, above) {
                            (Some(b), Some(a)) => Some(if miss(a) < miss(b) { a } else { b }),
                            (b, a) => b.or(a),
                        }?;
                        (miss(best) <= tolerance_m).then_some((i, i + 1 + best))
                    })
                    .collect()
            } else {
                // A running sum restarted at every chosen pose, as evo sums it (not a difference of
                // cumulative lengths, which can round the other way at a boundary).
                let mut ids = vec![0];
                let mut path_m = 0.0;
                for i in 1..n {
                    path_m += (poses[i].translation.vector - poses[i - 1].translation.vector).norm();
                    if path_m >= options.delta {
                        ids.push(i);
                        path_m = 0.0;
                    }
                }
                ids.windows(2).map(|w| (w[0], w[1])).collect()
            }
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
