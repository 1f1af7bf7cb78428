//! The run's `metrics.json`: each robot's ATE and ARE after SE(3) Umeyama alignment, the paper's α/β
//! multi-robot alignment metric for every other robot against robot 0 (α), what became of the loop
//! candidates (accepted, rejected, undecided, failed registration; they add up), and the bytes each robot sent per message kind.
//!
//! The α/β metric (SKiD-SLAM paper, "Multi-Robot Alignment Error") needs `T^α_β`, the estimate of β's
//! map frame in α's: robot α's distributed back-end holds the β keyframes its inter-robot loops touch,
//! so `T^α_β` is the SE(3) Umeyama fit of those poses in α's graph onto the same keyframes' poses in β's
//! own estimate. A robot α never closed a loop with is placed through the robots that did, when α has
//! joined it through them (their reported frames composed, see `RobotHost::joined_frames`): `T^α_β` is
//! then α's first keyframe composed with the joined frame and β's own first keyframe, and the entry names
//! the robot it came through. A robot α cannot place at all has no `T^α_β`; its entry says so.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::Serialize;
use skid_core::slots::LoopClosure;
use skid_core::{KeyframeId, Pose};
use skid_eval::{
    AlignmentConditioning, AlignmentKind, AlphaBetaInput, ErrorStats, MEETING_RADIUS_M, MeetingError,
    RpeOptions, TransformError, alignment_conditioning, alpha_beta, anchored_frame_error, ape,
    meeting_frame_error, meeting_with_fleet, rpe, umeyama,
};

use crate::host::{LoopStats, RobotHost};
use crate::loop_truth::{LoopTruth, keyframe_truths, loop_truth};

/// Absolute errors of one robot's trajectory after its own SE(3) alignment.
#[derive(Clone, Debug, Serialize)]
pub struct TrajectoryMetrics {
    pub poses: usize,
    /// The length of the ground-truth path (`summary.json` gives the estimate's).
    pub ground_truth_path_length_m: f64,
    /// ATE: position errors, metres.
    pub ate_m: ErrorStats,
    /// ARE: rotation errors, degrees; not meaningful when `alignment_conditioning.ill_conditioned`.
    pub are_deg: ErrorStats,
    /// ATE RMSE as a percentage of the ground-truth path length.
    pub ate_percent_of_path: f64,
    /// Whether the SE(3) alignment fixes its rotation (not on a nearly straight path).
    pub alignment_conditioning: AlignmentConditioning,
    /// Rotation error between consecutive poses (RPE, Δ = 1 pose), which needs no alignment, degrees.
    pub rpe_rotation_deg: Option<ErrorStats>,
}

/// One stretch of time over which α placed β at one frame hypothesis.
#[derive(Clone, Debug, Serialize)]
pub struct PlacementRecord {
    /// Seconds of robot time from α's first scan.
    pub from_s: f64,
    /// `None` while it stands at the end.
    pub until_s: Option<f64>,
    /// The frame's error against the truth at the two robots' first poses
    /// (`skid_eval::anchored_frame_error`), which carries the odometry's drift to where the frame
    /// was found.
    pub frame_error: TransformError,
}

