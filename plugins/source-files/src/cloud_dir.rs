//! The `cloud_dir` source: a folder of PCD or PLY clouds read in file-name order, with an optional TUM
//! trajectory giving each cloud's stamp and ground-truth pose (matched by order).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use skid_core::slots::Source;
use skid_core::{PluginContext, PluginError, PluginResult, RawPoint, RobotId, Scan};
use skid_io::{CloudReadOptions, trajectory::StampedPose};

use crate::segment::{SplitConfig, segment};
use crate::{io_error, resolve_path};

/// Parameters of the `cloud_dir` source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct CloudDirConfig {
    /// The folder of `.pcd` / `.ply` files; `{robot}` is replaced by the robot index.
    pub path: PathBuf,
    /// TUM trajectory (relative to the folder) with one pose per cloud; empty for none.
    pub trajectory: String,
    /// Time between clouds when there is no trajectory, in seconds.
    pub period_s: f64,
    /// Stop after this many clouds; 0 reads to the end.
    pub max_scans: usize,
    /// Drop `(0, 0, 0)` "no return" points (organised clouds write them for missing returns).
    pub drop_zero_points: bool,
    pub split: SplitConfig,
}

impl Default for CloudDirConfig {
    fn default() -> Self {
        Self {
            path: PathBuf::from("lidar_scan_pair_fast_gicp"),
            trajectory: String::new(),
            period_s: 0.1,
            max_scans: 0,
            drop_zero_points: true,
            split: SplitConfig::default(),
        }
    }
}

/// Reads one robot's clouds from a folder.
pub struct CloudDirSource {
    robot: RobotId,
    files: Vec<PathBuf>,
    trajectory: Option<Vec<StampedPose>>,
    period_s: f64,
    options: CloudReadOptions,
    next: usize,
    end: usize,
    sequence: u32,
}

impl CloudDirSource {
    pub fn open(config: CloudDirConfig, context: &PluginContext) -> PluginResult<Self> {
        let folder = resolve_path(Path::new(
            &config
                .path
                .to_string_lossy()
                .replace("{robot}", &context.robot.0.to_string()),
        ))?;
        let entries = std::fs::read_dir(&folder).map_err(|e| PluginError::io(&folder, e))?;
        let mut files: Vec<PathBuf> = entries
            .filter_map(|entry| entry.ok().map(|e| e.path()))
            .filter(|path| path.extension().is_some_and(|ext| ext == "pcd" || ext == "ply"))
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(PluginError::InvalidInput(format!(
                "{}: no .pcd or .ply files",
                folder.display()
            )));
        }
        let trajectory = if config.trajectory.is_empty() {
            None
        } else {
            let path = folder.join(&config.trajectory);
            let poses = skid_io::trajectory::read_tum(&path).map_err(io_error)?;
            if poses.len() < files.len() {
                return Err(PluginError::InvalidInput(format!(
                    "{}: {} poses for {} clouds",
                    path.display(),
                    poses.len(),
                    files.len()
                )));
            }
            Some(poses)
        };
        if !(config.period_s.is_finite() && config.period_s > 0.0) {
            return Err(PluginError::failed("cloud_dir", "period_s must be positive"));
        }
        let mut range = segment(
            files.len(),
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
            files,
            trajectory,
            period_s: config.period_s,
            options,
            next: range.start,
            end: range.end,
            sequence: 0,
        })
    }

    fn read_points(&self, path: &Path) -> PluginResult<Vec<RawPoint>> {
        let is_pcd = path.extension().is_some_and(|ext| ext == "pcd");
        let (points, report) = if is_pcd {
            let cloud = skid_io::pcd::read_pcd(path, self.options).map_err(io_error)?;
            (cloud.points, cloud.report)
        } else {
            let cloud = skid_io::ply::read_ply(path, self.options).map_err(io_error)?;
            (cloud.points, cloud.report)
        };
        if let Some(warning) = report.under_count_warning(path) {
            tracing::warn!("{warning}");
        }
        Ok(points
            .iter()
            .map(|p| RawPoint::new(p.x, p.y, p.z, p.intensity, 0.0, RawPoint::UNKNOWN_RING))
            .collect())
    }
}

impl Source for CloudDirSource {
    fn next_scan(&mut self) -> PluginResult<Option<Scan>> {
        if self.next >= self.end {
            return Ok(None);
        }
        let index = self.next;
        let points = self.read_points(&self.files[index])?;
        let pose = self.trajectory.as_ref().map(|poses| poses[index]);
        let stamp_s = pose.map_or(index as f64 * self.period_s, |p| p.stamp_s);
        let scan = Scan {
            robot: self.robot,
            sequence: self.sequence,
            stamp_nanos: (stamp_s * 1e9).round().max(0.0) as u64,
            points,
            imu: Vec::new(),
            ground_truth_world_from_sensor: pose.map(|p| p.world_from_sensor),
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

impl skid_core::PluginParams for CloudDirConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        crate::check_path("path", &self.path)?;
        skid_core::registry::check::positive("period_s", self.period_s)
    }

    fn check_files(&self) -> Result<(), skid_core::ParamError> {
        crate::check_path_exists("path", &self.path)
    }
}
