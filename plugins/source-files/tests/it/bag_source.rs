//! The `bag` source on the shared KITTI 00 bags (`$SKID_DATA_DIR/kitti_00_rosbags`, written by the
//! independent `rosbags` library): the same scans, ground truth and stamps as the `kitti` source on
//! the KITTI folder, IMU samples attached to the scans they precede, robots split from one recording,
//! and clear errors for wrong topics.

use std::path::PathBuf;

use skid_core::slots::Source;
use skid_core::{PluginContext, RobotId, Scan};
use skid_source_files::{BagConfig, BagSource, KittiConfig, KittiSource};

const ROS1_BAG: &str = "kitti_00_rosbags/kitti00_velodyne_ros1-lz4.bag";
const MCAP_BAG: &str = "kitti_00_rosbags/kitti00_velodyne_mcap";

fn data(relative: &str) -> PathBuf {
    skid_io::data_path(relative).unwrap()
}

fn drain(source: &mut dyn Source) -> Vec<Scan> {
    let mut scans = Vec::new();
    while let Some(scan) = source.next_scan().unwrap() {
        scans.push(scan);
    }
    scans
}

fn kitti_scans() -> Vec<Scan> {
    let config = KittiConfig {
        path: data("kitti_00_lidar_frames_0000_0015"),
        max_scans: 8,
        ..KittiConfig::default()
    };
    drain(&mut KittiSource::open(config, &PluginContext::default()).unwrap())
}

#[test]
fn both_bags_give_the_kitti_scans_with_imu_and_ground_truth() {
    let kitti = kitti_scans();
    for bag in [ROS1_BAG, MCAP_BAG] {
        let config = BagConfig {
            path: data(bag),
            ..BagConfig::default()
        };
        let mut source = BagSource::open(config.clone(), &PluginContext::default()).unwrap();
        assert_eq!(skid_testkit::source::check_source(&mut source, 100), 8, "{bag}");
        let scans = drain(&mut BagSource::open(config, &PluginContext::default()).unwrap());
        assert_eq!(scans.len(), 8);
        let imu_total: usize = scans.iter().map(|s| s.imu.len()).sum();
        // 70 samples: those after the last scan's stamp belong to no scan.
        assert!((60..=70).contains(&imu_total), "{bag}: {imu_total} IMU samples");
        for (index, (scan, expected)) in scans.iter().zip(&kitti).enumerate() {
            assert_eq!(scan.points.len(), expected.points.len(), "{bag} scan {index}");
            assert!(
                scan.points
                    .iter()
                    .zip(&expected.points)
                    .all(|(a, b)| a.x == b.x && a.y == b.y && a.z == b.z)
            );
            // Stamps: the bags start on the recording day; the spacing is KITTI's times.txt.
            let bag_dt = (scan.stamp_nanos - scans[0].stamp_nanos) as f64;
            let kitti_dt = (expected.stamp_nanos - kitti[0].stamp_nanos) as f64;
            assert!((bag_dt - kitti_dt).abs() < 2e3, "{bag} scan {index}");
            if index > 0 {
                assert!(!scan.imu.is_empty(), "{bag} scan {index} has no IMU samples");
                let previous = scans[index - 1].stamp_nanos;
                assert!(
                    scan.imu
                        .iter()
                        .all(|s| s.stamp_nanos > previous && s.stamp_nanos <= scan.stamp_nanos)
                );
            }
            // The bag's ground truth is KITTI's poses_velodyne.txt as quaternions; that file's rotation
            // matrices are orthonormal only to their printed digits (determinants 0.9999999), and their
            // quaternions differ from them by up to 5.5e-4 rad (measured with rosbags), hence 1e-3 rad.
            let relative = |scans: &[Scan], i: usize| {
                scans[0].ground_truth_world_from_sensor.unwrap().inverse()
                    * scans[i].ground_truth_world_from_sensor.unwrap()
            };
            let error = relative(&scans, index).inverse() * relative(&kitti, index);
            assert!(
                error.translation.vector.norm() < 5e-3,
                "{bag} scan {index}: {error:?}"
            );
            assert!(
                error.rotation.angle() < 1e-3,
                "{bag} scan {index}: {}",
                error.rotation.angle()
            );
        }
    }
}

#[test]
fn one_recording_splits_into_robots() {
    let config = BagConfig {
        path: data(ROS1_BAG),
        split: skid_source_files::SplitConfig {
            enabled: true,
            overlap_scans: 1,
        },
        ..BagConfig::default()
    };
    let robot = |index: u32| PluginContext {
        robot: RobotId(index),
        fleet_size: 2,
        ..PluginContext::default()
    };
    let first = drain(&mut BagSource::open(config.clone(), &robot(0)).unwrap());
    let second = drain(&mut BagSource::open(config, &robot(1)).unwrap());
    assert_eq!((first.len(), second.len()), (4, 5));
    assert_eq!(second[0].stamp_nanos, first[3].stamp_nanos);
    assert_eq!(second[0].sequence, 0);
    assert_eq!(second[0].robot, RobotId(1));
}

#[test]
fn wrong_topics_are_refused_with_the_file_and_the_topics_that_exist_unless_the_choice_is_clear() {
    let open = |config: BagConfig| {
        BagSource::open(config, &PluginContext::default())
            .err()
            .unwrap()
            .to_string()
    };
    // A cloud topic of another name than the bag's only PointCloud2 topic: that one is read.
    let mut renamed = BagSource::open(
        BagConfig {
            path: data(MCAP_BAG),
            points_topic: "/os_cloud_node/points".to_owned(),
            max_scans: 2,
            ..BagConfig::default()
        },
        &PluginContext::default(),
    )
    .unwrap();
    assert_eq!(drain(&mut renamed).len(), 2);
    let wrong_type = open(BagConfig {
        path: data(ROS1_BAG),
        points_topic: "/imu/data".to_owned(),
        imu_topic: String::new(),
        ..BagConfig::default()
    });
    assert!(
        wrong_type.contains("sensor_msgs/Imu") && wrong_type.contains("PointCloud2"),
        "{wrong_type}"
    );
    let no_file = open(BagConfig {
        path: PathBuf::from("no/such.bag"),
        ..BagConfig::default()
    });
    assert!(no_file.contains("no/such.bag"), "{no_file}");
}