/// The α/β metric for one robot β against α = robot 0.
#[derive(Clone, Debug, Serialize)]
pub struct AlignmentMetrics {
    pub alpha: u32,
    /// β keyframes in α's graph used to estimate `T^α_β` (0 when joined through another robot).
    pub shared_keyframes: usize,
    /// The robot through which α placed β, when α holds no loop with β.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joined_via: Option<u32>,
    /// Seconds of robot time from α's first scan to when α first placed β in its frame (which may be
    /// a placement withdrawn later: see `placements`).
    pub joined_after_s: Option<f64>,
    /// Seconds of robot time from α's first scan to when the placement that stands at the end began:
    /// the time to the merge the run ends with. `None` when β is not placed at the end.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placed_since_s: Option<f64>,
    /// Every placement of β in α's frame over the run, oldest first, each judged against the truth at
    /// the two robots' first poses (a frame that jumped by more than 2 m or 5°, or a merge withdrawn,
    /// ends one).
    pub placements: Vec<PlacementRecord>,
    /// `T_β,APE = (T^GT_β)⁻¹ · T^GT_α · T^α_β`.
    pub beta_alignment_error: TransformError,
    /// β's frame in α's against the truth at the two robots' first poses: defined on straight routes,
    /// where `T_β,APE`'s rotation is not (the aliasing benchmark judges a merge by it there).
    pub anchored_frame_error: TransformError,
    /// β's placement judged where the robots met (within 10 m of each other in truth): the median error
    /// of the relative poses between them in the merged map, free of the drift the two measures above
    /// carry; absent when the robots never met. The aliasing benchmark judges merges by it.
    pub meeting_frame_error: Option<MeetingError>,
    /// The same where β met any robot placed in α's frame (α or others, each through its own frame):
    /// for robots that joined through others and never met α.
    pub fleet_meeting_frame_error: Option<MeetingError>,
    /// The translation of `T_β,APE` as a percentage of β's path length.
    pub beta_alignment_percent_of_path: f64,
    /// β's trajectory placed through α's alignment, against β's ground truth: metres and degrees.
    pub beta_in_alpha_ate_m: ErrorStats,
    pub beta_in_alpha_are_deg: ErrorStats,
}

/// What one robot did and how well.
#[derive(Clone, Debug, Serialize)]
pub struct RobotMetrics {
    pub robot: u32,
    pub scans: usize,
    pub keyframes: usize,
    /// `None` when the source gives no ground truth.
    pub trajectory: Option<TrajectoryMetrics>,
    /// For robots other than α: the α/β metric, or why it could not be computed.
    pub alignment: Option<AlignmentMetrics>,
    pub alignment_unavailable: Option<String>,
    pub loops: LoopStats,
    /// The loops this robot's graph holds at the end, judged against the ground truth.
    pub loops_against_truth: LoopTruth,
    pub bytes_sent_by_kind: BTreeMap<String, u64>,
    pub bytes_sent_total: u64,
}

/// The whole `metrics.json`.
#[derive(Clone, Debug, Serialize)]
pub struct RunMetrics {
    pub name: String,
    pub robots: Vec<RobotMetrics>,
    /// Inter-robot loop candidates from place recognition (each robot's `loops` says what became of them).
    pub inter_robot_candidates: usize,
    /// Inter-robot loops in the robots' graphs at the end.
    pub inter_robot_loops_accepted: usize,
    /// Loops (intra- and inter-robot) the verifiers refused or retracted, and those still undecided.
    pub loops_rejected: usize,
    pub loops_undecided: usize,
    /// False loops (past 2 m or 5° from the truth) over every robot's graph; a loop two graphs hold
    /// counts in each.
    pub false_loops_in_graphs: usize,
    pub bytes_sent_total: u64,
    /// Robots other than α that α placed in its frame (directly or through others).
    pub robots_in_alpha_frame: usize,
    /// Bytes of keyframe clouds sent by every robot per inter-robot loop accepted: what a loop costs
    /// the links (`None` without an accepted loop).
    pub cloud_bytes_per_inter_loop: Option<f64>,
}

/// Pairs of (ground truth, estimate) for every scan that has ground truth.
pub(crate) fn associated(host: &RobotHost) -> (Vec<Pose>, Vec<Pose>) {
    host.optimised_trajectory()
        .iter()
        .zip(host.scans())
        .filter_map(|((_, estimate), scan)| scan.ground_truth.map(|truth| (truth, *estimate)))
        .unzip()
}

fn path_length_m(poses: &[Pose]) -> f64 {
    poses
        .windows(2)
        .map(|pair| (pair[1].translation.vector - pair[0].translation.vector).norm())
        .sum()
}

fn trajectory_metrics(truth: &[Pose], estimate: &[Pose]) -> Result<TrajectoryMetrics, String> {
    let result = ape(truth, estimate, AlignmentKind::Se3).map_err(|e| e.to_string())?;
    let path_length_m = path_length_m(truth);
    let rpe_rotation_deg = rpe(truth, estimate, &RpeOptions::default())
        .ok()
        .map(|rpe| rpe.rotation_deg);
    Ok(TrajectoryMetrics {
        poses: truth.len(),
        ground_truth_path_length_m: path_length_m,
        ate_percent_of_path: 100.0 * result.translation_m.rmse / path_length_m.max(f64::MIN_POSITIVE),
        ate_m: result.translation_m,
        are_deg: result.rotation_deg,
        alignment_conditioning: alignment_conditioning(truth),
        rpe_rotation_deg,
    })
}

