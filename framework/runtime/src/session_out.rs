//! The session a run leaves in `<run>/session/` (`skid-session`'s format): every robot's keyframes with
//! their optimised poses, odometry poses, descriptors and clouds, its pose graph, and where robot 0's
//! frame places it.

use std::path::Path;

use skid_config::PriorMode;
use skid_core::{KeyframeId, Pose};
use skid_session::{
    DescriptorSpec, JoinPart, PartClouds, RobotStanding, Session, SessionKeyframe, SessionPlacement,
    SessionRobot, place_session,
};

use crate::artifacts::g2o_vertex_id;
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

/// Keyframe `index`'s cloud of robot `robot`, in its sensor frame.
fn cloud_of(fleet: &Fleet, robot: u32, index: u32) -> Option<&[skid_core::Point]> {
    let host = fleet.robots.iter().find(|host| host.robot().0 == robot)?;
    host.keyframes().get(&index).map(|k| k.cloud.points.as_slice())
}

/// The run's session joined to the prior it extends (`[prior] mode = "extend"`): the prior's robots as
/// they were, then the run's, placed in the prior's map frame where their localisations agree
/// (`skid_session::place_session`, as a merge places a session), or kept unplaced.
fn write_extended(dir: &Path, fleet: &Fleet, session: &Session, prior: &Path) -> Result<(), RuntimeError> {
    let prior_dir = skid_session::session_folder(prior);
    let prior_session = skid_session::read_session(&prior_dir).map_err(|e| output_error(&prior_dir, e))?;
    let standings: Vec<RobotStanding> = fleet
        .robots
        .iter()
        .zip(&session.robots)
        .map(|(host, robot)| {
            let placed = host.localisation();
            RobotStanding {
                session_from_robot: robot.map_from_robot,
                base_from_robot: placed.map(|placed| placed.prior_from_map),
                loops: placed.map_or(0, |placed| placed.loops),
            }
        })
        .collect();
    let placements = match place_session(&standings) {
        SessionPlacement::Placed { robots, .. } => robots,
        SessionPlacement::NotPlaced { reason } => {
            tracing::warn!(%reason, "the run's robots are not placed in the prior they extend; kept unplaced");
            vec![None; session.robots.len()]
        }
    };
    let parts = [
        JoinPart::as_saved(&prior_session, &prior_dir),
        JoinPart {
            session,
            placements,
            clouds: PartClouds::Memory(&|robot, index| cloud_of(fleet, robot, index).map(<[_]>::to_vec)),
            // The run's graphs name the prior's keyframes as the prior peer's.
            foreign_vertices: fleet
                .prior
                .iter()
                .flat_map(|prior| &prior.keyframes)
                .map(|keyframe| {
                    (
                        g2o_vertex_id(keyframe.id),
                        g2o_vertex_id(KeyframeId::new(keyframe.session_robot, keyframe.session_index)),
                    )
                })
                .collect(),
        },
    ];
    skid_session::write_joined(dir, &session.name, &parts).map_err(|e| output_error(dir, e))?;
    Ok(())
}

/// Writes the fleet's session into `<folder>/session/`; a run extending its prior writes the prior grown
/// by the run.
pub(crate) fn write_session(
    folder: &Path,
    fleet: &Fleet,
    frames: &[Option<Pose>],
) -> Result<(), RuntimeError> {
    let session = fleet_session(fleet, frames)?;
    let dir = folder.join("session");
    match &fleet.config.prior.path {
        Some(prior) if fleet.config.prior.mode == PriorMode::Extend => {
            write_extended(&dir, fleet, &session, prior)
        }
        _ => skid_session::write_session(&dir, &session, |robot, index| cloud_of(fleet, robot, index))
            .map_err(|e| output_error(&dir, e)),
    }
}
