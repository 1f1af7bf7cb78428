//! What `summary.json` says of each robot's place in a prior map (`[prior]`): whether the verifier
//! granted it a set of loops with the prior, when and how far into its route that first happened, where
//! the loops place its map frame in the prior's, and, when both the prior and the robot know their
//! ground truth, how far that placement is from the truth along the robot's keyframes since the fix
//! (median position and rotation error: the measure a false fix, more than 2 m or 5°, is judged by).

use serde::Serialize;
use skid_core::Pose;

use crate::host::RobotHost;
use crate::prior::{PriorMap, is_prior_robot};

/// One robot's standing in the prior map.
#[derive(Clone, Debug, Serialize)]
pub struct LocalisationSummary {
    /// True once the verifier granted loops with the prior (and still holds them at the end).
    pub localised: bool,
    /// The prior session's robot that recorded most of the keyframes its loops join.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub through_session_robot: Option<u32>,
    /// Accepted loops with the prior.
    pub loops: usize,
    /// The fleet robot whose reported frames place this one, when it holds no loop with the prior.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub via_robot: Option<u32>,
    /// Seconds from the robot's first scan to its first granted loop set with the prior.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_fix_s: Option<f64>,
    /// Metres of its optimised path driven before the first fix.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_fix_distance_m: Option<f64>,
    /// The robot's map frame in the prior's map frame: translation (m) and rotation (x, y, z, w).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior_from_map: Option<([f64; 3], [f64; 4])>,
    /// Against the ground truth (prior and robot both): median position error of the robot's keyframes
    /// since the fix placed in the prior's frame, metres, and median rotation error, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_deg: Option<f64>,
}

/// Where the prior's map frame sits in the world of its ground truth.
fn world_from_prior(prior: &PriorMap) -> Option<Pose> {
    skid_session::world_from_map_pairs(
        prior
            .keyframes
            .iter()
            .filter_map(|k| Some((k.session_from_sensor, k.ground_truth?))),
    )
}

/// The robot's standing in `prior`.
pub fn summarise(host: &RobotHost, prior: &PriorMap) -> LocalisationSummary {
    let placed = host.localisation();
    let first_fix_nanos = host
        .first_joined_nanos()
        .iter()
        .filter(|(robot, _)| is_prior_robot(**robot))
        .map(|(_, &nanos)| nanos)
        .min();
    let first_scan_nanos = host.scans().first().map(|scan| scan.stamp_nanos);
    let trajectory = host.optimised_trajectory();
    let first_fix_distance_m = first_fix_nanos.map(|fix| {
        trajectory
            .windows(2)
            .take_while(|pair| pair[1].0 <= fix)
            .map(|pair| (pair[1].1.translation.vector - pair[0].1.translation.vector).norm())
            .sum()
    });
    let mut summary = LocalisationSummary {
        localised: placed.is_some(),
        through_session_robot: placed.as_ref().and_then(|p| p.session_robot),
        loops: placed.map_or(0, |p| p.loops),
        via_robot: placed.and_then(|p| p.via).map(|robot| robot.0),
        first_fix_s: first_fix_nanos
            .zip(first_scan_nanos)
            .map(|(fix, first)| fix.saturating_sub(first) as f64 * 1e-9),
        first_fix_distance_m,
        prior_from_map: placed.map(|p| {
            let q = p.prior_from_map.rotation.coords;
            (p.prior_from_map.translation.vector.into(), [q.x, q.y, q.z, q.w])
        }),
        error_m: None,
        error_deg: None,
    };
    let (Some(placed), Some(world_from_prior)) = (placed, world_from_prior(prior)) else {
        return summary;
    };
    let since = first_fix_nanos.unwrap_or(0);
    let placed_against_truth = host
        .scans()
        .iter()
        .filter(|scan| scan.stamp_nanos >= since)
        .filter_map(|scan| {
            let (truth, index) = (scan.ground_truth?, scan.keyframe?);
            let keyframe = host.keyframes().get(&index)?;
            if keyframe.stamp_nanos != scan.stamp_nanos {
                return None;
            }
            let estimate = host.keyframe_pose(index)?;
            Some((world_from_prior * placed.prior_from_map * estimate, truth))
        });
    if let Some((metres, degrees)) = skid_session::median_errors(placed_against_truth) {
        summary.error_m = Some(metres);
        summary.error_deg = Some(degrees);
    }
    summary
}
