//! Serde forms of poses and information matrices as they travel between robots, with conversions to
//! the core types (`Pose = Isometry3<f64>`, `Information = Matrix6<f64>` ordered translation then
//! rotation, as in the SKiD-SLAM pose graph of Eq. (4)–(6) of the paper).

use serde::{Deserialize, Serialize};
use skid_core::pose::{information_from_wire, information_to_wire, pose_from_wire, pose_to_wire};
use skid_core::{Information, Pose};
use skid_msgs::{Information6, PoseWire};

/// Largest deviation of a received quaternion's norm from 1 that is still accepted (it is then
/// re-normalised); anything further off is treated as a corrupted message.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// A rigid transform: translation in metres and a unit quaternion `(x, y, z, w)`, both in f64 so that a
/// pose survives the trip bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseMsg {
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

impl PoseMsg {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        translation_m: [0.0; 3],
        rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
    };

    /// The wire form of `pose`.
    pub fn from_pose(pose: &Pose) -> Self {
        let wire = pose_to_wire(pose);
        Self {
            translation_m: wire.translation_m,
            rotation_xyzw: wire.rotation_xyzw,
        }
    }

    /// The pose, or `None` when a number is not finite or the quaternion is not of unit norm.
    pub fn to_pose(&self) -> Option<Pose> {
        self.is_valid().then(|| {
            pose_from_wire(&PoseWire {
                translation_m: self.translation_m,
                rotation_xyzw: self.rotation_xyzw,
            })
        })?
    }

    /// True when every number is finite and the quaternion norm is within
    /// [`QUATERNION_NORM_TOLERANCE`] of one.
    pub fn is_valid(&self) -> bool {
        let finite = self
            .translation_m
            .iter()
            .chain(&self.rotation_xyzw)
            .all(|v| v.is_finite());
        let norm = self.rotation_xyzw.iter().map(|v| v * v).sum::<f64>().sqrt();
        finite && (norm - 1.0).abs() <= QUATERNION_NORM_TOLERANCE
    }
}

/// A symmetric 6x6 information matrix as its upper triangle, row by row (21 values), in f32: the
/// information is a weight, and seven significant digits are far more than its own accuracy.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct InformationMsg {
    pub upper_row_major: [f32; 21],
}

impl InformationMsg {
    /// The identity information.
    pub fn identity() -> Self {
        Self::from_information(&Information::identity())
    }

    /// The upper triangle of `information` (the lower one is assumed to mirror it).
    pub fn from_information(information: &Information) -> Self {
        let wire = information_to_wire(information);
        let mut upper_row_major = [0.0f32; 21];
        let mut next = 0;
        for row in 0..6 {
            for col in row..6 {
                // Narrowing to f32 is the documented precision of this message.
                upper_row_major[next] = wire.row_major[row * 6 + col] as f32;
                next += 1;
            }
        }
        Self { upper_row_major }
    }

    /// The full symmetric matrix, or `None` when a value is not finite.
    pub fn to_information(&self) -> Option<Information> {
        if !self.is_finite() {
            return None;
        }
        let mut row_major = [0.0f64; 36];
        let mut next = 0;
        for row in 0..6 {
            for col in row..6 {
                let value = f64::from(self.upper_row_major[next]);
                row_major[row * 6 + col] = value;
                row_major[col * 6 + row] = value;
                next += 1;
            }
        }
        Some(information_from_wire(&Information6 { row_major }))
    }

    /// True when every value is finite.
    pub fn is_finite(&self) -> bool {
        self.upper_row_major.iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn pose_round_trip_is_exact() {
        let pose = Pose::new(Vector3::new(1.5, -2.25, 3.0), Vector3::new(0.1, -0.2, 1.3));
        let back = PoseMsg::from_pose(&pose).to_pose().unwrap();
        assert!((back.inverse() * pose).translation.vector.norm() < 1e-12);
        assert!((back.inverse() * pose).rotation.angle() < 1e-12);
    }

    #[test]
    fn invalid_poses_are_refused() {
        let mut nan = PoseMsg::IDENTITY;
        nan.translation_m[1] = f64::NAN;
        assert!(nan.to_pose().is_none());
        let mut scaled = PoseMsg::IDENTITY;
        scaled.rotation_xyzw[3] = 1.5;
        assert!(scaled.to_pose().is_none());
    }

    #[test]
    fn information_round_trip_keeps_symmetry() {
        let mut information = Information::identity() * 100.0;
        information[(0, 4)] = 3.0;
        information[(4, 0)] = 3.0;
        let back = InformationMsg::from_information(&information)
            .to_information()
            .unwrap();
        assert_eq!(back[(4, 0)], 3.0);
        assert_eq!(back[(0, 4)], 3.0);
        assert_eq!(back[(5, 5)], 100.0);
        let mut bad = InformationMsg::identity();
        bad.upper_row_major[7] = f32::INFINITY;
        assert!(bad.to_information().is_none());
    }
}
