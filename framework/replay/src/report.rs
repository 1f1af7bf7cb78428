//! The figures of a replay: each robot's ATE against the file's ground truth (unaligned, since the priors
//! hold each robot at its true start, and after one SE(3) alignment of all robots together), the loops
//! accepted, the labelled outliers kept and the true loops dropped, split into intra- and inter-robot
//! loops, and the time per update.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::Serialize;
use skid_core::LoopId;

use crate::problem::{Item, ReplayProblem};
use crate::run::{LoopFate, ReplayMode, ReplayOutcome};

/// One robot's figures.
#[derive(Clone, Debug, Serialize)]
pub struct RobotReport {
    pub robot: char,
    pub keyframes: usize,
    /// RMSE of the keyframe positions against the ground truth, no alignment.
    pub ate_m: f64,
    /// The same after one SE(3) alignment of every robot's estimate together.
    pub ate_aligned_m: f64,
}

/// Loop counts of one kind (intra- or inter-robot).
#[derive(Clone, Debug, Default, Serialize)]
pub struct LoopCounts {
    /// Loops the file holds, of them the labelled outliers, and the known inliers (factors between
    /// keyframes that are not consecutive but that the file does not list as possibly wrong: they go to
    /// the back-end without the verifier).
    pub loops: usize,
    pub labelled_outliers: usize,
    pub known_inliers: usize,
    /// Loops the verifier accepted (or the file marks known inliers).
    pub accepted: usize,
    /// Loops that move some robot's estimate at the end.
    pub kept: usize,
    /// Labelled outliers kept: false positives.
    pub outliers_kept: usize,
    /// True loops not kept (rejected, undecided or given no weight).
    pub inliers_dropped: usize,
    /// The true loops dropped by where they were lost: the verifier's reason ([`RejectionKind::key`]:
    /// `consistency`, `odometry`, `retracted`, ...), `undecided`, or `backend` (accepted, and given no
    /// weight by the back-end's robust solve).
    ///
    /// [`RejectionKind::key`]: skid_core::slots::RejectionKind::key
    pub inliers_dropped_by: BTreeMap<&'static str, usize>,
    /// Loops the verifier had not decided at the end.
    pub undecided: usize,
}

/// Milliseconds per update.
#[derive(Clone, Debug, Default, Serialize)]
pub struct UpdateTimes {
    pub updates: usize,
    pub median_ms: f64,
    pub p95_ms: f64,
    pub max_ms: f64,
}

/// Every figure of one replay.
#[derive(Clone, Debug, Serialize)]
pub struct ReplayReport {
    pub dataset: String,
    pub mode: &'static str,
    pub robots: Vec<RobotReport>,
    pub intra: LoopCounts,
    pub inter: LoopCounts,
    pub total_s: f64,
    /// Every robot's work per event (the fleet's, summed).
    pub updates: UpdateTimes,
    /// Per event, the work of the robot that spent the most on it: the update's latency, as each robot
    /// runs on its own computer and they work at once.
    pub slowest_robot_updates: UpdateTimes,
}

impl ReplayReport {
    pub fn new(problem: &ReplayProblem, outcome: &ReplayOutcome) -> Self {
        let (intra, inter) = loop_counts(problem, &outcome.loops);
        Self {
            dataset: problem.name.clone(),
            mode: match outcome.mode {
                ReplayMode::Batch => "batch",
                ReplayMode::Incremental => "incremental",
            },
            robots: robot_reports(problem, outcome),
            intra,
            inter,
            total_s: outcome.total_s,
            updates: update_times(&outcome.update_ms),
            slowest_robot_updates: update_times(&outcome.slowest_robot_update_ms),
        }
    }

    /// Labelled outliers kept, intra- and inter-robot together.
    pub fn outliers_kept(&self) -> usize {
        self.intra.outliers_kept + self.inter.outliers_kept
    }
}