/// `T^α_β` from the β keyframes α's back-end holds, with how many there were.
pub fn alpha_from_beta(alpha: &RobotHost, beta: &RobotHost) -> Result<(Pose, usize), String> {
    let graph = alpha
        .backend_graph()
        .ok_or("robot α has no back-end, so it holds no estimate of β's frame")?;
    // β's keyframes stay in α's back-end after every loop between them was retracted (a merge
    // withdrawn); they place β nowhere then. The fleet's loops in α's graph that touch β place it too
    // (`loops.fleet_loops`: a loop between β and a robot α placed).
    let touches_beta =
        |closure: &LoopClosure| closure.target.robot == beta.robot() || closure.source.robot == beta.robot();
    let merged = alpha.accepted_loops().values().any(touches_beta)
        || alpha.fleet_loops_in_graph().iter().any(touches_beta);
    if !merged {
        return Err(format!(
            "{} accepted no loop with {} (or withdrew every one)",
            alpha.robot(),
            beta.robot()
        ));
    }
    let (in_alpha, in_beta): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = beta
        .keyframes()
        .keys()
        .filter_map(|&index| {
            let id = KeyframeId {
                robot: beta.robot(),
                index,
            };
            let seen_by_alpha = graph.pose(id)?;
            let own = beta.keyframe_pose(index)?;
            Some((seen_by_alpha.translation.vector, own.translation.vector))
        })
        .unzip();
    if in_alpha.is_empty() {
        return Err(format!(
            "{} accepted no loop with {}",
            alpha.robot(),
            beta.robot()
        ));
    }
    let fit = umeyama(&in_beta, &in_alpha, false).map_err(|e| e.to_string())?;
    Ok((fit.isometry, in_alpha.len()))
}

/// `T^α_β` and the number of shared keyframes for every robot, robot 0 being α (identity, all its
/// keyframes), or why it is unknown. Computed once per run for both metrics.json and the map frames.
pub fn alpha_frames(robots: &[RobotHost]) -> Vec<Result<(Pose, usize), String>> {
    let Some(alpha) = robots.first() else {
        return Vec::new();
    };
    robots
        .iter()
        .map(|robot| {
            if robot.robot() == alpha.robot() {
                Ok((Pose::identity(), robot.keyframes().len()))
            } else {
                alpha_from_beta(alpha, robot).or_else(|direct| {
                    alpha_from_beta_through_others(alpha, robot)
                        .map(|frame| (frame, 0))
                        .ok_or(direct)
                })
            }
        })
        .collect()
}

/// `T^α_β` when α placed β only through other robots' reported frames: α's first keyframe in its own
/// graph, then the joined frame, then β's first keyframe in β's own estimate, inverted.
fn alpha_from_beta_through_others(alpha: &RobotHost, beta: &RobotHost) -> Option<Pose> {
    let joined = alpha.joined_frames().get(&beta.robot()).copied()?;
    joined.via?;
    let alpha_first = alpha.backend_graph()?.pose(KeyframeId {
        robot: alpha.robot(),
        index: 0,
    })?;
    let beta_first = beta.keyframe_pose(0)?;
    Some(alpha_first * joined.own_first_from_robot_first * beta_first.inverse())
}

/// What every robot's metrics read, computed once per run: the hosts, their frames in α's
/// ([`alpha_frames`]), their (ground truth, estimate) poses, and the estimates moved into α's frame
/// where α placed the robot.
struct Fleet<'a> {
    robots: &'a [RobotHost],
    frames: &'a [Result<(Pose, usize), String>],
    tracks: Vec<(Vec<Pose>, Vec<Pose>)>,
    in_alpha: Vec<Option<Vec<Pose>>>,
}

