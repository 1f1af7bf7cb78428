//! A summary of a session, for `skid session info`: per robot its keyframes, points, path, loops and
//! whether it is placed in the session's map frame, and the session's size on disk.

use std::path::Path;

use serde::Serialize;

use crate::{Session, SessionError};

/// One robot's part of a session, summarised.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RobotInfo {
    pub robot: u32,
    pub keyframes: usize,
    /// Keyframes with a descriptor.
    pub described: usize,
    /// Points in all its keyframe clouds.
    pub points: usize,
    /// The length of the path through its keyframes' optimised poses, metres.
    pub path_length_m: f64,
    /// Time from its first keyframe to its last, seconds.
    pub duration_s: f64,
    /// Loop edges in its pose graph (edges other than one keyframe to the next of the same robot).
    pub loops: usize,
    /// Other robots whose keyframes its pose graph holds.
    pub peers_in_graph: Vec<u32>,
    /// Whether its map frame is placed in the session's.
    pub placed: bool,
}

/// A session, summarised.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SessionInfo {
    pub name: String,
    pub skid_version: String,
    /// The descriptor kind and length, when the keyframes were described.
    pub descriptor: Option<(String, usize)>,
    pub robots: Vec<RobotInfo>,
    /// Bytes of every file in the session folder.
    pub bytes_on_disk: u64,
}

fn folder_bytes(dir: &Path) -> Result<u64, SessionError> {
    let mut total = 0;
    for entry in std::fs::read_dir(dir).map_err(|e| SessionError::io(dir, e))? {
        let entry = entry.map_err(|e| SessionError::io(dir, e))?;
        let meta = entry.metadata().map_err(|e| SessionError::io(entry.path(), e))?;
        total += if meta.is_dir() {
            folder_bytes(&entry.path())?
        } else {
            meta.len()
        };
    }
    Ok(total)
}

/// The robot a g2o vertex id belongs to (`robot · 10⁶ + index`) and its index.
fn split_vertex_id(id: u64) -> (u64, u64) {
    (id / 1_000_000, id % 1_000_000)
}

impl SessionInfo {
    /// Summarises `session`, read from the folder `dir`.
    pub fn of(session: &Session, dir: &Path) -> Result<Self, SessionError> {
        let robots = session
            .robots
            .iter()
            .map(|robot| {
                let path_length_m = robot
                    .keyframes
                    .windows(2)
                    .map(|pair| {
                        (pair[1].map_from_sensor.translation.vector
                            - pair[0].map_from_sensor.translation.vector)
                            .norm()
                    })
                    .sum();
                let duration_s = match (robot.keyframes.first(), robot.keyframes.last()) {
                    (Some(first), Some(last)) => {
                        last.stamp_nanos.saturating_sub(first.stamp_nanos) as f64 * 1e-9
                    }
                    _ => 0.0,
                };
                let loops = robot
                    .graph
                    .edges
                    .iter()
                    .filter(|edge| {
                        let (from, to) = (split_vertex_id(edge.from), split_vertex_id(edge.to));
                        from.0 != to.0 || to.1 != from.1 + 1
                    })
                    .count();
                let mut peers: Vec<u32> = robot
                    .graph
                    .vertices
                    .keys()
                    .filter_map(|&id| u32::try_from(split_vertex_id(id).0).ok())
                    .filter(|&owner| owner != robot.robot)
                    .collect();
                peers.dedup();
                RobotInfo {
                    robot: robot.robot,
                    keyframes: robot.keyframes.len(),
                    described: robot.keyframes.iter().filter(|k| k.descriptor.is_some()).count(),
                    points: robot.keyframes.iter().map(|k| k.point_count).sum(),
                    path_length_m,
                    duration_s,
                    loops,
                    peers_in_graph: peers,
                    placed: robot.map_from_robot.is_some(),
                }
            })
            .collect();
        Ok(Self {
            name: session.name.clone(),
            skid_version: session.skid_version.clone(),
            descriptor: session
                .descriptor
                .as_ref()
                .map(|spec| (spec.kind.clone(), spec.length)),
            robots,
            bytes_on_disk: folder_bytes(dir)?,
        })
    }
}
