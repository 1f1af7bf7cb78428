//! The `bag` source: one robot's scans from a ROS 1 bag, a ROS 2 bag folder (MCAP or sqlite3) or a bare
//! MCAP file, streamed through `skid-bag` without a ROS installation.
//!
//! The point-cloud topic gives the scans (`sensor_msgs/PointCloud2`, any driver layout; the scan stamp is
//! the message's header stamp and per-point times become `RawPoint` time offsets from it). The IMU topic
//! fills each scan's `imu` with the samples after the previous scan's stamp up to this one. The
//! ground-truth topic (`nav_msgs/Odometry`, `geometry_msgs/PoseStamped` or `tf2_msgs/TFMessage` filtered
//! by `ground_truth_frame`) is interpolated at the scan stamp. Several robots read one bag each (`{robot}`
//! in `path`) or one bag with per-robot namespaces (`{robot}` in the topics), or split one recording.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use skid_bag::{Bag, MessageReader};
use skid_core::slots::Source;
use skid_core::{PluginContext, PluginError, PluginResult, RobotId, Scan};

use crate::bag_stream::{ScanAssembler, Topics};
use crate::resolve_path;
use crate::segment::{SplitConfig, segment};

/// Parameters of the `bag` source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct BagConfig {
    /// A `.bag` file, a ROS 2 bag folder, or a `.mcap`/`.db3` file; `{robot}` is replaced by the robot index.
    pub path: PathBuf,
    /// The `sensor_msgs/PointCloud2` topic; `{robot}` is replaced by the robot index.
    pub points_topic: String,
    /// The `sensor_msgs/Imu` topic; empty for none.
    pub imu_topic: String,
    /// The ground-truth topic (`nav_msgs/Odometry`, `geometry_msgs/PoseStamped` or `/tf`); empty for none.
    pub ground_truth_topic: String,
    /// On a `/tf` ground-truth topic, the child frame whose pose is the ground truth.
    pub ground_truth_frame: String,
    /// Static transforms (`tf2_msgs/TFMessage`) giving the LiDAR→IMU extrinsic, read when the bag has
    /// the topic; empty for none.
    pub tf_static_topic: String,
    /// Stop after this many scans; 0 reads to the end.
    pub max_scans: usize,
    /// Drop `(0, 0, 0)` "no return" points.
    pub drop_zero_points: bool,
    /// Split one recording among the robots (counts the scans in a first pass over the bag).
    pub split: SplitConfig,
}

impl Default for BagConfig {
    fn default() -> Self {
        Self {
            path: PathBuf::from("kitti_00_rosbags/kitti00_velodyne_ros1-lz4.bag"),
            points_topic: "/velodyne_points".to_owned(),
            imu_topic: "/imu/data".to_owned(),
            ground_truth_topic: "/ground_truth".to_owned(),
            ground_truth_frame: String::new(),
            tf_static_topic: "/tf_static".to_owned(),
            max_scans: 0,
            drop_zero_points: true,
            split: SplitConfig::default(),
        }
    }
}

/// Reads one robot's scans from a bag.
pub struct BagSource {
    robot: RobotId,
    assembler: ScanAssembler,
    /// Scans of the bag this robot skips (split), then reads.
    skip: usize,
    remaining: usize,
    sequence: u32,
}

/// A bag error as a plugin error (its text names the file, topic and message).
pub fn bag_error(error: skid_bag::BagError) -> PluginError {
    PluginError::InvalidInput(error.to_string())
}

