//! Reads a session folder back, checking that its files agree with one another (layout in the crate
//! doc).

use std::collections::BTreeMap;
use std::path::Path;

use skid_core::Point;
use skid_io::CloudReadOptions;
use skid_io::g2o::{G2oReadOptions, read_g2o_3d};
use skid_io::ply::read_ply;

use crate::manifest::{KeyframeRecord, Manifest, ManifestHead};
use crate::{
    DescriptorSpec, FORMAT_NAME, FORMAT_VERSION, MANIFEST_FILE, Session, SessionError, SessionKeyframe,
    SessionRobot,
};

fn read_bytes(path: &Path) -> Result<Vec<u8>, SessionError> {
    std::fs::read(path).map_err(|e| SessionError::io(path, e))
}

/// Parses JSON naming the key path of the first thing wrong.
fn parse_json<T: serde::de::DeserializeOwned>(path: &Path, bytes: &[u8]) -> Result<T, SessionError> {
    let mut deserializer = serde_json::Deserializer::from_slice(bytes);
    serde_path_to_error::deserialize(&mut deserializer)
        .map_err(|e| SessionError::invalid(path, format!("at `{}`: {}", e.path(), e.inner())))
}

fn read_manifest(dir: &Path) -> Result<Manifest, SessionError> {
    let path = dir.join(MANIFEST_FILE);
    if !path.exists() && dir.is_dir() {
        return Err(SessionError::invalid(
            dir,
            format!(
                "not a session folder: it has no {MANIFEST_FILE} (a run writes one last, so its writing may not have finished)"
            ),
        ));
    }
    let bytes = read_bytes(&path)?;
    let head: ManifestHead = parse_json(&path, &bytes)?;
    if head.format.as_deref() != Some(FORMAT_NAME) {
        return Err(SessionError::invalid(
            &path,
            format!(
                "`format` is {:?}, not {FORMAT_NAME:?}: not a SKiD session",
                head.format
            ),
        ));
    }
    match head.version {
        Some(version) if (1..=FORMAT_VERSION).contains(&version) => {}
        Some(version) if version > FORMAT_VERSION => {
            return Err(SessionError::invalid(
                &path,
                format!(
                    "session format version {version} was written by a newer SKiD; this one reads up to version {FORMAT_VERSION}"
                ),
            ));
        }
        other => {
            return Err(SessionError::invalid(
                &path,
                format!("`version` {other:?} is not a session format version"),
            ));
        }
    }
    parse_json(&path, &bytes)
}

fn keyframes_of(dir: &Path, robot: u32, expected: usize) -> Result<Vec<SessionKeyframe>, SessionError> {
    let path = dir.join(crate::robot_folder(robot)).join("keyframes.json");
    let records: Vec<KeyframeRecord> = parse_json(&path, &read_bytes(&path)?)?;
    if records.len() != expected {
        return Err(SessionError::invalid(
            &path,
            format!(
                "{} keyframes where {MANIFEST_FILE} says robot {robot} has {expected}",
                records.len()
            ),
        ));
    }
    let mut keyframes: Vec<SessionKeyframe> = Vec::with_capacity(records.len());
    for (at, record) in records.into_iter().enumerate() {
        if keyframes.last().is_some_and(|last| last.index >= record.index) {
            return Err(SessionError::invalid(
                &path,
                format!(
                    "entry {at} (keyframe {}): keyframe indices must ascend without repeats",
                    record.index
                ),
            ));
        }
        let pose = |which: &str, pose: crate::manifest::PoseRecord| {
            pose.to_pose().map_err(|m| {
                SessionError::invalid(
                    &path,
                    format!("entry {at} (keyframe {}), `{which}`: {m}", record.index),
                )
            })
        };
        keyframes.push(SessionKeyframe {
            index: record.index,
            stamp_nanos: record.stamp_nanos,
            map_from_sensor: pose("map_from_sensor", record.map_from_sensor)?,
            odometry_from_sensor: pose("odometry_from_sensor", record.odometry_from_sensor)?,
            ground_truth: record
                .ground_truth
                .map(|truth| pose("ground_truth", truth))
                .transpose()?,
            point_count: record.points,
            descriptor: None,
        });
    }
    Ok(keyframes)
}

