//! Identifiers of robots, keyframes and loop closures.

use std::fmt;

use serde::{Deserialize, Serialize};

/// A robot in the fleet. Robot ids are small, dense integers starting at 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct RobotId(pub u32);

impl fmt::Display for RobotId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "robot{}", self.0)
    }
}

/// A keyframe: the robot that took it and its index along that robot's trajectory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct KeyframeId {
    pub robot: RobotId,
    pub index: u32,
}

impl KeyframeId {
    /// The keyframe `index` of robot `robot`.
    pub const fn new(robot: u32, index: u32) -> Self {
        Self {
            robot: RobotId(robot),
            index,
        }
    }
}

impl fmt::Display for KeyframeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/kf{}", self.robot, self.index)
    }
}

/// A loop closure candidate or accepted loop, unique within one robot's host.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct LoopId(pub u64);

impl fmt::Display for LoopId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "loop{}", self.0)
    }
}