impl<'a> Fleet<'a> {
    fn new(robots: &'a [RobotHost], frames: &'a [Result<(Pose, usize), String>]) -> Self {
        let tracks: Vec<(Vec<Pose>, Vec<Pose>)> = robots.iter().map(associated).collect();
        let in_alpha = tracks
            .iter()
            .zip(frames)
            .map(|((_, estimate), frame)| {
                let (alpha_from_robot, _) = frame.as_ref().ok()?;
                Some(estimate.iter().map(|pose| alpha_from_robot * pose).collect())
            })
            .collect();
        Self {
            robots,
            frames,
            tracks,
            in_alpha,
        }
    }
}

fn alignment_metrics(fleet: &Fleet<'_>, beta_index: usize) -> Result<AlignmentMetrics, String> {
    let (alpha, beta) = (&fleet.robots[0], &fleet.robots[beta_index]);
    let (alpha_from_beta, shared_keyframes) = fleet.frames[beta_index].clone()?;
    let (gt_alpha, est_alpha) = &fleet.tracks[0];
    let (gt_beta, est_beta) = &fleet.tracks[beta_index];
    let result = alpha_beta(
        &AlphaBetaInput {
            gt_alpha,
            est_alpha,
            gt_beta,
            est_beta,
            alpha_from_beta,
        },
        AlignmentKind::Se3,
    )
    .map_err(|e| e.to_string())?;
    let anchored_frame_error = match (
        gt_alpha.first(),
        est_alpha.first(),
        gt_beta.first(),
        est_beta.first(),
    ) {
        (Some(gt_a), Some(est_a), Some(gt_b), Some(est_b)) => {
            anchored_frame_error((gt_a, est_a), (gt_b, est_b), &alpha_from_beta)
        }
        _ => return Err("no pose with ground truth to anchor the frames".to_owned()),
    };
    let meeting_frame_error = meeting_frame_error(
        (gt_alpha, est_alpha),
        (gt_beta, est_beta),
        &alpha_from_beta,
        MEETING_RADIUS_M,
    );
    // Every other robot placed in α's frame, with its estimates in that frame.
    let placed: Vec<(&[Pose], &[Pose])> = fleet
        .tracks
        .iter()
        .zip(&fleet.in_alpha)
        .enumerate()
        .filter(|&(index, _)| index != beta_index)
        .filter_map(|(_, ((truth, _), in_alpha))| Some((&truth[..], &in_alpha.as_ref()?[..])))
        .collect();
    let fleet_meeting_frame_error =
        meeting_with_fleet(&placed, (gt_beta, est_beta), &alpha_from_beta, MEETING_RADIUS_M);
    let beta_path_m = path_length_m(gt_beta).max(f64::MIN_POSITIVE);
    // Through another robot's frames (no β keyframes in α's graph) or through the fleet's loops (β's
    // keyframes there, placed by loops between β and others).
    let joined_via = alpha
        .joined_frames()
        .get(&beta.robot())
        .and_then(|joined| joined.via)
        .map(|via| via.0);
    let alpha_start_nanos = alpha.scans().first().map(|scan| scan.stamp_nanos);
    let since_start_s = |nanos: u64| alpha_start_nanos.map(|start| nanos.saturating_sub(start) as f64 * 1e-9);
    let history = alpha
        .placements()
        .get(&beta.robot())
        .map(Vec::as_slice)
        .unwrap_or_default();
    let joined_after_s = history
        .first()
        .and_then(|placement| since_start_s(placement.since_nanos));
    let placed_since_s = history
        .last()
        .filter(|placement| placement.until_nanos.is_none())
        .and_then(|placement| since_start_s(placement.since_nanos));
    let placements = match (gt_alpha.first(), gt_beta.first()) {
        (Some(gt_a), Some(gt_b)) => history
            .iter()
            .filter_map(|placement| {
                Some(PlacementRecord {
                    from_s: since_start_s(placement.since_nanos)?,
                    until_s: placement.until_nanos.and_then(since_start_s),
                    // The frame joins the first keyframes, whose estimates are each robot's origin.
                    frame_error: skid_eval::anchored_frame_error(
                        (gt_a, &Pose::identity()),
                        (gt_b, &Pose::identity()),
                        &placement.own_first_from_robot_first,
                    ),
                })
            })
            .collect(),
        _ => Vec::new(),
    };
    Ok(AlignmentMetrics {
        alpha: alpha.robot().0,
        shared_keyframes,
        joined_via,
        joined_after_s,
        placed_since_s,
        placements,
        beta_alignment_percent_of_path: 100.0 * result.beta_alignment_error.translation_m / beta_path_m,
        beta_alignment_error: result.beta_alignment_error,
        anchored_frame_error,
        meeting_frame_error,
        fleet_meeting_frame_error,
        beta_in_alpha_ate_m: result.beta_in_alpha.translation_m,
        beta_in_alpha_are_deg: result.beta_in_alpha.rotation_deg,
    })
}

