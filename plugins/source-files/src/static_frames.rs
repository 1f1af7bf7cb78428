//! The static transform tree of a recording (`/tf_static`, `tf2_msgs/TFMessage`): transforms between
//! any two frames it connects, found by walking the tree through parents and children. The bag source
//! uses it for the LiDAR→IMU extrinsic (REP 105 frames; a transform's `frame_id` is the parent and its
//! pose places `child_frame_id` in it).

use std::collections::{BTreeMap, VecDeque};

use skid_core::Pose;

/// Static transforms, `parent_from_child` by (parent, child) frame names.
#[derive(Clone, Debug, Default)]
pub struct StaticFrames {
    edges: BTreeMap<String, Vec<(String, Pose)>>,
}

/// Frame names compare without a leading `/` (ROS 1 allowed `/base_link`).
fn normalized(frame: &str) -> String {
    frame.trim_start_matches('/').to_owned()
}

impl StaticFrames {
    /// Adds `parent_from_child`; the tree may be walked either way.
    pub fn insert(&mut self, parent: &str, child: &str, parent_from_child: Pose) {
        let (parent, child) = (normalized(parent), normalized(child));
        self.edges
            .entry(parent.clone())
            .or_default()
            .push((child.clone(), parent_from_child));
        self.edges
            .entry(child)
            .or_default()
            .push((parent, parent_from_child.inverse()));
    }

    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// `target_from_source`, when the tree connects the two frames (identity for the same frame).
    pub fn transform(&self, target: &str, source: &str) -> Option<Pose> {
        let (target, source) = (normalized(target), normalized(source));
        if target == source {
            return Some(Pose::identity());
        }
        // Breadth-first from the target: each reached frame's pose in the target frame.
        let mut target_from: BTreeMap<&str, Pose> = BTreeMap::from([(target.as_str(), Pose::identity())]);
        let mut queue = VecDeque::from([target.as_str()]);
        while let Some(frame) = queue.pop_front() {
            let target_from_frame = target_from[frame];
            for (next, frame_from_next) in self.edges.get(frame).into_iter().flatten() {
                if target_from.contains_key(next.as_str()) {
                    continue;
                }
                let target_from_next = target_from_frame * frame_from_next;
                if *next == source {
                    return Some(target_from_next);
                }
                target_from.insert(next, target_from_next);
                queue.push_back(next);
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn pose(x: f64, y: f64, z: f64, yaw_deg: f64) -> Pose {
        Pose::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
        )
    }

    #[test]
    fn transforms_compose_through_a_common_parent_in_both_directions() {
        let mut frames = StaticFrames::default();
        let base_from_imu = pose(0.1, 0.0, 0.2, 90.0);
        let base_from_lidar = pose(0.0, 0.3, 0.5, -30.0);
        frames.insert("base_link", "imu_link", base_from_imu);
        frames.insert("/base_link", "velodyne", base_from_lidar);
        let imu_from_lidar = frames.transform("imu_link", "velodyne").unwrap();
        let expected = base_from_imu.inverse() * base_from_lidar;
        assert!((imu_from_lidar.to_homogeneous() - expected.to_homogeneous()).norm() < 1e-12);
        let lidar_from_imu = frames.transform("velodyne", "imu_link").unwrap();
        assert!(
            (lidar_from_imu * imu_from_lidar)
                .to_homogeneous()
                .is_identity(1e-12)
        );
        assert_eq!(frames.transform("imu_link", "imu_link"), Some(Pose::identity()));
        assert!(frames.transform("imu_link", "camera").is_none());
    }
}
