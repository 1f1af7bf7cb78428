//! Running an odometry alone over a source, as `skid odometry SEQ_DIR` does: per-scan timing, the
//! estimated and ground-truth trajectories, and the one-line summary (frames, milliseconds per frame,
//! ATE and drift as defined in [`crate::evaluation`], after KISS-ICP's evaluation, Vizzo et al., RA-L 2023).

use std::time::Instant;

use serde::Serialize;
use skid_core::slots::{Odometry, Source};
use skid_core::{PluginError, PluginResult, Pose};

use crate::evaluation::{TrajectoryErrors, trajectory_errors};

/// Everything recorded while running an odometry over a sequence.
#[derive(Clone, Debug, Default)]
pub struct SequenceRun {
    /// Stamps and poses of the scans the odometry accepted.
    pub stamps_nanos: Vec<u64>,
    pub poses: Vec<Pose>,
    /// Ground truth of the accepted scans, when the source has it for every one of them.
    pub ground_truth: Option<Vec<Pose>>,
    /// Wall time of each accepted `register` call, milliseconds.
    pub frame_ms: Vec<f64>,
    /// Scans the odometry refused (each logged as a warning).
    pub skipped: usize,
    pub keyframes: usize,
}

/// The one-line JSON summary of a run.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub frames: usize,
    pub skipped: usize,
    pub keyframes: usize,
    pub ms_per_frame_median: f64,
    pub ms_per_frame_p90: f64,
    /// Present when the source provides ground truth.
    pub ate_m: Option<f64>,
    pub drift_percent: Option<f64>,
    pub path_length_m: Option<f64>,
}

/// The `q` quantile (nearest rank) of `values`; 0 when empty.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[((sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize]
}

impl SequenceRun {
    /// ATE and drift against the ground truth, if there is one.
    pub fn errors(&self) -> Option<TrajectoryErrors> {
        trajectory_errors(&self.poses, self.ground_truth.as_ref()?)
    }

    pub fn summary(&self) -> RunSummary {
        let errors = self.errors();
        RunSummary {
            frames: self.poses.len(),
            skipped: self.skipped,
            keyframes: self.keyframes,
            ms_per_frame_median: quantile(&self.frame_ms, 0.5),
            ms_per_frame_p90: quantile(&self.frame_ms, 0.9),
            ate_m: errors.map(|e| e.ate_rmse_m),
            drift_percent: errors.map(|e| e.drift_percent),
            path_length_m: errors.map(|e| e.path_length_m),
        }
    }
}

/// Feeds every scan of `source` (at most `max_frames` when given) to `odometry`. Scans the odometry
/// refuses as invalid input are skipped with a warning; any other error stops the run.
pub fn run_sequence(
    source: &mut dyn Source,
    odometry: &mut dyn Odometry,
    max_frames: Option<usize>,
) -> PluginResult<SequenceRun> {
    let mut run = SequenceRun::default();
    let mut truth = Some(Vec::new());
    let mut seen = 0usize;
    while max_frames.is_none_or(|max| seen < max) {
        let Some(scan) = source.next_scan()? else { break };
        seen += 1;
        let started = Instant::now();
        match odometry.register(&scan) {
            Ok(update) => {
                run.frame_ms.push(started.elapsed().as_secs_f64() * 1e3);
                run.stamps_nanos.push(update.stamp_nanos);
                run.poses.push(update.world_from_sensor);
                run.keyframes += usize::from(update.keyframe.is_some());
                truth = truth
                    .zip(scan.ground_truth_world_from_sensor)
                    .map(|(mut poses, pose)| {
                        poses.push(pose);
                        poses
                    });
            }
            Err(PluginError::InvalidInput(reason)) => {
                tracing::warn!("skipping scan {}: {reason}", scan.sequence);
                run.skipped += 1;
            }
            Err(other) => return Err(other),
        }
    }
    run.ground_truth = truth.filter(|poses| !poses.is_empty());
    Ok(run)
}
