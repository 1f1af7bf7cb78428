//! The `ros2` source: one robot's scans live from a running ROS 2 system whose nodes use `rmw_zenoh`
//! (the Zenoh RMW shipped with ROS 2 Jazzy and later), spoken directly with the `zenoh` crate — no ROS
//! installation. The topics are read as the `bag` source reads a recording (`sensor_msgs/PointCloud2` in
//! any driver layout or Livox `CustomMsg` — the latter needs a definition, so live only PointCloud2 —,
//! `sensor_msgs/Imu`, ground truth when a topic carries it), through the same scan assembly.
//!
//! Like the `zenoh` transport this is a plugin that talks to a network; it connects to a zenoh router
//! (`rmw_zenohd`, `tcp/127.0.0.1:7447` by default) or directly to peers.

mod live;

pub use live::{LiveTopics, topic_key, type_from_dds};

use std::time::Duration;

use serde::{Deserialize, Serialize};
use skid_core::slots::Source;
use skid_core::{PluginContext, PluginEntry, PluginError, PluginResult, Registry, RobotId, Scan};
use skid_source_files::bag_error;
use skid_source_files::bag_stream::{ScanAssembler, Topics};
use zenoh::Wait;

/// Parameters of the `ros2` source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct Ros2Config {
    /// The `sensor_msgs/PointCloud2` topic; `{robot}` is replaced by the robot index.
    pub points_topic: String,
    /// The `sensor_msgs/Imu` topic; empty for none.
    pub imu_topic: String,
    /// A ground-truth topic (`nav_msgs/Odometry`, `geometry_msgs/PoseStamped`, `/tf`); empty for none.
    pub ground_truth_topic: String,
    /// On a `/tf` ground-truth topic, the child frame to follow.
    pub ground_truth_frame: String,
    /// The ROS domain id (`ROS_DOMAIN_ID`), the first chunk of rmw_zenoh's keys.
    pub domain_id: u32,
    /// Zenoh endpoints to connect to: the router (`rmw_zenohd`) or a peer.
    pub connect: Vec<String>,
    /// Zenoh endpoints to listen on (for peers that connect to this robot); usually empty.
    pub listen: Vec<String>,
    /// The source ends after this long without a message, in seconds; 0 waits for ever.
    pub idle_timeout_s: f64,
    /// Stop after this many scans; 0 reads until the topics go quiet.
    pub max_scans: usize,
    /// Received bytes waiting to be assembled; beyond this new messages are dropped and counted.
    pub max_queued_bytes: usize,
    /// Drop `(0, 0, 0)` "no return" points.
    pub drop_zero_points: bool,
}

impl Default for Ros2Config {
    fn default() -> Self {
        Self {
            points_topic: "/points".to_owned(),
            imu_topic: "/imu".to_owned(),
            ground_truth_topic: String::new(),
            ground_truth_frame: String::new(),
            domain_id: 0,
            connect: vec!["tcp/127.0.0.1:7447".to_owned()],
            listen: Vec::new(),
            idle_timeout_s: 10.0,
            max_scans: 0,
            max_queued_bytes: 256 << 20,
            drop_zero_points: true,
        }
    }
}

impl Ros2Config {
    fn validate(&self) -> PluginResult<()> {
        let bad = |message: &str| Err(PluginError::failed("ros2", message));
        if self.points_topic.trim().is_empty() {
            return bad("points_topic is empty");
        }
        if !(self.idle_timeout_s.is_finite() && self.idle_timeout_s >= 0.0) {
            return bad("idle_timeout_s must be a finite number of seconds, 0 or more");
        }
        if self.connect.is_empty() && self.listen.is_empty() {
            return bad("neither `connect` nor `listen` endpoints are given: nothing would be received");
        }
        if self.max_queued_bytes < (1 << 20) {
            return bad("max_queued_bytes must hold at least one cloud (1 MiB or more)");
        }
        Ok(())
    }

    fn zenoh_config(&self) -> PluginResult<zenoh::Config> {
        skid_transport_zenoh::peer::peer_config(&self.listen, &self.connect, &[])
            .map_err(|error| PluginError::failed("ros2", error))
    }
}

/// Reads one robot's scans from live topics.
pub struct Ros2Source {
    robot: RobotId,
    assembler: ScanAssembler,
    remaining: usize,
    sequence: u32,
}

impl Ros2Source {
    /// Opens a zenoh session and subscribes to the robot's topics.
    pub fn open(config: Ros2Config, context: &PluginContext) -> PluginResult<Self> {
        config.validate()?;
        let robot_text = context.robot.0.to_string();
        let per_robot = |text: &str| text.replace("{robot}", &robot_text);
        let topics = Topics {
            points: per_robot(&config.points_topic),
            imu: Some(per_robot(&config.imu_topic)).filter(|t| !t.is_empty()),
            ground_truth: Some(per_robot(&config.ground_truth_topic)).filter(|t| !t.is_empty()),
            ground_truth_frame: config.ground_truth_frame.clone(),
            // rmw_zenoh serves `/tf_static` to late joiners only through a query; not read live.
            tf_static: None,
        };
        let session = zenoh::open(config.zenoh_config()?)
            .wait()
            .map_err(|e| PluginError::Failed {
                plugin: "ros2".into(),
                message: format!("opening the zenoh session: {e}"),
            })?;
        let mut names = vec![topics.points.clone()];
        names.extend(topics.imu.iter().cloned());
        names.extend(topics.ground_truth.iter().cloned());
        let idle = (config.idle_timeout_s > 0.0).then(|| Duration::from_secs_f64(config.idle_timeout_s));
        let live = LiveTopics::subscribe(session, config.domain_id, &names, config.max_queued_bytes, idle)
            .map_err(|message| PluginError::Failed {
                plugin: "ros2".into(),
                message,
            })?;
        let label = live.label();
        let assembler =
            ScanAssembler::new(Box::new(live), label, topics, config.drop_zero_points).map_err(bag_error)?;
        Ok(Self {
            robot: context.robot,
            assembler,
            remaining: if config.max_scans == 0 {
                usize::MAX
            } else {
                config.max_scans
            },
            sequence: 0,
        })
    }
}

impl Source for Ros2Source {
    fn next_scan(&mut self) -> PluginResult<Option<Scan>> {
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

/// Registers `ros2` in the source slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.source.register(PluginEntry::new(
        "ros2",
        "live ROS 2 topics from rmw_zenoh nodes (PointCloud2, Imu, ground truth) over zenoh, no ROS install",
        |config: Ros2Config, context: &PluginContext| {
            Ok(Box::new(Ros2Source::open(config, context)?) as Box<dyn Source>)
        },
    )?)?;
    Ok(())
}

impl skid_core::PluginParams for Ros2Config {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate().map_err(skid_core::ParamError::from_plugin_error)
    }
}
