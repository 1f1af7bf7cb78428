//! Point clouds, scans and keyframes.
//!
//! [`Cloud`] owns its points; [`CloudView`] borrows them from anywhere a `&[Point]` can come from (an owned
//! `Cloud`, a memory-mapped file, or an iceoryx2 shared-memory sample, whose payload dereferences to a
//! slice) so stages read clouds without copying them.

use nalgebra::Point3;
use skid_msgs::{ImuSample, Point, RawPoint};

use crate::{KeyframeId, PluginError, Pose, RobotId};

/// An owned point cloud in some frame the holder knows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Cloud {
    pub points: Vec<Point>,
}

impl Cloud {
    /// A cloud of the given points, taken as they are.
    pub fn new(points: Vec<Point>) -> Self {
        Self { points }
    }

    /// A cloud of the finite points among `points`, and how many non-finite points were dropped.
    pub fn from_finite(points: impl IntoIterator<Item = Point>) -> (Self, usize) {
        let mut dropped = 0;
        let points = points
            .into_iter()
            .filter(|p| {
                let keep = p.is_finite();
                dropped += usize::from(!keep);
                keep
            })
            .collect();
        (Self { points }, dropped)
    }

    /// A borrowed view of the whole cloud.
    pub fn view(&self) -> CloudView<'_> {
        CloudView::new(&self.points)
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

impl From<Vec<Point>> for Cloud {
    fn from(points: Vec<Point>) -> Self {
        Self::new(points)
    }
}

/// A borrowed, read-only view of points; copying the view never copies the points.
#[derive(Clone, Copy, Debug, Default)]
pub struct CloudView<'a> {
    points: &'a [Point],
}

impl<'a> CloudView<'a> {
    /// A view of any point slice: an owned buffer or a shared-memory sample's payload.
    pub const fn new(points: &'a [Point]) -> Self {
        Self { points }
    }

    /// The points.
    pub const fn points(&self) -> &'a [Point] {
        self.points
    }

    pub const fn len(&self) -> usize {
        self.points.len()
    }

    pub const fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Iterates the positions as f64 nalgebra points.
    pub fn positions(&self) -> impl Iterator<Item = Point3<f64>> + 'a {
        self.points
            .iter()
            .map(|p| Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
    }

    /// A copy of the points moved by `target_from_source` (the view's frame being the source frame).
    pub fn transformed(&self, target_from_source: &Pose) -> Cloud {
        let points = self
            .points
            .iter()
            .map(|p| {
                let q = target_from_source * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
                Point::with_intensity(q.x as f32, q.y as f32, q.z as f32, p.intensity)
            })
            .collect();
        Cloud::new(points)
    }

    /// Checks that the cloud is usable by an algorithm: at least `min_points` points, all finite.
    /// `what` names the cloud in the error ("source cloud", "keyframe 3", …).
    pub fn ensure_usable(&self, what: &str, min_points: usize) -> Result<(), PluginError> {
        if let Some(index) = self.points.iter().position(|p| !p.is_finite()) {
            return Err(PluginError::InvalidInput(format!(
                "{what}: point {index} of {} is not finite",
                self.points.len()
            )));
        }
        if self.points.len() < min_points {
            return Err(PluginError::InvalidInput(format!(
                "{what}: {} points, at least {min_points} needed",
                self.points.len()
            )));
        }
        Ok(())
    }
}

impl<'a> From<&'a [Point]> for CloudView<'a> {
    fn from(points: &'a [Point]) -> Self {
        Self::new(points)
    }
}

impl<'a> From<&'a Cloud> for CloudView<'a> {
    fn from(cloud: &'a Cloud) -> Self {
        cloud.view()
    }
}

/// One sweep of a LiDAR as a source delivers it.
#[derive(Clone, Debug, Default)]
pub struct Scan {
    pub robot: RobotId,
    /// Per-robot scan counter, starting at 0.
    pub sequence: u32,
    /// Start of the sweep in nanoseconds; point time offsets are relative to it.
    pub stamp_nanos: u64,
    /// Points in the sensor frame, with per-point time offsets and rings.
    pub points: Vec<RawPoint>,
    /// IMU samples between the previous scan's stamp and this one's, if the source has an IMU.
    pub imu: Vec<ImuSample>,
    /// Ground-truth pose of the sensor at `stamp_nanos`, in the robot's ground-truth world frame.
    pub ground_truth_world_from_sensor: Option<Pose>,
    /// The LiDAR's pose in the IMU's frame (the extrinsic), when the source knows it (a bag's
    /// `/tf_static`, the simulator's mounting); `None` when it is not known.
    pub imu_from_sensor: Option<Pose>,
}

impl Scan {
    /// The positions and intensities, without timing.
    pub fn cloud(&self) -> Cloud {
        Cloud::new(self.points.iter().map(RawPoint::point).collect())
    }
}

/// A keyframe: a deskewed, downsampled cloud in the sensor frame and the sensor pose in the robot's
/// odometry world frame.
#[derive(Clone, Debug, Default)]
pub struct Keyframe {
    pub id: KeyframeId,
    pub stamp_nanos: u64,
    pub world_from_sensor: Pose,
    pub cloud: Cloud,
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn from_finite_drops_and_counts_bad_points() {
        let points = vec![
            Point::new(1.0, 0.0, 0.0),
            Point::new(f32::NAN, 0.0, 0.0),
            Point::new(0.0, f32::INFINITY, 0.0),
        ];
        let (cloud, dropped) = Cloud::from_finite(points);
        assert_eq!(cloud.len(), 1);
        assert_eq!(dropped, 2);
    }

    #[test]
    fn view_borrows_without_copying() {
        let cloud = Cloud::new(vec![Point::new(1.0, 2.0, 3.0); 4]);
        let view = cloud.view();
        assert!(std::ptr::eq(view.points().as_ptr(), cloud.points.as_ptr()));
    }

    #[test]
    fn ensure_usable_names_the_problem() {
        let cloud = Cloud::new(vec![Point::new(1.0, 2.0, 3.0), Point::new(f32::NAN, 0.0, 0.0)]);
        let error = cloud
            .view()
            .ensure_usable("source cloud", 1)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("source cloud") && error.contains("point 1"),
            "{error}"
        );
        let tiny = Cloud::new(vec![Point::new(1.0, 2.0, 3.0)]);
        let error = tiny.view().ensure_usable("target", 10).unwrap_err().to_string();
        assert!(error.contains("at least 10"), "{error}");
    }

    #[test]
    fn transformed_applies_target_from_source() {
        let cloud = Cloud::new(vec![Point::with_intensity(1.0, 0.0, 0.0, 7.0)]);
        let target_from_source = Pose::new(
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let moved = cloud.view().transformed(&target_from_source);
        let p = moved.points[0];
        assert!((p.x - 0.0).abs() < 1e-6 && (p.y - 1.0).abs() < 1e-6 && (p.z - 1.0).abs() < 1e-6);
        assert_eq!(p.intensity, 7.0);
    }
}
