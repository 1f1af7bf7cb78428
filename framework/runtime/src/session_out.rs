//! The session a run leaves in `<run>/session/` (`skid-session`'s format): every robot's keyframes with
//! their optimised poses, odometry poses, descriptors and clouds, its pose graph, and where robot 0's
//! frame places it.

use std::path::Path;

use skid_core::Pose;
use skid_session::{DescriptorSpec, Session, SessionKeyframe, SessionRobot};

use crate::error::{RuntimeError, output_error};
use crate::fleet::Fleet;
use crate::host::RobotHost;

fn robot_session(robot: &RobotHost, map_from_robot: Option<Pose>) -> SessionRobot {
    let descriptors = robot.own_descriptors();
    let truth: std::collections::BTreeMap<u64, Pose> = robot
        .scans()
        .iter()
        .filter_map(|scan| Some((scan.stamp_nanos, scan.ground_truth?)))
        .collect();
    let keyframes = robot
        .keyframes()
        .iter()
        .map(|(&index, keyframe)| SessionKeyframe {
            index,
            stamp_nanos: keyframe.stamp_nanos,
            map_from_sensor: robot.keyframe_pose(index).unwrap_or(keyframe.world_from_sensor),
            odometry_from_sensor: keyframe.world_from_sensor,
            ground_truth: truth.get(&keyframe.stamp_nanos).copied(),
            point_count: keyframe.cloud.len(),
            descriptor: descriptors.get(&index).map(|d| d.values.clone()),
        })
        .collect();
    SessionRobot {
        robot: robot.robot().0,
        map_from_robot,
        keyframes,
        graph: crate::artifacts::pose_graph(robot),
    }
}

/// The fleet's session: `frames` places each robot's map in robot 0's.
fn fleet_session(fleet: &Fleet, frames: &[Option<Pose>]) -> Result<Session, RuntimeError> {
    let config = &fleet.config;
    let length = fleet
        .robots
        .iter()
        .find_map(|robot| robot.own_descriptors().values().next())
        .map(|d| d.values.len());
    let descriptor = match (fleet.robots.first().and_then(RobotHost::descriptor_kind), length) {
        (Some(kind), Some(length)) => Some(DescriptorSpec {
            kind,
            params: crate::prior::descriptor_params(config).map_err(|e| {
                output_error(
                    Path::new("session/session.json"),
                    format!("the descriptor's parameters cannot be written as JSON: {e}"),
                )
            })?,
            length,
        }),
        _ => None,
    };
    Ok(Session {
        name: config.run.name.clone(),
        skid_version: env!("CARGO_PKG_VERSION").to_string(),
        descriptor,
        config_toml: config.to_toml_string(),
        robots: fleet
            .robots
            .iter()
            .zip(frames.iter().copied().chain(std::iter::repeat(None)))
            .map(|(robot, frame)| robot_session(robot, frame))
            .collect(),
    })
}

/// Writes the fleet's session into `<folder>/session/`.
pub(crate) fn write_session(
    folder: &Path,
    fleet: &Fleet,
    frames: &[Option<Pose>],
) -> Result<(), RuntimeError> {
    let session = fleet_session(fleet, frames)?;
    let dir = folder.join("session");
    skid_session::write_session(&dir, &session, |robot, index| {
        let host = fleet.robots.iter().find(|host| host.robot().0 == robot)?;
        host.keyframes().get(&index).map(|k| k.cloud.points.as_slice())
    })
    .map_err(|e| output_error(&dir, e))
}
