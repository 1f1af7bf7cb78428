//! Relative-pose measurements between keyframes: odometry edges and loop closures.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::{PoseWire, wire_type};

/// A 6x6 information matrix stored row-major, ordered (translation x, y, z, rotation x, y, z).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/Information6@1"))]
pub struct Information6 {
    pub row_major: [f64; 36],
}
wire_type!(Information6, "skid/Information6@1");

impl Information6 {
    /// The identity information (unit weight on every axis).
    pub const IDENTITY: Self = {
        let mut row_major = [0.0; 36];
        let mut i = 0;
        while i < 6 {
            row_major[i * 6 + i] = 1.0;
            i += 1;
        }
        Self { row_major }
    };
}

impl Default for Information6 {
    fn default() -> Self {
        Self::IDENTITY
    }
}

/// Relative motion between two consecutive keyframes of one robot.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/OdometryEdge@1"))]
pub struct OdometryEdge {
    pub robot_id: u32,
    /// Keyframe index of the earlier (target) keyframe.
    pub target_sequence: u32,
    /// Keyframe index of the later (source) keyframe.
    pub source_sequence: u32,
    pub reserved: u32,
    /// Pose of the source keyframe in the target keyframe's frame.
    pub target_from_source: PoseWire,
    pub information: Information6,
}
wire_type!(OdometryEdge, "skid/OdometryEdge@1");

/// A loop closure: the relative pose between two keyframes of the same or of two robots.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/LoopMeasurement@1"))]
pub struct LoopMeasurement {
    pub target_robot_id: u32,
    pub target_sequence: u32,
    pub source_robot_id: u32,
    pub source_sequence: u32,
    /// Pose of the source keyframe in the target keyframe's frame.
    pub target_from_source: PoseWire,
    pub information: Information6,
    /// Truncated mean squared error of the alignment in m² (see the verifier); NaN when not computed.
    pub fitness_m2: f64,
    /// Number of inlier correspondences supporting the measurement.
    pub inlier_count: u32,
    pub reserved: u32,
}
wire_type!(LoopMeasurement, "skid/LoopMeasurement@1");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identity_information_is_diagonal() {
        let info = Information6::IDENTITY;
        for row in 0..6 {
            for col in 0..6 {
                let expected = if row == col { 1.0 } else { 0.0 };
                assert_eq!(info.row_major[row * 6 + col], expected);
            }
        }
    }
}
