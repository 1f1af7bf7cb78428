//! Writes a run's outputs: the effective configuration, per-robot trajectories (TUM and KITTI; the
//! optimised estimate and the ground truth), each robot's pose graph (g2o) and the summary JSON.

use std::path::{Path, PathBuf};

use skid_core::Pose;
use skid_io::trajectory::{StampedPose, write_kitti_poses, write_tum};

use crate::summary::RunSummary;
use crate::{Fleet, RuntimeError};

fn output_error(path: &Path, message: impl ToString) -> RuntimeError {
    RuntimeError::Output {
        path: path.to_owned(),
        message: message.to_string(),
    }
}

fn stamped(poses: &[(u64, Pose)]) -> Vec<StampedPose> {
    poses
        .iter()
        .map(|(stamp, pose)| StampedPose {
            stamp_s: *stamp as f64 * 1e-9,
            world_from_sensor: *pose,
        })
        .collect()
}

/// Writes everything under `<output_dir>/<name>/` and returns that folder.
pub fn write_outputs(fleet: &Fleet, summary: &RunSummary) -> Result<PathBuf, RuntimeError> {
    let folder = fleet.config.run.output_dir.join(&fleet.config.run.name);
    std::fs::create_dir_all(&folder).map_err(|e| output_error(&folder, e))?;
    let config_path = folder.join("config.toml");
    std::fs::write(&config_path, fleet.config.to_toml_string()).map_err(|e| output_error(&config_path, e))?;
    for robot in &fleet.robots {
        let robot_folder = folder.join(format!("robot{}", robot.robot.0));
        std::fs::create_dir_all(&robot_folder).map_err(|e| output_error(&robot_folder, e))?;
        let trajectory = robot.optimised_trajectory();
        if !trajectory.is_empty() {
            let tum = robot_folder.join("trajectory.tum");
            write_tum(&tum, &stamped(&trajectory)).map_err(|e| output_error(&tum, e))?;
            let kitti = robot_folder.join("trajectory.kitti");
            let poses: Vec<_> = trajectory.iter().map(|(_, pose)| *pose).collect();
            write_kitti_poses(&kitti, &poses).map_err(|e| output_error(&kitti, e))?;
        }
        let truth: Vec<(u64, Pose)> = robot
            .scans
            .iter()
            .filter_map(|s| s.ground_truth.map(|t| (s.stamp_nanos, t)))
            .collect();
        if !truth.is_empty() {
            let tum = robot_folder.join("ground_truth.tum");
            write_tum(&tum, &stamped(&truth)).map_err(|e| output_error(&tum, e))?;
        }
    }
    let summary_path = folder.join("summary.json");
    let json = serde_json::to_string_pretty(summary).map_err(|e| output_error(&summary_path, e))?;
    std::fs::write(&summary_path, json).map_err(|e| output_error(&summary_path, e))?;
    Ok(folder)
}
