//! The keyframe clouds at the end of a run, placed once. Each keyframe's cloud is moved into its robot's
//! map frame by its optimised pose exactly once; from that one pass come the robot's map (thinned once,
//! for the plots and, placed in robot 0's frame, for `map.ply` and the record's `/map`) and the record's
//! per-keyframe clouds (each thinned at the record's own voxel size).

use skid_core::{Point, Pose};

use crate::host::RobotHost;

/// Edge of the voxels the merged map and each robot's map are thinned with, metres.
pub const MAP_VOXEL_M: f32 = 0.5;

/// Points gathered before an intermediate thinning, so memory stays bounded by the explored volume.
const THIN_ABOVE_POINTS: usize = 4_000_000;

/// One keyframe's cloud in its robot's map frame, thinned for the run record.
pub struct KeyframeCloud {
    pub index: u32,
    pub stamp_nanos: u64,
    pub points: Vec<Point>,
}

/// One robot's keyframe clouds in its own map frame.
pub struct RobotClouds {
    /// The robot's map, thinned at [`MAP_VOXEL_M`].
    pub map: Vec<Point>,
    /// Each keyframe's cloud at the record's voxel size; empty when no record is written.
    pub keyframes: Vec<KeyframeCloud>,
}

/// Places `robot`'s keyframe clouds by their optimised poses, keeping per-keyframe clouds thinned at
/// `record_voxel_m` when a record will be written (`Some`, 0 keeps every point).
pub fn place_clouds(robot: &RobotHost, record_voxel_m: Option<f32>) -> RobotClouds {
    let mut map: Vec<Point> = Vec::new();
    let mut keyframes = Vec::new();
    for (&index, keyframe) in robot.keyframes() {
        let Some(pose) = robot.keyframe_pose(index) else {
            continue;
        };
        let placed = keyframe.cloud.view().transformed(&pose).points;
        if let Some(voxel_m) = record_voxel_m {
            keyframes.push(KeyframeCloud {
                index,
                stamp_nanos: keyframe.stamp_nanos,
                points: skid_geometry::voxel_downsample(&placed, voxel_m),
            });
        }
        map.extend_from_slice(&placed);
        if map.len() > THIN_ABOVE_POINTS {
            map = skid_geometry::voxel_downsample(&map, MAP_VOXEL_M);
        }
    }
    RobotClouds {
        map: skid_geometry::voxel_downsample(&map, MAP_VOXEL_M),
        keyframes,
    }
}

/// The robots' maps merged in robot 0's frame (`frames`, one per robot; robots without a frame there
/// are left out), thinned at [`MAP_VOXEL_M`].
pub fn merge_maps(clouds: &[RobotClouds], frames: &[Option<Pose>]) -> Vec<Point> {
    let mut merged: Vec<Point> = Vec::new();
    for (robot, frame) in clouds.iter().zip(frames) {
        let Some(alpha_from_robot) = frame else { continue };
        merged.extend(
            robot
                .map
                .iter()
                .map(|point| transform_point(alpha_from_robot, point)),
        );
        if merged.len() > THIN_ABOVE_POINTS {
            merged = skid_geometry::voxel_downsample(&merged, MAP_VOXEL_M);
        }
    }
    skid_geometry::voxel_downsample(&merged, MAP_VOXEL_M)
}

fn transform_point(pose: &Pose, point: &Point) -> Point {
    let moved = pose * nalgebra::Point3::new(f64::from(point.x), f64::from(point.y), f64::from(point.z));
    Point::with_intensity(moved.x as f32, moved.y as f32, moved.z as f32, point.intensity)
}

/// The merged map in robot 0's frame, from the robots whose frame is known there (each robot's clouds
/// placed once, as for the run's outputs).
pub fn merged_map(robots: &[RobotHost], frames: &[Option<Pose>]) -> Vec<Point> {
    let clouds: Vec<RobotClouds> = robots.iter().map(|robot| place_clouds(robot, None)).collect();
    merge_maps(&clouds, frames)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;

    #[test]
    fn maps_are_merged_in_robot_zero_frame_and_unplaced_robots_left_out() {
        let robot = |x: f32| RobotClouds {
            map: vec![Point::with_intensity(x, 0.0, 0.0, 1.0)],
            keyframes: Vec::new(),
        };
        let shifted = Pose::from_parts(Translation3::new(10.0, 0.0, 0.0), UnitQuaternion::identity());
        let merged = merge_maps(
            &[robot(1.0), robot(2.0), robot(3.0)],
            &[Some(Pose::identity()), Some(shifted), None],
        );
        let mut xs: Vec<f32> = merged.iter().map(|p| p.x).collect();
        xs.sort_by(f32::total_cmp);
        assert_eq!(xs.len(), 2, "{xs:?}");
        assert!(
            (xs[0] - 1.0).abs() < 1e-3 && (xs[1] - 12.0).abs() < 1e-3,
            "{xs:?}"
        );
        assert!(merged.iter().all(|p| p.intensity == 1.0));
    }
}