fn robot_reports(problem: &ReplayProblem, outcome: &ReplayOutcome) -> Vec<RobotReport> {
    // Pairs of estimated and true positions, per robot.
    let pairs: Vec<Vec<(Vector3<f64>, Vector3<f64>)>> = problem
        .robots
        .iter()
        .zip(&outcome.estimates)
        .map(|(robot, estimate)| {
            estimate
                .iter()
                .filter_map(|(index, pose)| {
                    let truth = robot.ground_truth.get(index)?;
                    Some((pose.translation.vector, truth.translation.vector))
                })
                .collect()
        })
        .collect();
    let (source, target): (Vec<_>, Vec<_>) = pairs.iter().flatten().copied().unzip();
    let alignment = skid_eval::umeyama::umeyama(&source, &target, false).ok();
    let rmse = |pairs: &[(Vector3<f64>, Vector3<f64>)], map: &dyn Fn(&Vector3<f64>) -> Vector3<f64>| {
        if pairs.is_empty() {
            return f64::NAN;
        }
        let sum: f64 = pairs
            .iter()
            .map(|(estimate, truth)| (map(estimate) - truth).norm_squared())
            .sum();
        (sum / pairs.len() as f64).sqrt()
    };
    problem
        .robots
        .iter()
        .zip(&pairs)
        .zip(&outcome.estimates)
        .map(|((robot, pairs), estimate)| RobotReport {
            robot: robot.letter,
            keyframes: estimate.len(),
            ate_m: rmse(pairs, &|p| *p),
            ate_aligned_m: alignment.map_or(f64::NAN, |gt_from_est| {
                rmse(pairs, &|p| gt_from_est.transform_point(&(*p).into()).coords)
            }),
        })
        .collect()
}

fn loop_counts(problem: &ReplayProblem, fates: &BTreeMap<LoopId, LoopFate>) -> (LoopCounts, LoopCounts) {
    let (mut intra, mut inter) = (LoopCounts::default(), LoopCounts::default());
    for item in problem.events.iter().flat_map(|event| &event.items) {
        let Item::Loop { closure, label } = item else {
            continue;
        };
        let counts = if closure.is_inter_robot() {
            &mut inter
        } else {
            &mut intra
        };
        let fate = fates.get(&closure.id).copied().unwrap_or_default();
        counts.loops += 1;
        counts.labelled_outliers += usize::from(label.outlier);
        counts.known_inliers += usize::from(!label.potential_outlier);
        counts.accepted += usize::from(fate.accepted);
        counts.kept += usize::from(fate.kept());
        counts.undecided += usize::from(fate.undecided);
        counts.outliers_kept += usize::from(label.outlier && fate.kept());
        if !label.outlier && !fate.kept() {
            counts.inliers_dropped += 1;
            *counts.inliers_dropped_by.entry(lost_at(&fate)).or_default() += 1;
        }
    }
    (intra, inter)
}

/// Where a loop that is not kept was lost (the keys of [`LoopCounts::inliers_dropped_by`]).
fn lost_at(fate: &LoopFate) -> &'static str {
    match (fate.undecided, fate.accepted, fate.rejected_by) {
        (true, _, _) => "undecided",
        (false, true, _) => "backend",
        (false, false, Some(kind)) => kind.key(),
        (false, false, None) => "other",
    }
}

fn update_times(update_ms: &[f64]) -> UpdateTimes {
    let mut sorted = update_ms.to_vec();
    sorted.sort_by(f64::total_cmp);
    let quantile = |q: f64| {
        if sorted.is_empty() {
            return 0.0;
        }
        let position = ((sorted.len() - 1) as f64 * q).round() as usize;
        sorted[position]
    };
    UpdateTimes {
        updates: sorted.len(),
        median_ms: quantile(0.5),
        p95_ms: quantile(0.95),
        max_ms: sorted.last().copied().unwrap_or(0.0),
    }
}
