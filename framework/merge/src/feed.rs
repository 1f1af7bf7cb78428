//! A saved robot's keyframes fed to a host in place of its source and odometry: each keyframe, in
//! order, as one registered scan whose pose is the keyframe's optimised pose in the robot's map frame
//! and whose keyframe cloud is the one the session holds. The host describes, queries, registers and
//! verifies them exactly as it does a live robot's.

use std::path::PathBuf;

use skid_core::{Cloud, Keyframe, KeyframeId, PluginError, RobotId, Slot};
use skid_runtime::{FrontEndError, FrontEndFeed, FrontEndOutput, OdometryOutcome};
use skid_session::SessionRobot;

/// Replays one robot of a session folder.
pub struct SessionFeed {
    dir: PathBuf,
    robot: SessionRobot,
    /// The host's robot id (the session's robot keeps its own id on disk).
    host_robot: RobotId,
    next: usize,
}

impl SessionFeed {
    /// A feed of `robot`'s keyframes from the session folder `dir`, as host robot `host_robot`.
    pub fn new(dir: PathBuf, robot: SessionRobot, host_robot: RobotId) -> Self {
        Self {
            dir,
            robot,
            host_robot,
            next: 0,
        }
    }
}

impl FrontEndFeed for SessionFeed {
    fn next(&mut self) -> Result<Option<FrontEndOutput>, FrontEndError> {
        let Some(keyframe) = self.robot.keyframes.get(self.next) else {
            return Ok(None);
        };
        let position = u32::try_from(self.next).map_err(|_| FrontEndError {
            slot: Slot::Source,
            source: PluginError::InvalidInput("more keyframes than a robot can number".into()),
        })?;
        self.next += 1;
        let points = skid_session::read_keyframe_cloud(&self.dir, &self.robot, keyframe).map_err(|e| {
            FrontEndError {
                slot: Slot::Source,
                source: PluginError::InvalidInput(e.to_string()),
            }
        })?;
        let count = points.len();
        // The host numbers a robot's keyframes from 0 without gaps, as an odometry does.
        let replayed = Keyframe {
            id: KeyframeId {
                robot: self.host_robot,
                index: position,
            },
            stamp_nanos: keyframe.stamp_nanos,
            world_from_sensor: keyframe.map_from_sensor,
            cloud: Cloud::new(points),
        };
        Ok(Some(FrontEndOutput {
            sequence: position,
            stamp_nanos: keyframe.stamp_nanos,
            points: count,
            ground_truth: keyframe.ground_truth,
            source_ms: 0.0,
            odometry_ms: 0.0,
            odometry: Some(OdometryOutcome::Registered {
                world_from_sensor: keyframe.map_from_sensor,
                keyframe: Some(replayed),
                degenerate: false,
            }),
        }))
    }
}
