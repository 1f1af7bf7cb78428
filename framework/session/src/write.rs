//! Writes a session folder (layout in the crate doc).

use std::path::Path;

use skid_core::Point;
use skid_io::g2o::write_g2o_3d;
use skid_io::ply::{PlyFormat, write_ply};

use crate::manifest::{DescriptorRecord, KeyframeRecord, Manifest, PoseRecord, RobotRecord};
use crate::{
    FORMAT_NAME, FORMAT_VERSION, MANIFEST_FILE, Session, SessionError, SessionKeyframe, SessionRobot,
};

fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), SessionError> {
    std::fs::write(path, bytes).map_err(|e| SessionError::io(path, e))
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), SessionError> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| SessionError::invalid(path, format!("cannot be encoded: {e}")))?;
    write_bytes(path, text.as_bytes())
}

fn manifest(session: &Session) -> Manifest {
    Manifest {
        format: FORMAT_NAME.to_string(),
        version: FORMAT_VERSION,
        skid_version: session.skid_version.clone(),
        name: session.name.clone(),
        map_frame: "robot0/map".to_string(),
        descriptor: session.descriptor.as_ref().map(|spec| DescriptorRecord {
            kind: spec.kind.clone(),
            params: spec.params.clone(),
            length: spec.length,
        }),
        robots: session
            .robots
            .iter()
            .map(|robot| RobotRecord {
                robot: robot.robot,
                map_from_robot: robot.map_from_robot.as_ref().map(PoseRecord::from_pose),
                keyframes: robot.keyframes.len(),
            })
            .collect(),
        config: session.config_toml.clone(),
    }
}

/// Writes one keyframe's cloud file at the given path and returns its point count.
pub(crate) type CloudWriter<'w> = dyn FnMut(&SessionKeyframe, &Path) -> Result<usize, SessionError> + 'w;

/// Writes a robot's folder: its keyframes, descriptors, pose graph and, through `write_cloud`, one
/// cloud file per keyframe.
pub(crate) fn write_robot(
    folder: &Path,
    robot: &SessionRobot,
    length: usize,
    write_cloud: &mut CloudWriter<'_>,
) -> Result<(), SessionError> {
    let clouds = folder.join("clouds");
    std::fs::create_dir_all(&clouds).map_err(|e| SessionError::io(&clouds, e))?;
    let mut records = Vec::with_capacity(robot.keyframes.len());
    let mut descriptors: Vec<(u32, &[f32])> = Vec::new();
    for keyframe in &robot.keyframes {
        let points = write_cloud(keyframe, &folder.join(crate::cloud_file(keyframe.index)))?;
        records.push(KeyframeRecord {
            index: keyframe.index,
            stamp_nanos: keyframe.stamp_nanos,
            map_from_sensor: PoseRecord::from_pose(&keyframe.map_from_sensor),
            odometry_from_sensor: PoseRecord::from_pose(&keyframe.odometry_from_sensor),
            ground_truth: keyframe.ground_truth.as_ref().map(PoseRecord::from_pose),
            points,
        });
        if let Some(values) = &keyframe.descriptor {
            descriptors.push((keyframe.index, values));
        }
    }
    write_json(&folder.join("keyframes.json"), &records)?;
    let path = folder.join("descriptors.bin");
    let bytes =
        crate::encode_descriptors(length, &descriptors).map_err(|m| SessionError::invalid(&path, m))?;
    write_bytes(&path, &bytes)?;
    write_g2o_3d(folder.join("pose_graph.g2o"), &robot.graph)?;
    Ok(())
}

/// Writes the manifest, last: a folder without one is a session whose writing did not finish.
pub(crate) fn write_manifest(dir: &Path, session: &Session) -> Result<(), SessionError> {
    write_json(&dir.join(MANIFEST_FILE), &manifest(session))
}

/// Writes `session` into the folder `dir` (created if needed); `cloud_of(robot, index)` gives each
/// keyframe's cloud in its sensor frame (a keyframe without one is written as an empty cloud).
pub fn write_session<'a>(
    dir: &Path,
    session: &Session,
    cloud_of: impl Fn(u32, u32) -> Option<&'a [Point]>,
) -> Result<(), SessionError> {
    std::fs::create_dir_all(dir).map_err(|e| SessionError::io(dir, e))?;
    let length = session.descriptor.as_ref().map_or(0, |spec| spec.length);
    for robot in &session.robots {
        let mut write_cloud = |keyframe: &SessionKeyframe, path: &Path| {
            let points = cloud_of(robot.robot, keyframe.index).unwrap_or_default();
            write_ply(path, points, PlyFormat::BinaryLittleEndian)?;
            Ok(points.len())
        };
        write_robot(
            &dir.join(crate::robot_folder(robot.robot)),
            robot,
            length,
            &mut write_cloud,
        )?;
    }
    write_manifest(dir, session)
}
