//! Front-end slots: where scans come from (source) and how they become poses and keyframes (odometry).

use crate::{Keyframe, PluginResult, Pose, Scan};

/// Produces the scans of one robot, in order.
pub trait Source: Send {
    /// The next scan, or `None` when the sequence has ended.
    fn next_scan(&mut self) -> PluginResult<Option<Scan>>;

    /// Whether the scans carry IMU samples (`Scan::imu`): an IMU is simulated, or an IMU topic is
    /// configured and present. The `auto` odometry runs LiDAR-inertial odometry on such a source.
    fn provides_imu(&self) -> bool {
        false
    }

    /// How many scans remain, when the source knows (files, a fixed simulation length).
    fn remaining_hint(&self) -> Option<usize> {
        None
    }
}

/// Result of registering one scan.
#[derive(Clone, Debug)]
pub struct OdometryUpdate {
    pub stamp_nanos: u64,
    /// Pose of the sensor at the scan stamp in the robot's odometry world frame.
    pub world_from_sensor: Pose,
    /// Motion since the previous scan, `previous_from_current`.
    pub previous_from_current: Pose,
    /// Set when the keyframe policy fired on this scan.
    pub keyframe: Option<Keyframe>,
    /// The scan left at least one direction of the motion weakly constrained or unconstrained, so the
    /// odometry leaned on its motion prior (or the IMU) there: expected on open ground and in long
    /// corridors, and counted per robot in the run summary (`degenerate_scans`). `lio` and `kiss_icp`
    /// test it; odometries that cannot tell (ground truth, C plugins) say `false`.
    pub degenerate: bool,
}

/// Estimates the robot's motion scan by scan and decides which scans become keyframes.
pub trait Odometry: Send {
    /// Registers one scan. Scans arrive in order; a scan the odometry cannot use is an error and leaves
    /// the estimator's state as it was.
    fn register(&mut self, scan: &Scan) -> PluginResult<OdometryUpdate>;
}
