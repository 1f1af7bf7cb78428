//! The keyframe policy: a scan becomes a keyframe when the robot has moved far enough, turned enough,
//! or enough time has passed since the last keyframe.

use serde::{Deserialize, Serialize};
use skid_core::{Cloud, Keyframe, KeyframeId, Point, Pose, RobotId};

use crate::voxel_downsample;

/// Thresholds of the keyframe policy; any one of them fires a keyframe.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct KeyframePolicy {
    /// Distance travelled since the last keyframe, in metres.
    pub distance_m: f64,
    /// Rotation since the last keyframe, in degrees.
    pub angle_deg: f64,
    /// Time since the last keyframe, in seconds; 0 disables the time rule.
    pub interval_s: f64,
}

impl Default for KeyframePolicy {
    fn default() -> Self {
        Self {
            distance_m: 2.0,
            angle_deg: 15.0,
            interval_s: 0.0,
        }
    }
}

/// Tracks the last keyframe and decides on each new pose.
#[derive(Clone, Debug)]
pub struct KeyframeTrigger {
    policy: KeyframePolicy,
    last: Option<(u64, Pose)>,
    count: u32,
}

impl KeyframeTrigger {
    pub fn new(policy: KeyframePolicy) -> Self {
        Self {
            policy,
            last: None,
            count: 0,
        }
    }

    /// Decides whether the scan at `stamp_nanos` with pose `world_from_sensor` is a keyframe, and if so
    /// returns its index (0 for the first scan) and remembers it.
    pub fn check(&mut self, stamp_nanos: u64, world_from_sensor: &Pose) -> Option<u32> {
        let fire = match &self.last {
            None => true,
            Some((last_stamp, last_pose)) => {
                let delta = last_pose.inverse() * world_from_sensor;
                let elapsed_s = stamp_nanos.saturating_sub(*last_stamp) as f64 * 1e-9;
                delta.translation.vector.norm() >= self.policy.distance_m
                    || delta.rotation.angle().to_degrees() >= self.policy.angle_deg
                    || (self.policy.interval_s > 0.0 && elapsed_s >= self.policy.interval_s)
            }
        };
        if !fire {
            return None;
        }
        self.last = Some((stamp_nanos, *world_from_sensor));
        let index = self.count;
        self.count += 1;
        Some(index)
    }

    /// The keyframe of robot `robot`'s scan at `stamp_nanos`, when the policy fires: its cloud is
    /// `points_at_stamp()` (sensor frame at the stamp, built only then) downsampled at `voxel_m`.
    pub fn keyframe(
        &mut self,
        robot: RobotId,
        stamp_nanos: u64,
        world_from_sensor: &Pose,
        voxel_m: f64,
        points_at_stamp: impl FnOnce() -> Vec<Point>,
    ) -> Option<Keyframe> {
        let index = self.check(stamp_nanos, world_from_sensor)?;
        Some(Keyframe {
            id: KeyframeId { robot, index },
            stamp_nanos,
            world_from_sensor: *world_from_sensor,
            cloud: Cloud::new(voxel_downsample(&points_at_stamp(), voxel_m as f32)),
        })
    }
}

impl KeyframePolicy {
    /// Refuses negative or non-finite thresholds (paths relative to the plugin table's `keyframe`).
    pub fn check(&self) -> Result<(), skid_core::ParamError> {
        use skid_core::registry::check::non_negative;
        non_negative("keyframe.distance_m", self.distance_m)?;
        non_negative("keyframe.angle_deg", self.angle_deg)?;
        non_negative("keyframe.interval_s", self.interval_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn fires_on_distance_angle_and_time() {
        let policy = KeyframePolicy {
            distance_m: 1.0,
            angle_deg: 10.0,
            interval_s: 5.0,
        };
        let mut trigger = KeyframeTrigger::new(policy);
        assert_eq!(trigger.check(0, &Pose::identity()), Some(0));
        assert_eq!(
            trigger.check(100_000_000, &Pose::translation(0.5, 0.0, 0.0)),
            None
        );
        assert_eq!(
            trigger.check(200_000_000, &Pose::translation(1.2, 0.0, 0.0)),
            Some(1)
        );
        let turned = Pose::new(
            Vector3::new(1.2, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 11f64.to_radians()),
        );
        assert_eq!(trigger.check(300_000_000, &turned), Some(2));
        assert_eq!(trigger.check(6_000_000_000, &turned), Some(3));
    }
}
