//! Small geometric helpers shared by the metrics: the rotation angle of a rotation, finiteness checks
//! on poses, and applying a similarity (Umeyama's Sim(3) result) to a pose the way evo does.

use nalgebra::{Isometry3, Similarity3, Translation3, UnitQuaternion};

use crate::error::EvalError;
use skid_core::Pose;

/// The rotation angle of `rotation` in radians, in `[0, π]`.
///
/// Computed as `2·atan2(|v|, |w|)` from the quaternion, which stays accurate for tiny angles where
/// `acos` of the trace loses half of the digits.
pub fn rotation_angle_rad(rotation: &UnitQuaternion<f64>) -> f64 {
    let q = rotation.quaternion();
    2.0 * q.imag().norm().atan2(q.w.abs())
}

/// The rotation angle of `rotation` in degrees, in `[0, 180]`.
pub fn rotation_angle_deg(rotation: &UnitQuaternion<f64>) -> f64 {
    rotation_angle_rad(rotation).to_degrees()
}

/// True when every number of the pose is finite.
pub fn pose_is_finite(pose: &Pose) -> bool {
    let t = &pose.translation.vector;
    let q = pose.rotation.quaternion();
    t.iter().all(|v| v.is_finite()) && q.coords.iter().all(|v| v.is_finite())
}

/// Returns an error naming the first pose of `poses` with a NaN or infinite number.
pub fn check_poses(what: &'static str, poses: &[Pose]) -> Result<(), EvalError> {
    match poses.iter().position(|p| !pose_is_finite(p)) {
        Some(index) => Err(EvalError::NonFinite { what, index }),
        None => Ok(()),
    }
}

/// Applies `target_from_source` to a pose: the position becomes `s·R·t + t₀` and the orientation `R·R_pose`.
///
/// This is what evo does to an estimate after Umeyama: scale the positions, then transform the poses
/// rigidly; orientations are never scaled.
pub fn apply_similarity(target_from_source: &Similarity3<f64>, pose: &Pose) -> Pose {
    let rigid = &target_from_source.isometry;
    let position = target_from_source.scaling() * pose.translation.vector;
    Isometry3::from_parts(
        Translation3::from(rigid.rotation * position + rigid.translation.vector),
        rigid.rotation * pose.rotation,
    )
}

/// A pose on the ground plane at (x, y), turned by `yaw_deg` (test scenes).
#[cfg(test)]
pub(crate) fn planar_pose(x: f64, y: f64, yaw_deg: f64) -> Pose {
    Pose::from_parts(
        nalgebra::Translation3::new(x, y, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn angle_is_exact_for_small_and_large_rotations() {
        for angle in [0.0, 1e-9, 1e-4, 0.5, 3.0, std::f64::consts::PI] {
            let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle);
            assert!(
                (rotation_angle_rad(&q) - angle).abs() < 1e-15 + 1e-12 * angle,
                "angle {angle}"
            );
            // The inverse rotation has the same angle.
            assert!((rotation_angle_rad(&q.inverse()) - angle).abs() < 1e-12);
        }
    }

    #[test]
    fn similarity_scales_positions_only() {
        let sim = Similarity3::new(
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            2.0,
        );
        let pose = Isometry3::new(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.1));
        let out = apply_similarity(&sim, &pose);
        // 2·Rz(90°)·(1,0,0) + (1,0,0) = (1,2,0).
        assert!((out.translation.vector - Vector3::new(1.0, 2.0, 0.0)).norm() < 1e-12);
        assert!((rotation_angle_rad(&out.rotation) - (std::f64::consts::FRAC_PI_2 + 0.1)).abs() < 1e-12);
        assert!(check_poses("p", &[out]).is_ok());
        let bad = Isometry3::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::zeros());
        assert!(matches!(
            check_poses("p", &[out, bad]),
            Err(EvalError::NonFinite { index: 1, .. })
        ));
    }
}
