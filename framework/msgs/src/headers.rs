//! Headers that travel in front of a point slice or a descriptor: who, when, which and where.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::wire_type;

/// A rigid transform on the wire: translation in metres and a unit quaternion `(x, y, z, w)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/PoseWire@1"))]
pub struct PoseWire {
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}
wire_type!(PoseWire, "skid/PoseWire@1");

impl PoseWire {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        translation_m: [0.0; 3],
        rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
    };

    /// True when every number is finite and the quaternion has unit norm (within 1e-6).
    pub fn is_valid(&self) -> bool {
        let finite = self
            .translation_m
            .iter()
            .chain(&self.rotation_xyzw)
            .all(|v| v.is_finite());
        let norm_sq: f64 = self.rotation_xyzw.iter().map(|v| v * v).sum();
        finite && (norm_sq - 1.0).abs() < 1e-6
    }
}

impl Default for PoseWire {
    fn default() -> Self {
        Self::IDENTITY
    }
}

/// Header of a point cloud (a scan or any other cloud) placed in front of its points.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/CloudHeader@1"))]
pub struct CloudHeader {
    /// Acquisition time in nanoseconds (start of the sweep for scans).
    pub stamp_nanos: u64,
    pub robot_id: u32,
    /// Per-robot, per-stream sequence number, increasing by one per message.
    pub sequence: u32,
    /// Number of points that follow the header.
    pub point_count: u32,
    pub reserved: u32,
    /// Pose of the sensor in the robot's world (odometry) frame at `stamp_nanos`.
    pub world_from_sensor: PoseWire,
}
wire_type!(CloudHeader, "skid/CloudHeader@1");

/// Header of a keyframe: a deskewed, voxel-downsampled cloud in the sensor frame and its pose.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/KeyframeHeader@1"))]
pub struct KeyframeHeader {
    pub stamp_nanos: u64,
    pub robot_id: u32,
    /// Keyframe index within the robot's trajectory, starting at 0.
    pub sequence: u32,
    pub point_count: u32,
    pub reserved: u32,
    pub world_from_sensor: PoseWire,
}
wire_type!(KeyframeHeader, "skid/KeyframeHeader@1");

/// Header of a global descriptor; `value_count` f32 values follow it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/DescriptorHeader@1"))]
pub struct DescriptorHeader {
    pub stamp_nanos: u64,
    pub robot_id: u32,
    /// Index of the keyframe this descriptor describes.
    pub sequence: u32,
    /// Number of points in the keyframe that was described.
    pub point_count: u32,
    /// Number of f32 values in the descriptor.
    pub value_count: u32,
    /// Name of the descriptor kind, NUL-padded ASCII (for example `solid`).
    pub kind: [u8; 16],
    pub world_from_sensor: PoseWire,
}
wire_type!(DescriptorHeader, "skid/DescriptorHeader@1");

impl DescriptorHeader {
    /// Stores `kind` as NUL-padded ASCII, truncated to 16 bytes.
    pub fn set_kind(&mut self, kind: &str) {
        self.kind = [0; 16];
        for (slot, byte) in self.kind.iter_mut().zip(kind.bytes()) {
            *slot = byte;
        }
    }

    /// The descriptor kind as a string (up to the first NUL); invalid UTF-8 reads as empty.
    pub fn kind(&self) -> &str {
        let end = self.kind.iter().position(|&b| b == 0).unwrap_or(self.kind.len());
        std::str::from_utf8(&self.kind[..end]).unwrap_or("")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn descriptor_kind_round_trips_and_truncates() {
        let mut header = DescriptorHeader::default();
        header.set_kind("solid");
        assert_eq!(header.kind(), "solid");
        header.set_kind("a_much_longer_name_than_sixteen");
        assert_eq!(header.kind(), "a_much_longer_na");
    }

    #[test]
    fn pose_validity() {
        assert!(PoseWire::IDENTITY.is_valid());
        let bad = PoseWire {
            translation_m: [f64::NAN, 0.0, 0.0],
            ..PoseWire::IDENTITY
        };
        assert!(!bad.is_valid());
        let unnormalised = PoseWire {
            rotation_xyzw: [0.0, 0.0, 0.0, 2.0],
            ..PoseWire::IDENTITY
        };
        assert!(!unnormalised.is_valid());
    }
}
