//! Reading a trajectory file for evaluation in either of evo's two plain formats, TUM
//! (`stamp tx ty tz qx qy qz qw`) or KITTI (12 numbers of a row-major 3x4 pose, no stamps), telling
//! them apart by content (8 or 12 numbers on the first data line), with the file extension
//! (`.tum` / `.kitti`) as a hint when the content is ambiguous.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::EvalError;
use skid_core::Pose;
use skid_io::trajectory::{StampedPose, read_kitti_poses, read_tum};

/// A trajectory file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrajectoryFormat {
    Tum,
    Kitti,
}

/// A trajectory read from a file: poses, with stamps when the format has them.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    pub format: TrajectoryFormat,
    /// `world_from_sensor` poses in file order.
    pub poses: Vec<Pose>,
    /// One stamp in seconds per pose (TUM), or `None` (KITTI).
    pub stamps_s: Option<Vec<f64>>,
}

impl Trajectory {
    /// A trajectory from stamped poses (as the runtime or a TUM reader produces them).
    pub fn from_stamped(poses: &[StampedPose]) -> Self {
        Self {
            format: TrajectoryFormat::Tum,
            poses: poses.iter().map(|p| p.world_from_sensor).collect(),
            stamps_s: Some(poses.iter().map(|p| p.stamp_s).collect()),
        }
    }

    /// A trajectory without stamps, associated by index.
    pub fn from_poses(poses: Vec<Pose>) -> Self {
        Self {
            format: TrajectoryFormat::Kitti,
            poses,
            stamps_s: None,
        }
    }

    /// The poses with their stamps, when the trajectory has stamps.
    pub fn stamped(&self) -> Option<Vec<StampedPose>> {
        let stamps = self.stamps_s.as_ref()?;
        Some(
            stamps
                .iter()
                .zip(&self.poses)
                .map(|(&stamp_s, &world_from_sensor)| StampedPose {
                    stamp_s,
                    world_from_sensor,
                })
                .collect(),
        )
    }
}

/// Tells the format of a trajectory file from its first data line (blank and `#` lines skipped).
pub fn detect_format(path: &Path) -> Result<TrajectoryFormat, EvalError> {
    let text = std::fs::read_to_string(path).map_err(|e| skid_io::IoError::io(path, e))?;
    let unknown = |reason: String| EvalError::UnknownFormat {
        path: path.to_path_buf(),
        reason,
    };
    let Some(line) = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
    else {
        return Err(unknown("the file has no data line".into()));
    };
    let tokens = line
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .count();
    match tokens {
        8 => Ok(TrajectoryFormat::Tum),
        12 => Ok(TrajectoryFormat::Kitti),
        _ => match path.extension().and_then(|e| e.to_str()) {
            Some("tum") => Ok(TrajectoryFormat::Tum),
            Some("kitti") => Ok(TrajectoryFormat::Kitti),
            _ => Err(unknown(format!(
                "the first data line has {tokens} values; TUM has 8 (stamp tx ty tz qx qy qz qw), KITTI 12 (3x4 matrix)"
            ))),
        },
    }
}

/// Reads a trajectory file, detecting the format unless `format` is given.
pub fn read_trajectory(path: &Path, format: Option<TrajectoryFormat>) -> Result<Trajectory, EvalError> {
    let format = match format {
        Some(f) => f,
        None => detect_format(path)?,
    };
    Ok(match format {
        TrajectoryFormat::Tum => Trajectory::from_stamped(&read_tum(path)?),
        TrajectoryFormat::Kitti => Trajectory::from_poses(read_kitti_poses(path)?),
    })
}
