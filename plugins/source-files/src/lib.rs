//! Sources that read recorded data from files: `kitti` (a KITTI odometry sequence folder),
//! `cloud_dir` (a folder of PCD or PLY clouds with an optional TUM trajectory) and `bag` (ROS 1 and
//! ROS 2 bags and MCAP files).
//!
//! Both can turn one long sequence into several robots with `split = true`: robot `i` of `N` reads the
//! `i`-th of `N` consecutive segments (plus `split_overlap_scans` scans of the previous one), as
//! multi-robot papers do with KITTI 00 and 08. Relative paths that do not exist from the current folder
//! are looked up under the data folder (`SKID_DATA_DIR`, default `../shared/data`).

mod bag;
pub mod bag_stream;
mod cloud_dir;
mod kitti;
mod segment;
pub mod static_frames;

pub use segment::SplitConfig;

pub use bag::{BagConfig, BagSource, bag_error};
pub use cloud_dir::{CloudDirConfig, CloudDirSource};
pub use kitti::{KittiConfig, KittiSource};

use skid_core::slots::Source;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

/// Registers `kitti`, `cloud_dir` and `bag` in the source slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.source.register(PluginEntry::new(
        "kitti",
        "KITTI odometry folder: velodyne/*.bin, times.txt, poses.txt + calib.txt (ground truth in the LiDAR frame)",
        |config: KittiConfig, context: &PluginContext| Ok(Box::new(KittiSource::open(config, context)?) as Box<dyn Source>),
    )?)?;
    registry.source.register(PluginEntry::new(
        "cloud_dir",
        "Folder of PCD/PLY clouds in name order, with an optional TUM trajectory as ground truth",
        |config: CloudDirConfig, context: &PluginContext| {
            Ok(Box::new(CloudDirSource::open(config, context)?) as Box<dyn Source>)
        },
    )?)?;
    registry.source.register(PluginEntry::new(
        "bag",
        "ROS 1 bag, ROS 2 bag folder (MCAP or sqlite3) or MCAP file: PointCloud2 scans, Imu, ground truth",
        |config: BagConfig, context: &PluginContext| {
            Ok(Box::new(BagSource::open(config, context)?) as Box<dyn Source>)
        },
    )?)?;
    Ok(())
}

/// A configured path must name something.
pub(crate) fn check_path(key: &str, path: &std::path::Path) -> Result<(), skid_core::ParamError> {
    if path.as_os_str().is_empty() {
        return Err(skid_core::ParamError::at(key, "empty: name a file or folder"));
    }
    Ok(())
}

/// Checks that the configured path under `key` exists, here or under the data folder (what
/// `skid config check` asks of every source that reads files).
pub(crate) fn check_path_exists(key: &str, path: &std::path::Path) -> Result<(), skid_core::ParamError> {
    match resolve_path(path) {
        Ok(_) => Ok(()),
        Err(PluginError::InvalidInput(message)) => Err(skid_core::ParamError::at(key, message)),
        Err(other) => Err(skid_core::ParamError::at(key, other.to_string())),
    }
}

/// Resolves a configured path: as given when it exists, else under the data folder; when neither
/// exists, an error that names both places and the variable that moves the data folder.
pub(crate) fn resolve_path(path: &std::path::Path) -> Result<std::path::PathBuf, PluginError> {
    if path.exists() {
        return Ok(path.to_owned());
    }
    let data = skid_io::data_dir();
    let under_data = data.join(path);
    if !path.is_absolute() && under_data.exists() {
        return Ok(under_data);
    }
    let looked = if path.is_absolute() {
        String::new()
    } else {
        format!(
            " (looked in the current folder and in the data folder {}, which SKID_DATA_DIR sets)",
            data.display()
        )
    };
    Err(PluginError::InvalidInput(format!(
        "{} does not exist{looked}",
        path.display()
    )))
}

/// Converts a skid-io error into a plugin error.
pub(crate) fn io_error(error: skid_io::IoError) -> PluginError {
    PluginError::InvalidInput(error.to_string())
}
