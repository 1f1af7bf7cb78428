//! Odometry drift as a percentage of distance travelled, the KITTI odometry benchmark's measure
//! (Geiger et al., "Are we ready for autonomous driving? The KITTI vision benchmark suite", CVPR 2012,
//! and its development kit), plus a simpler end-point drift for short runs.
//!
//! **Segment drift (KITTI).** Path length is accumulated along the ground truth. From every
//! `step_frames`-th pose `i` and for each segment length `L`, the segment ends at the first pose `j`
//! whose path length exceeds that of `i` by more than `L`. Its error pose is
//! `E = (P_i⁻¹ P_j)⁻¹ (Q_i⁻¹ Q_j)` (`Q` ground truth, `P` estimate); the segment's translational error
//! is `‖t(E)‖ / L` and its rotational error `angle(R(E)) / L`. The drift is the mean over all segments
//! of all lengths, in percent and in degrees per 100 m. No alignment is needed: only relative motion
//! enters.
//!
//! **End-point drift.** `‖t(E)‖ / path length · 100` for the single segment from the first to the last
//! pose, for trajectories shorter than the shortest KITTI segment.

use serde::{Deserialize, Serialize};

use crate::ape::check_pairs;
use crate::error::EvalError;
use crate::geometry::rotation_angle_rad;
use skid_core::Pose;

/// Options of the segment drift.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriftOptions {
    /// Segment lengths in metres (KITTI: 100, 200, …, 800).
    pub segment_lengths_m: Vec<f64>,
    /// Start a segment at every `step_frames`-th pose (KITTI: 10).
    pub step_frames: usize,
}

impl Default for DriftOptions {
    fn default() -> Self {
        Self {
            segment_lengths_m: (1..=8).map(|k| 100.0 * f64::from(k)).collect(),
            step_frames: 10,
        }
    }
}

/// Drift over the segments of one length.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentDrift {
    pub length_m: f64,
    pub segments: usize,
    pub translation_percent: f64,
    pub rotation_deg_per_100m: f64,
}

/// Drift of one trajectory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DriftResult {
    /// Ground-truth path length, metres.
    pub path_length_m: f64,
    /// Number of segments over all lengths.
    pub segments: usize,
    /// Mean segment translational error, percent (`None` when no segment fits in the path).
    pub translation_percent: Option<f64>,
    /// Mean segment rotational error, degrees per 100 m (`None` when no segment fits).
    pub rotation_deg_per_100m: Option<f64>,
    /// The same per segment length (lengths without a segment are left out).
    pub per_length: Vec<SegmentDrift>,
    /// End-point translational drift, percent of the path length.
    pub endpoint_percent: f64,
}

/// The relative-motion error `(P_i⁻¹ P_j)⁻¹ (Q_i⁻¹ Q_j)` of a pose pair, as (translation m, angle rad).
fn segment_error(gt: &[Pose], est: &[Pose], i: usize, j: usize) -> (f64, f64) {
    let gt_motion = gt[i].inverse() * gt[j];
    let est_motion = est[i].inverse() * est[j];
    let error = est_motion.inverse() * gt_motion;
    (
        error.translation.vector.norm(),
        rotation_angle_rad(&error.rotation),
    )
}

/// Segment and end-point drift of the associated estimate `est` against `gt`.
pub fn drift(gt: &[Pose], est: &[Pose], options: &DriftOptions) -> Result<DriftResult, EvalError> {
    check_pairs(gt, est)?;
    if gt.len() < 2 {
        return Err(EvalError::TooFew {
            what: "poses for drift",
            needed: 2,
            got: gt.len(),
        });
    }
    if options.step_frames == 0 {
        return Err(EvalError::InvalidOption {
            name: "step_frames",
            reason: "must be at least 1".into(),
        });
    }
    if let Some(bad) = options
        .segment_lengths_m
        .iter()
        .find(|l| !(l.is_finite() && **l > 0.0))
    {
        return Err(EvalError::InvalidOption {
            name: "segment_lengths_m",
            reason: format!("{bad} is not a positive length"),
        });
    }
    let mut distance_m = Vec::with_capacity(gt.len());
    distance_m.push(0.0);
    for k in 1..gt.len() {
        let step = (gt[k].translation.vector - gt[k - 1].translation.vector).norm();
        distance_m.push(distance_m[k - 1] + step);
    }
    let path_length_m = distance_m[gt.len() - 1];
    if path_length_m <= 0.0 {
        return Err(EvalError::InvalidOption {
            name: "ground truth",
            reason: "the ground truth does not move (path length 0)".into(),
        });
    }

    let mut per_length = Vec::new();
    let (mut sum_t, mut sum_r, mut segments) = (0.0, 0.0, 0usize);
    for &length_m in &options.segment_lengths_m {
        let (mut t_sum, mut r_sum, mut count) = (0.0, 0.0, 0usize);
        for first in (0..gt.len()).step_by(options.step_frames) {
            let goal = distance_m[first] + length_m;
            // The path length never decreases, so the first pose beyond the goal is a partition point.
            let last = distance_m.partition_point(|&d| d <= goal);
            if last >= gt.len() {
                continue;
            }
            let (t_err, r_err) = segment_error(gt, est, first, last);
            t_sum += t_err / length_m;
            r_sum += r_err / length_m;
            count += 1;
        }
        if count > 0 {
            per_length.push(SegmentDrift {
                length_m,
                segments: count,
                translation_percent: 100.0 * t_sum / count as f64,
                rotation_deg_per_100m: 100.0 * (r_sum / count as f64).to_degrees(),
            });
            sum_t += t_sum;
            sum_r += r_sum;
            segments += count;
        }
    }
    let (endpoint_t, _) = segment_error(gt, est, 0, gt.len() - 1);
    Ok(DriftResult {
        path_length_m,
        segments,
        translation_percent: (segments > 0).then(|| 100.0 * sum_t / segments as f64),
        rotation_deg_per_100m: (segments > 0).then(|| 100.0 * (sum_r / segments as f64).to_degrees()),
        per_length,
        endpoint_percent: 100.0 * endpoint_t / path_length_m,
    })
}