impl BagSource {
    /// Opens the bag and checks that the configured topics exist and carry the expected types.
    pub fn open(config: BagConfig, context: &PluginContext) -> PluginResult<Self> {
        let robot_text = context.robot.0.to_string();
        let per_robot = |text: &str| text.replace("{robot}", &robot_text);
        let path = resolve_path(Path::new(&per_robot(&config.path.to_string_lossy())))?;
        let topics = Topics {
            points: cloud_topic(&path, per_robot(&config.points_topic))?,
            imu: Some(per_robot(&config.imu_topic)).filter(|t| !t.is_empty()),
            ground_truth: Some(per_robot(&config.ground_truth_topic)).filter(|t| !t.is_empty()),
            ground_truth_frame: config.ground_truth_frame.clone(),
            tf_static: Some(config.tf_static_topic.clone()).filter(|t| !t.is_empty()),
        };
        let mut range = 0..usize::MAX;
        if config.split.enabled && context.fleet_size > 1 {
            let total = count_messages(&path, &topics.points)?;
            range = segment(
                total,
                context.robot.0 as usize,
                context.fleet_size as usize,
                &config.split,
            );
        }
        if config.max_scans > 0 {
            range.end = range.end.min(range.start.saturating_add(config.max_scans));
        }
        let bag = Bag::open(&path).map_err(bag_error)?;
        let assembler =
            ScanAssembler::new(Box::new(bag), path, topics, config.drop_zero_points).map_err(bag_error)?;
        Ok(Self {
            robot: context.robot,
            assembler,
            skip: range.start,
            remaining: range.len(),
            sequence: 0,
        })
    }
}

/// The cloud topic to read: the configured one when the bag has it; otherwise the bag's only
/// `sensor_msgs/PointCloud2` topic, said in the log (a driver of another name, `/os_cloud_node/points`).
/// With none, or several, the choice is the user's: the error lists the candidates.
fn cloud_topic(path: &Path, configured: String) -> PluginResult<String> {
    let bag = Bag::open(path).map_err(bag_error)?;
    let connections = bag.connections();
    if !bag.connections_complete() || connections.iter().any(|c| c.topic == configured) {
        return Ok(configured);
    }
    let clouds: Vec<&str> = connections
        .iter()
        .filter(|c| c.message_type == "sensor_msgs/PointCloud2")
        .map(|c| c.topic.as_str())
        .collect();
    match clouds.as_slice() {
        [only] => {
            tracing::info!(
                bag = %path.display(),
                configured = %configured,
                using = %only,
                "the bag has no topic named as source.bag.points_topic says, and one PointCloud2 topic: reading that"
            );
            Ok((*only).to_owned())
        }
        [] => Err(PluginError::InvalidInput(format!(
            "{}: no topic {configured:?} and no sensor_msgs/PointCloud2 topic at all; the bag has: {}",
            path.display(),
            connections
                .iter()
                .map(|c| format!("{} ({})", c.topic, c.message_type))
                .collect::<Vec<_>>()
                .join(", ")
        ))),
        several => Err(PluginError::InvalidInput(format!(
            "{}: no topic {configured:?}, and {} PointCloud2 topics to choose from: {}; set \
             source.bag.points_topic to one",
            path.display(),
            several.len(),
            several.join(", ")
        ))),
    }
}

/// How many messages `topic` has (a pass over the bag reading only that topic's records).
fn count_messages(path: &Path, topic: &str) -> PluginResult<usize> {
    let mut bag = Bag::open(path).map_err(bag_error)?;
    bag.require_topic(topic).map_err(bag_error)?;
    bag.select_topics(&[topic.to_owned()]);
    let mut count = 0;
    while bag.next_message().map_err(bag_error)?.is_some() {
        count += 1;
    }
    Ok(count)
}

impl Source for BagSource {
    fn next_scan(&mut self) -> PluginResult<Option<Scan>> {
        while self.skip > 0 {
            if self.assembler.next_scan().map_err(bag_error)?.is_none() {
                return Ok(None);
            }
            self.skip -= 1;
        }
        if self.remaining == 0 {
            return Ok(None);
        }
        let Some(mut scan) = self.assembler.next_scan().map_err(bag_error)? else {
            return Ok(None);
        };
        scan.robot = self.robot;
        scan.sequence = self.sequence;
        self.sequence += 1;
        self.remaining -= 1;
        Ok(Some(scan))
    }

    fn provides_imu(&self) -> bool {
        self.assembler.reads_imu()
    }
}

impl skid_core::PluginParams for BagConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        crate::check_path("path", &self.path)?;
        if self.points_topic.trim().is_empty() {
            return Err(skid_core::ParamError::at(
                "points_topic",
                "empty: name the sensor_msgs/PointCloud2 topic (`skid bag info` lists them)",
            ));
        }
        Ok(())
    }

    fn check_files(&self) -> Result<(), skid_core::ParamError> {
        crate::check_path_exists("path", &self.path)
    }
}
