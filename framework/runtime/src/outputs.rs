//! Writes a run's outputs under `<output_dir>/<name>/` (staged by the `run_folder` module): the effective configuration (`config.toml`),
//! per-robot trajectories (TUM and KITTI; the optimised estimate and the ground truth) and pose graphs
//! (g2o), the merged map (`map.ply`), the run record (`run.mcap`), the session (`session/`),
//! `metrics.json`, `summary.json` and the PNG plots.

use std::path::{Path, PathBuf};

use skid_core::Pose;
use skid_io::ply::{PlyFormat, write_ply};
use skid_io::trajectory::{StampedPose, write_kitti_poses, write_tum};

use crate::artifacts::{map_frames, write_plots, write_pose_graphs};
use crate::error::{RuntimeError, output_error};
use crate::fleet::Fleet;
use crate::host::RobotHost;
use crate::map_clouds::{merge_maps, place_clouds};
use crate::metrics::{RunMetrics, alpha_frames};
use crate::summary::RunSummary;

fn stamped(poses: &[(u64, Pose)]) -> Vec<StampedPose> {
    poses
        .iter()
        .map(|(stamp, pose)| StampedPose {
            stamp_s: *stamp as f64 * 1e-9,
            world_from_sensor: *pose,
        })
        .collect()
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), RuntimeError> {
    let json = serde_json::to_string_pretty(value).map_err(|e| output_error(path, e))?;
    std::fs::write(path, json).map_err(|e| output_error(path, e))
}

fn write_trajectories(folder: &Path, robot: &RobotHost) -> Result<(), RuntimeError> {
    let robot_folder = folder.join(format!("robot{}", robot.robot().0));
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
        .scans()
        .iter()
        .filter_map(|s| s.ground_truth.map(|t| (s.stamp_nanos, t)))
        .collect();
    if !truth.is_empty() {
        let tum = robot_folder.join("ground_truth.tum");
        write_tum(&tum, &stamped(&truth)).map_err(|e| output_error(&tum, e))?;
        let kitti = robot_folder.join("ground_truth.kitti");
        let poses: Vec<_> = truth.iter().map(|(_, pose)| *pose).collect();
        write_kitti_poses(&kitti, &poses).map_err(|e| output_error(&kitti, e))?;
    }
    Ok(())
}

/// Writes everything into the run's staging folder, then moves it to `<output_dir>/<name>/` (replacing
/// an earlier run of that name whole) and returns that folder with the metrics it wrote.
pub fn write_outputs(fleet: &Fleet, summary: &RunSummary) -> Result<(PathBuf, RunMetrics), RuntimeError> {
    let staged = crate::run_folder::begin(&fleet.config)?;
    let metrics = write_into(staged.path(), fleet, summary)?;
    Ok((crate::run_folder::commit(&staged)?, metrics))
}

/// Writes what a run that stopped early has (trajectories so far, the graphs, the map, the plots, the
/// record up to the stop, and `summary` marked interrupted) into its `<name>.incomplete/` folder, which
/// stays incomplete: a complete run appears under the run's name only when it completes.
pub fn write_partial_outputs(fleet: &Fleet, summary: &RunSummary) -> Result<PathBuf, RuntimeError> {
    let staged = crate::run_folder::begin(&fleet.config)?;
    write_into(staged.path(), fleet, summary)?;
    Ok(staged.path().to_path_buf())
}

fn write_into(folder: &Path, fleet: &Fleet, summary: &RunSummary) -> Result<RunMetrics, RuntimeError> {
    let folder = folder.to_path_buf();
    let config_path = folder.join("config.toml");
    std::fs::write(&config_path, fleet.config.to_toml_string()).map_err(|e| output_error(&config_path, e))?;
    for robot in &fleet.robots {
        write_trajectories(&folder, robot)?;
    }
    write_pose_graphs(&folder, &fleet.robots)?;
    let fits = alpha_frames(&fleet.robots);
    let frames = map_frames(&fits);
    // Each keyframe cloud is placed by its optimised pose once, for the map, the plots and the record.
    let record_voxel_m = fleet
        .config
        .output
        .record
        .then_some(fleet.config.output.record_voxel_m as f32);
    let clouds: Vec<_> = fleet
        .robots
        .iter()
        .map(|robot| place_clouds(robot, record_voxel_m))
        .collect();
    let map = merge_maps(&clouds, &frames);
    if !map.is_empty() {
        let path = folder.join("map.ply");
        write_ply(&path, &map, PlyFormat::BinaryLittleEndian).map_err(|e| output_error(&path, e))?;
    }
    write_plots(&folder, &fleet.robots, &clouds, &frames)?;
    if fleet.config.output.record {
        let started = std::time::Instant::now();
        let in_prior: Vec<Option<Pose>> = fleet
            .robots
            .iter()
            .map(|robot| {
                fleet.prior.as_ref()?;
                robot.localisation().map(|placed| placed.prior_from_map)
            })
            .collect();
        let path =
            crate::run_record::write_run_record(&folder, &fleet.robots, &clouds, (&frames, &in_prior), &map)?;
        let bytes = std::fs::metadata(&path).map_or(0, |m| m.len());
        tracing::info!(
            bytes,
            seconds = started.elapsed().as_secs_f64(),
            "wrote the run record run.mcap"
        );
    }
    if fleet.config.output.session {
        crate::session_out::write_session(&folder, fleet, &frames)?;
    }
    let metrics = RunMetrics::with_frames(&fleet.config.run.name, &fleet.robots, &fits);
    write_json(&folder.join("metrics.json"), &metrics)?;
    write_json(&folder.join("summary.json"), summary)?;
    Ok(metrics)
}