fn robot_metrics(fleet: &Fleet<'_>, truths: &BTreeMap<KeyframeId, Pose>, index: usize) -> RobotMetrics {
    let host = &fleet.robots[index];
    let (truth, estimate) = &fleet.tracks[index];
    let trajectory = if truth.len() >= 3 {
        trajectory_metrics(truth, estimate)
            .map_err(|reason| tracing::warn!(robot = %host.robot(), %reason, "no ATE"))
            .ok()
    } else {
        None
    };
    let (alignment, alignment_unavailable) = match index {
        0 => (None, None),
        _ => match alignment_metrics(fleet, index) {
            Ok(metrics) => (Some(metrics), None),
            Err(reason) => (None, Some(reason)),
        },
    };
    let counters = host.protocol().counters().snapshot();
    let bytes_sent_by_kind: BTreeMap<String, u64> = counters
        .sent
        .iter()
        .map(|(kind, tally)| (kind.clone(), tally.bytes))
        .collect();
    RobotMetrics {
        robot: host.robot().0,
        scans: host.scans().len(),
        keyframes: host.keyframes().len(),
        trajectory,
        alignment,
        alignment_unavailable,
        loops: host.loop_stats(),
        loops_against_truth: loop_truth(host, truths),
        bytes_sent_total: counters.sent_total.bytes,
        bytes_sent_by_kind,
    }
}

impl RunMetrics {
    /// Computes every robot's metrics; robot 0 is α.
    pub fn of(name: &str, robots: &[RobotHost]) -> Self {
        Self::with_frames(name, robots, &alpha_frames(robots))
    }

    /// [`RunMetrics::of`] with the frames of [`alpha_frames`] already computed.
    pub fn with_frames(name: &str, robots: &[RobotHost], frames: &[Result<(Pose, usize), String>]) -> Self {
        let fleet = Fleet::new(robots, frames);
        let truths = keyframe_truths(robots);
        let robots_metrics: Vec<RobotMetrics> = (0..robots.len().min(frames.len()))
            .map(|index| robot_metrics(&fleet, &truths, index))
            .collect();
        let cloud_bytes: u64 = robots_metrics
            .iter()
            .filter_map(|r| r.bytes_sent_by_kind.get("cloud"))
            .sum();
        let accepted: usize = robots_metrics.iter().map(|r| r.loops.accepted_inter).sum();
        Self {
            name: name.to_owned(),
            robots_in_alpha_frame: robots_metrics.iter().filter(|r| r.alignment.is_some()).count(),
            cloud_bytes_per_inter_loop: (accepted > 0).then(|| cloud_bytes as f64 / accepted as f64),
            inter_robot_candidates: robots_metrics.iter().map(|r| r.loops.candidates_inter).sum(),
            inter_robot_loops_accepted: robots_metrics.iter().map(|r| r.loops.accepted_inter).sum(),
            loops_rejected: robots_metrics.iter().map(|r| r.loops.rejected).sum(),
            loops_undecided: robots_metrics.iter().map(|r| r.loops.undecided).sum(),
            false_loops_in_graphs: robots_metrics
                .iter()
                .map(|r| r.loops_against_truth.false_loops)
                .sum(),
            bytes_sent_total: robots_metrics.iter().map(|r| r.bytes_sent_total).sum(),
            robots: robots_metrics,
        }
    }
}
