//! A session in memory: the robots, their keyframes with poses and descriptors, their pose graphs and
//! where each robot's map frame sits in the session's. Clouds stay on disk and are read one keyframe at
//! a time (`read_keyframe_cloud`), since a fleet's clouds can run to gigabytes.

use skid_core::Pose;
use skid_io::g2o::PoseGraph;

/// The descriptor the keyframes were described with: a session is only useful to a run that describes
/// its own keyframes the same way.
#[derive(Clone, Debug, PartialEq)]
pub struct DescriptorSpec {
    /// The descriptor plugin (`solid`, `scan_context`, …).
    pub kind: String,
    /// The plugin's complete parameters as the run used them.
    pub params: serde_json::Value,
    /// The number of values in each descriptor.
    pub length: usize,
}

/// One keyframe of a robot.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionKeyframe {
    /// The keyframe's index within its robot.
    pub index: u32,
    pub stamp_nanos: u64,
    /// The back-end's estimate of the keyframe's sensor pose in the robot's map frame.
    pub map_from_sensor: Pose,
    /// The odometry's pose of the keyframe, in the odometry's world frame.
    pub odometry_from_sensor: Pose,
    /// The keyframe's true pose in the world, when the source knew it (the simulator, a dataset's
    /// ground truth): what benchmarks judge a relocalisation by.
    pub ground_truth: Option<Pose>,
    /// Points in the keyframe's cloud file.
    pub point_count: usize,
    /// The keyframe's descriptor, when it was described.
    pub descriptor: Option<Vec<f32>>,
}

/// One robot of a session.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionRobot {
    pub robot: u32,
    /// Where the robot's map frame sits in the session's map frame (robot 0's map); `None` when the run
    /// never placed the robot there.
    pub map_from_robot: Option<Pose>,
    /// Its keyframes, by ascending index.
    pub keyframes: Vec<SessionKeyframe>,
    /// Its pose graph (keyframes of several robots, odometry edges and loops), as the run ended.
    pub graph: PoseGraph<Pose>,
}

/// A whole session.
#[derive(Clone, Debug, PartialEq)]
pub struct Session {
    /// The run's name.
    pub name: String,
    /// The SKiD version that wrote it.
    pub skid_version: String,
    /// The descriptor of every keyframe; `None` when the run described none.
    pub descriptor: Option<DescriptorSpec>,
    /// The run's effective configuration as TOML text.
    pub config_toml: String,
    /// The robots, by ascending id.
    pub robots: Vec<SessionRobot>,
}

impl Session {
    /// The robot with id `robot`.
    pub fn robot(&self, robot: u32) -> Option<&SessionRobot> {
        self.robots.iter().find(|r| r.robot == robot)
    }
}

impl SessionRobot {
    /// The keyframe with index `index`.
    pub fn keyframe(&self, index: u32) -> Option<&SessionKeyframe> {
        self.keyframes
            .binary_search_by_key(&index, |k| k.index)
            .ok()
            .and_then(|at| self.keyframes.get(at))
    }

    /// The keyframe's pose in the session's map frame, when the robot is placed there.
    pub fn session_from_sensor(&self, keyframe: &SessionKeyframe) -> Option<Pose> {
        self.map_from_robot.map(|frame| frame * keyframe.map_from_sensor)
    }
}
