//! The run's summary: per robot what was read, estimated and exchanged, and how long each stage took.

use std::collections::BTreeMap;

use serde::Serialize;
use skid_core::slots::NetworkTotals;
use skid_core::{Pose, Slot};
use skid_protocol::CountersSnapshot;

use crate::fleet::Fleet;
use crate::host::{CloudServing, LoopStats, RobotHost};

/// What one robot did.
#[derive(Clone, Debug, Serialize)]
pub struct RobotSummary {
    pub robot: u32,
    /// Scans the odometry registered; `scans_read` counts those read, `scans_skipped` those it refused.
    pub scans: usize,
    pub scans_read: usize,
    pub scans_skipped: u64,
    /// Registered scans whose geometry left a direction of the motion to the odometry's prior or IMU
    /// (expected on open ground and in long corridors; 0 for odometries that cannot tell).
    pub degenerate_scans: u64,
    pub keyframes: usize,
    pub mean_points_per_scan: f64,
    /// Total milliseconds spent per stage.
    pub stage_ms: BTreeMap<String, f64>,
    pub loops: LoopStats,
    /// The length of the optimised trajectory (`metrics.json` gives the ground truth's).
    pub estimated_path_length_m: f64,
    /// RMSE of position of the optimised trajectory after aligning the first poses, when ground truth
    /// exists (the evaluation crate adds Umeyama-aligned ATE/ARE and the α/β metric).
    pub ate_first_pose_aligned_m: Option<f64>,
    pub messages: CountersSnapshot,
    /// What the robot did with its peers' requests for its keyframe clouds (each sent once per peer).
    pub clouds_served: CloudServing,
    /// Peer clouds that arrived while a copy was held already (the link carried that cloud twice).
    pub clouds_received_again: u64,
    /// Messages the transport refused before the protocol saw them (see `Transport::refusals`).
    pub transport_refusals: BTreeMap<String, u64>,
    /// Well-formed peer messages the robot refused, by class (see `peer_faults.rs`).
    pub peer_faults: BTreeMap<String, u64>,
    /// The robots this robot has placed in its frame at the end: those it merged with (it holds accepted
    /// loops with them) and those joined through them, each with where that robot's first keyframe sits
    /// in the frame of this robot's first keyframe.
    pub merged_with: Vec<MergedFrame>,
    /// Its standing in the prior map, when the run has one (`[prior]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub localisation: Option<crate::localisation::LocalisationSummary>,
}

/// A merged robot's frame as one robot holds it.
#[derive(Clone, Debug, Serialize)]
pub struct MergedFrame {
    pub robot: u32,
    /// This robot's accepted loops with it (0 when joined through another robot).
    pub loops: u32,
    /// The robot whose reported frame placed it, when this robot holds no loop with it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub via: Option<u32>,
    /// Translation in metres and rotation as a unit quaternion (x, y, z, w).
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

/// The summary of a whole run.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub name: String,
    /// The SKiD version and the commit it was built from (`None` outside a git work tree; `-dirty` when
    /// tracked files had changes).
    pub skid_version: &'static str,
    pub skid_commit: Option<&'static str>,
    pub robots: Vec<RobotSummary>,
    pub wall_s: f64,
    pub slots: BTreeMap<String, String>,
    /// What the simulated network did with the messages; absent on a real network.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub network: Option<NetworkTotals>,
    /// Why the run stopped before its sources ended (a signal, a plugin error); absent for a complete
    /// run. The outputs of an interrupted run hold what existed at the stop.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interrupted: Option<String>,
}

impl RunSummary {
    pub fn of(fleet: &Fleet, wall_s: f64) -> Self {
        Self {
            name: fleet.config.run.name.clone(),
            skid_version: env!("CARGO_PKG_VERSION"),
            skid_commit: option_env!("SKID_GIT_COMMIT"),
            robots: fleet
                .robots
                .iter()
                .map(|host| RobotSummary {
                    localisation: fleet
                        .prior
                        .as_deref()
                        .map(|prior| crate::localisation::summarise(host, prior)),
                    ..robot_summary(host)
                })
                .collect(),
            wall_s,
            slots: Slot::ALL
                .iter()
                .map(|&slot| (slot.key().to_owned(), fleet.config.slot(slot).plugin.clone()))
                .collect(),
            network: fleet.network.as_ref().map(|network| network.totals()),
            interrupted: None,
        }
    }

    /// The summary of a run that stopped early for `reason`, from the robots' state at the stop.
    pub fn interrupted(fleet: &Fleet, wall_s: f64, reason: &str) -> Self {
        Self {
            interrupted: Some(reason.to_owned()),
            ..Self::of(fleet, wall_s)
        }
    }
}

fn robot_summary(host: &RobotHost) -> RobotSummary {
    let trajectory = host.optimised_trajectory();
    let path_length_m = trajectory
        .windows(2)
        .map(|p| (p[1].1.translation.vector - p[0].1.translation.vector).norm())
        .sum();
    let truth: Vec<Option<Pose>> = host.scans().iter().map(|s| s.ground_truth).collect();
    RobotSummary {
        robot: host.robot().0,
        scans: host.scans().len(),
        scans_read: host.scans_read(),
        scans_skipped: host.scans_skipped(),
        degenerate_scans: host.degenerate_scans(),
        keyframes: host.keyframes().len(),
        mean_points_per_scan: if host.scans().is_empty() {
            0.0
        } else {
            host.points_read() as f64 / host.scans().len() as f64
        },
        stage_ms: host
            .stage_ms()
            .iter()
            .map(|(k, v)| ((*k).to_owned(), *v))
            .collect(),
        loops: host.loop_stats(),
        clouds_served: host.cloud_serving(),
        clouds_received_again: host.clouds_received_again(),
        estimated_path_length_m: path_length_m,
        ate_first_pose_aligned_m: ate_first_pose_aligned(&trajectory, &truth),
        messages: host.protocol().counters().snapshot(),
        transport_refusals: host
            .transport()
            .map(|transport| transport.refusals())
            .unwrap_or_default(),
        peer_faults: host.peer_faults().snapshot(),
        merged_with: host
            .joined_frames()
            .iter()
            .map(|(robot, joined)| {
                let frame = &joined.own_first_from_robot_first;
                MergedFrame {
                    robot: robot.0,
                    loops: joined.loops,
                    via: joined.via.map(|via| via.0),
                    translation_m: frame.translation.vector.into(),
                    rotation_xyzw: frame.rotation.coords.into(),
                }
            })
            .collect(),
        localisation: None,
    }
}

fn ate_first_pose_aligned(trajectory: &[(u64, Pose)], truth: &[Option<Pose>]) -> Option<f64> {
    let pairs: Vec<(Pose, Pose)> = trajectory
        .iter()
        .zip(truth)
        .filter_map(|((_, e), t)| t.map(|t| (*e, t)))
        .collect();
    let (first_estimate, first_truth) = pairs.first()?;
    let truth_from_estimate = first_truth * first_estimate.inverse();
    let sum_sq: f64 = pairs
        .iter()
        .map(|(e, t)| ((truth_from_estimate * e).translation.vector - t.translation.vector).norm_squared())
        .sum();
    Some((sum_sq / pairs.len() as f64).sqrt())
}
