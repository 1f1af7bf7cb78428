//! Motion deskewing under a constant-velocity model (as in KISS-ICP, Vizzo et al., RA-L 2023).
//!
//! A spinning LiDAR measures each point at its own time within the sweep; while the robot moves, the
//! raw cloud is distorted. Assuming the motion during this sweep equals `previous_from_current` (the
//! last inter-scan motion) spread uniformly over `scan_period_s`, each point is moved into the sensor
//! frame at the scan stamp.

use nalgebra::Point3;
use skid_core::{Point, Pose, RawPoint};

/// Deskews raw points into the sensor frame at the scan stamp (time offset 0).
///
/// `previous_from_current` is the motion over one scan period, `scan_period_s` its duration. Points with
/// a non-finite position or time offset are dropped.
pub fn deskew_constant_velocity(
    points: &[RawPoint],
    previous_from_current: &Pose,
    scan_period_s: f64,
) -> Vec<Point> {
    let usable = points.iter().filter(|p| p.is_finite());
    if !(scan_period_s.is_finite() && scan_period_s > 0.0) {
        return usable.map(RawPoint::point).collect();
    }
    let identity = Pose::identity();
    usable
        .map(|p| {
            let fraction = f64::from(p.time_offset_s) / scan_period_s;
            // Pose at the point's time expressed in the sensor frame at the stamp.
            let stamp_from_point = identity.lerp_slerp(previous_from_current, fraction);
            let q = stamp_from_point * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
            Point::with_intensity(q.x as f32, q.y as f32, q.z as f32, p.intensity)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn a_point_measured_later_moves_with_the_sensor() {
        // The sensor drives 1 m along x per 0.1 s sweep; a point measured half-way through at x = 10 m
        // in the moving frame lies at x = 10.5 m in the frame at the stamp.
        let motion = Pose::translation(1.0, 0.0, 0.0);
        let raw = [
            RawPoint::new(10.0, 0.0, 0.0, 1.0, 0.05, 0),
            RawPoint::new(5.0, 0.0, 0.0, 1.0, 0.0, 0),
        ];
        let deskewed = deskew_constant_velocity(&raw, &motion, 0.1);
        assert!((deskewed[0].x - 10.5).abs() < 1e-5);
        assert!((deskewed[1].x - 5.0).abs() < 1e-6);
    }

    #[test]
    fn rotation_is_interpolated() {
        let motion = Pose::new(Vector3::zeros(), Vector3::new(0.0, 0.0, 0.2));
        let raw = [RawPoint::new(1.0, 0.0, 0.0, 0.0, 0.1, 0)];
        let deskewed = deskew_constant_velocity(&raw, &motion, 0.1);
        let angle = f64::from(deskewed[0].y).atan2(f64::from(deskewed[0].x));
        assert!((angle - 0.2).abs() < 1e-5);
    }

    #[test]
    fn non_finite_points_are_dropped() {
        let raw = [
            RawPoint::new(f32::NAN, 0.0, 0.0, 0.0, 0.0, 0),
            RawPoint::new(1.0, 0.0, 0.0, 0.0, f32::NAN, 0),
        ];
        assert!(deskew_constant_velocity(&raw, &Pose::identity(), 0.1).is_empty());
    }
}
