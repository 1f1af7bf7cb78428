//! Poses and information matrices, and their conversions to and from the wire types.
//!
//! Naming convention: a transform is named `a_from_b`, so `a_from_b * b_from_c = a_from_c` and
//! `world_from_sensor * p_sensor = p_world`.

use nalgebra::{Isometry3, Matrix6, Quaternion, Translation3, UnitQuaternion};
use skid_msgs::{Information6, PoseWire};

/// A rigid transform in SE(3).
pub type Pose = Isometry3<f64>;

/// A 6x6 information matrix ordered (translation x, y, z, rotation x, y, z).
pub type Information = Matrix6<f64>;

/// Converts a pose to its wire form.
pub fn pose_to_wire(pose: &Pose) -> PoseWire {
    let q = pose.rotation.quaternion();
    PoseWire {
        translation_m: [pose.translation.x, pose.translation.y, pose.translation.z],
        rotation_xyzw: [q.i, q.j, q.k, q.w],
    }
}

/// Converts a wire pose back, or `None` when it holds non-finite numbers or a zero quaternion.
/// The quaternion is re-normalised.
pub fn pose_from_wire(wire: &PoseWire) -> Option<Pose> {
    let all_finite = wire
        .translation_m
        .iter()
        .chain(&wire.rotation_xyzw)
        .all(|v| v.is_finite());
    let [x, y, z, w] = wire.rotation_xyzw;
    let quaternion = Quaternion::new(w, x, y, z);
    if !all_finite || quaternion.norm() < 1e-9 {
        return None;
    }
    let [tx, ty, tz] = wire.translation_m;
    Some(Isometry3::from_parts(
        Translation3::new(tx, ty, tz),
        UnitQuaternion::from_quaternion(quaternion),
    ))
}

/// Converts an information matrix to its row-major wire form.
pub fn information_to_wire(information: &Information) -> Information6 {
    let mut row_major = [0.0; 36];
    for row in 0..6 {
        for col in 0..6 {
            row_major[row * 6 + col] = information[(row, col)];
        }
    }
    Information6 { row_major }
}

/// Converts a row-major wire information matrix back.
pub fn information_from_wire(wire: &Information6) -> Information {
    Matrix6::from_row_slice(&wire.row_major)
}

/// True when every component of the pose (translation and quaternion) is finite.
pub fn is_finite(pose: &Pose) -> bool {
    pose.translation
        .vector
        .iter()
        .chain(pose.rotation.coords.iter())
        .all(|v| v.is_finite())
}

/// Rotation angle of a pose in radians, in [0, π].
pub fn rotation_angle_rad(pose: &Pose) -> f64 {
    pose.rotation.angle()
}

/// True when `now` lies farther than `metres` or turns farther than `radians` from `before`.
pub fn moved_beyond(before: &Pose, now: &Pose, metres: f64, radians: f64) -> bool {
    let change = before.inverse() * now;
    change.translation.vector.norm() > metres || change.rotation.angle() > radians
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn wire_round_trip_preserves_the_pose() {
        let pose = Pose::new(Vector3::new(1.0, -2.0, 3.5), Vector3::new(0.1, -0.4, 2.0));
        let back = pose_from_wire(&pose_to_wire(&pose)).unwrap();
        assert!((back.inverse() * pose).translation.vector.norm() < 1e-12);
        assert!((back.inverse() * pose).rotation.angle() < 1e-12);
    }

    #[test]
    fn moved_beyond_compares_the_relative_pose_with_both_bounds() {
        let before = Pose::new(Vector3::new(10.0, 0.0, 0.0), Vector3::z() * 90f64.to_radians());
        // 0.5 m along the turned x axis, i.e. along the world's y axis.
        let near = before * Pose::new(Vector3::new(0.5, 0.0, 0.0), Vector3::zeros());
        assert!(!moved_beyond(&before, &near, 1.0, 0.1));
        assert!(moved_beyond(&before, &near, 0.4, 0.1));
        let turned = before * Pose::new(Vector3::zeros(), Vector3::z() * 0.2);
        assert!(!moved_beyond(&before, &turned, 1.0, 0.3));
        assert!(moved_beyond(&before, &turned, 1.0, 0.1));
        assert!(!moved_beyond(&before, &before, 1e-9, 1e-9));
    }

    #[test]
    fn invalid_wire_poses_are_refused() {
        let nan = PoseWire {
            translation_m: [f64::NAN, 0.0, 0.0],
            ..PoseWire::IDENTITY
        };
        assert!(pose_from_wire(&nan).is_none());
        let zero = PoseWire {
            rotation_xyzw: [0.0; 4],
            ..PoseWire::IDENTITY
        };
        assert!(pose_from_wire(&zero).is_none());
    }

    #[test]
    fn information_round_trip() {
        let mut info = Information::identity() * 3.0;
        info[(0, 5)] = 0.25;
        info[(5, 0)] = 0.25;
        assert_eq!(information_from_wire(&information_to_wire(&info)), info);
    }
}
