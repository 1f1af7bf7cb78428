//! The `kitti` source: a KITTI odometry sequence folder (`velodyne/*.bin`, `times.txt`, `poses.txt`,
//! `calib.txt`). Ground truth in `poses.txt` is given for camera 0; it is converted to the LiDAR frame
//! with the calibration `Tr` (camera 0 from Velodyne): `world_from_lidar = Tr⁻¹ · world_cam_from_cam · Tr`,
//! so the ground-truth world is the first LiDAR pose's frame, as the odometry's is.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use skid_core::slots::Source;
use skid_core::{PluginContext, PluginError, PluginResult, Pose, RawPoint, RobotId, Scan};
use skid_io::{CloudReadOptions, kitti, trajectory};

use crate::segment::{SplitConfig, segment};
use crate::{io_error, resolve_path};

/// The frame `poses_file` is expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PosesFrame {
    /// KITTI's own `poses.txt`: camera 0 poses, converted with `calib.txt`.
    #[default]
    Camera,
    /// Poses already in the LiDAR frame.
    Lidar,
}

/// Parameters of the `kitti` source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct KittiConfig {
    /// The sequence folder; `{robot}` is replaced by the robot index (one folder per robot).
    pub path: PathBuf,
    /// Ground-truth file inside the folder; missing means no ground truth.
    pub poses_file: String,
    pub poses_frame: PosesFrame,
    /// Stop after this many scans; 0 reads to the end.
    pub max_scans: usize,
    /// Drop `(0, 0, 0)` "no return" points.
    pub drop_zero_points: bool,
    pub split: SplitConfig,
}

impl Default for KittiConfig {
    fn default() -> Self {
        Self {
            path: PathBuf::from("kitti_00_lidar_frames_0000_0015"),
            poses_file: "poses.txt".to_owned(),
            poses_frame: PosesFrame::Camera,
            max_scans: 0,
            drop_zero_points: true,
            split: SplitConfig::default(),
        }
    }
}

/// Reads one robot's scans from a KITTI folder, one file per `next_scan`.
pub struct KittiSource {
    robot: RobotId,
    scans: Vec<PathBuf>,
    stamps_s: Vec<f64>,
    ground_truth: Option<Vec<Pose>>,
    options: CloudReadOptions,
    next: usize,
    end: usize,
    sequence: u32,
}

impl KittiSource {
    /// Opens the folder and reads its index files; scans are read lazily.
    pub fn open(config: KittiConfig, context: &PluginContext) -> PluginResult<Self> {
        let folder = resolve_path(Path::new(
            &config
                .path
                .to_string_lossy()
                .replace("{robot}", &context.robot.0.to_string()),
        ))?;
        let scans = list_scans(&folder.join("velodyne"))?;
        let times_path = folder.join("times.txt");
        let stamps_s = if times_path.is_file() {
            let stamps = kitti::read_kitti_times(&times_path).map_err(io_error)?;
            if stamps.len() < scans.len() {
                return Err(PluginError::InvalidInput(format!(
                    "{}: {} stamps for {} scans",
                    times_path.display(),
                    stamps.len(),
                    scans.len()
                )));
            }
            stamps
        } else {
            (0..scans.len()).map(|i| i as f64 * 0.1).collect()
        };
        let ground_truth = read_ground_truth(&folder, &config, scans.len())?;
        let mut range = segment(
            scans.len(),
            context.robot.0 as usize,
            context.fleet_size as usize,
            &config.split,
        );
        if config.max_scans > 0 {
            range.end = range.end.min(range.start + config.max_scans);
        }
        let options = CloudReadOptions {
            drop_zero: config.drop_zero_points,
            ..CloudReadOptions::default()
        };
        Ok(Self {
            robot: context.robot,
            scans,
            stamps_s,
            ground_truth,
            options,
            next: range.start,
            end: range.end,
            sequence: 0,
        })
    }
}

impl Source for KittiSource {
    fn next_scan(&mut self) -> PluginResult<Option<Scan>> {
        if self.next >= self.end {
            return Ok(None);
        }
        let index = self.next;
        let cloud = kitti::read_kitti_bin(&self.scans[index], self.options).map_err(io_error)?;
        let points = cloud
            .points
            .iter()
            .map(|p| RawPoint::new(p.x, p.y, p.z, p.intensity, 0.0, RawPoint::UNKNOWN_RING))
            .collect();
        let scan = Scan {
            robot: self.robot,
            sequence: self.sequence,
            stamp_nanos: (self.stamps_s[index] * 1e9).round().max(0.0) as u64,
            points,
            imu: Vec::new(),
            ground_truth_world_from_sensor: self.ground_truth.as_ref().map(|poses| poses[index]),
            imu_from_sensor: None,
        };
        self.next += 1;
        self.sequence += 1;
        Ok(Some(scan))
    }

    fn remaining_hint(&self) -> Option<usize> {
        Some(self.end.saturating_sub(self.next))
    }
}

/// The `.bin` files of a `velodyne/` folder in name order; an empty or missing folder is an error.
pub(crate) fn list_scans(folder: &Path) -> PluginResult<Vec<PathBuf>> {
    let entries = std::fs::read_dir(folder).map_err(|e| PluginError::io(folder, e))?;
    let mut scans: Vec<PathBuf> = entries
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.extension().is_some_and(|ext| ext == "bin"))
        .collect();
    scans.sort();
    if scans.is_empty() {
        return Err(PluginError::InvalidInput(format!(
            "{}: no .bin scans",
            folder.display()
        )));
    }
    Ok(scans)
}

/// Ground truth in the LiDAR frame, if the folder has it.
fn read_ground_truth(
    folder: &Path,
    config: &KittiConfig,
    scan_count: usize,
) -> PluginResult<Option<Vec<Pose>>> {
    let poses_path = folder.join(&config.poses_file);
    if config.poses_file.is_empty() || !poses_path.is_file() {
        return Ok(None);
    }
    let poses = trajectory::read_kitti_poses(&poses_path).map_err(io_error)?;
    if poses.len() < scan_count {
        return Err(PluginError::InvalidInput(format!(
            "{}: {} poses for {scan_count} scans",
            poses_path.display(),
            poses.len()
        )));
    }
    let poses = match config.poses_frame {
        PosesFrame::Lidar => poses,
        PosesFrame::Camera => {
            let calib = kitti::read_kitti_calib(folder.join("calib.txt")).map_err(io_error)?;
            let cam_from_lidar = calib.cam0_from_velodyne;
            let lidar_from_cam = cam_from_lidar.inverse();
            poses
                .iter()
                .map(|world_cam_from_cam| lidar_from_cam * world_cam_from_cam * cam_from_lidar)
                .collect()
        }
    };
    Ok(Some(poses))
}

impl skid_core::PluginParams for KittiConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        crate::check_path("path", &self.path)
    }

    fn check_files(&self) -> Result<(), skid_core::ParamError> {
        crate::check_path_exists("path", &self.path)
    }
}