/// Puts each descriptor of the robot's `descriptors.bin` on its keyframe.
fn attach_descriptors(
    dir: &Path,
    robot: u32,
    spec: Option<&DescriptorSpec>,
    keyframes: &mut [SessionKeyframe],
) -> Result<(), SessionError> {
    let path = dir.join(crate::robot_folder(robot)).join("descriptors.bin");
    let (length, entries) =
        crate::decode_descriptors(&read_bytes(&path)?).map_err(|m| SessionError::invalid(&path, m))?;
    let expected = spec.map_or(0, |spec| spec.length);
    if !entries.is_empty() && length != expected {
        return Err(SessionError::invalid(
            &path,
            format!("descriptors of {length} values where {MANIFEST_FILE} says {expected}"),
        ));
    }
    let at: BTreeMap<u32, usize> = keyframes.iter().enumerate().map(|(i, k)| (k.index, i)).collect();
    for (index, values) in entries {
        let Some(&slot) = at.get(&index) else {
            return Err(SessionError::invalid(
                &path,
                format!("a descriptor for keyframe {index}, which keyframes.json does not list"),
            ));
        };
        if keyframes[slot].descriptor.replace(values).is_some() {
            return Err(SessionError::invalid(
                &path,
                format!("two descriptors for keyframe {index}"),
            ));
        }
    }
    Ok(())
}

/// Reads the session in folder `dir`: manifest, keyframes, descriptors and pose graphs (clouds stay on
/// disk: [`read_keyframe_cloud`]).
pub fn read_session(dir: &Path) -> Result<Session, SessionError> {
    let manifest = read_manifest(dir)?;
    let descriptor = manifest.descriptor.map(|record| DescriptorSpec {
        kind: record.kind,
        params: record.params,
        length: record.length,
    });
    let manifest_path = dir.join(MANIFEST_FILE);
    let mut robots: Vec<SessionRobot> = Vec::with_capacity(manifest.robots.len());
    for record in manifest.robots {
        if robots.last().is_some_and(|last| last.robot >= record.robot) {
            return Err(SessionError::invalid(
                &manifest_path,
                format!(
                    "robot {}: robots must be listed by ascending id without repeats",
                    record.robot
                ),
            ));
        }
        let map_from_robot = record
            .map_from_robot
            .map(|pose| pose.to_pose())
            .transpose()
            .map_err(|m| {
                SessionError::invalid(
                    &manifest_path,
                    format!("robot {}, `map_from_robot`: {m}", record.robot),
                )
            })?;
        let mut keyframes = keyframes_of(dir, record.robot, record.keyframes)?;
        attach_descriptors(dir, record.robot, descriptor.as_ref(), &mut keyframes)?;
        let graph_path = dir.join(crate::robot_folder(record.robot)).join("pose_graph.g2o");
        let (graph, _) = read_g2o_3d(&graph_path, &G2oReadOptions::default())?;
        robots.push(SessionRobot {
            robot: record.robot,
            map_from_robot,
            keyframes,
            graph,
        });
    }
    Ok(Session {
        name: manifest.name,
        skid_version: manifest.skid_version,
        descriptor,
        config_toml: manifest.config,
        robots,
    })
}

/// Reads one keyframe's cloud (sensor frame) from the session in `dir`, checking it holds the points
/// `keyframes.json` says.
pub fn read_keyframe_cloud(
    dir: &Path,
    robot: &SessionRobot,
    keyframe: &SessionKeyframe,
) -> Result<Vec<Point>, SessionError> {
    let path = dir
        .join(crate::robot_folder(robot.robot))
        .join(crate::cloud_file(keyframe.index));
    let cloud = read_ply(&path, CloudReadOptions::default())?;
    if cloud.points.len() != keyframe.point_count {
        return Err(SessionError::invalid(
            &path,
            format!(
                "{} points where keyframes.json says keyframe {} has {}",
                cloud.points.len(),
                keyframe.index,
                keyframe.point_count
            ),
        ));
    }
    Ok(cloud.points)
}
