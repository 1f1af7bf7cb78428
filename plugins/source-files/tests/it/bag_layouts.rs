//! The `bag` source on bags written by the independent `rosbags`/`mcap` Python libraries
//! (`framework/bag/tests/fixtures/make_bags.py`): every driver layout and Livox's CustomMsg as the points
//! topic, ground truth from Odometry, PoseStamped or `/tf` filtered by frame, IMU samples per scan, in
//! ROS 1 and ROS 2 containers.

use crate::generated;

use generated::{CLOUDS, IMU_PER_CLOUD, fixtures};
use skid_core::slots::Source;
use skid_core::{PluginContext, Scan};
use skid_source_files::{BagConfig, BagSource};

fn scans(bag: &str, points: &str, ground_truth: &str, frame: &str) -> Vec<Scan> {
    let config = BagConfig {
        path: fixtures().join(bag),
        points_topic: points.to_owned(),
        imu_topic: "/imu".to_owned(),
        ground_truth_topic: ground_truth.to_owned(),
        ground_truth_frame: frame.to_owned(),
        drop_zero_points: false,
        ..BagConfig::default()
    };
    let mut source = BagSource::open(config, &PluginContext::default()).unwrap();
    let mut scans = Vec::new();
    while let Some(scan) = source.next_scan().unwrap() {
        scans.push(scan);
    }
    scans
}

#[test]
fn every_points_topic_and_ground_truth_kind_makes_scans() {
    for bag in ["lz4.bag", "ros2_mcap"] {
        let reference = scans(bag, "/velodyne/points", "/odom", "");
        for (points, ground_truth, frame) in [
            ("/ouster/points", "/pose", ""),
            ("/hesai/points", "/tf", "lidar"),
            ("/livox/points", "/odom", ""),
            ("/livox/custom", "/tf", "lidar"),
            ("/plain64be/points", "/pose", ""),
        ] {
            let got = scans(bag, points, ground_truth, frame);
            assert_eq!(got.len(), CLOUDS, "{bag} {points}");
            for (index, (scan, reference)) in got.iter().zip(&reference).enumerate() {
                let context = format!("{bag} {points} scan {index}");
                assert_eq!(scan.stamp_nanos, reference.stamp_nanos, "{context}");
                let expected = generated::expected_rows(
                    if points == "/livox/custom" {
                        "livox_custom"
                    } else {
                        &points[1..points.len() - 7]
                    },
                    index,
                );
                assert_eq!(scan.points.len(), expected.len(), "{context}");
                // IMU samples come 20 per scan period, the first ones after the scan stamp.
                let imu_expected = if index == 0 { 0 } else { IMU_PER_CLOUD };
                assert_eq!(scan.imu.len(), imu_expected, "{context}");
                let truth = scan.ground_truth_world_from_sensor.unwrap();
                let expected_truth = reference.ground_truth_world_from_sensor.unwrap();
                assert!(
                    (truth.inverse() * expected_truth).translation.vector.norm() < 1e-9,
                    "{context}"
                );
            }
        }
    }
}

#[test]
fn a_tf_ground_truth_without_a_frame_is_explained() {
    let config = BagConfig {
        path: fixtures().join("lz4.bag"),
        points_topic: "/velodyne/points".to_owned(),
        imu_topic: String::new(),
        ground_truth_topic: "/tf".to_owned(),
        ..BagConfig::default()
    };
    let mut source = BagSource::open(config, &PluginContext::default()).unwrap();
    let error = loop {
        match source.next_scan() {
            Ok(Some(_)) => {}
            Ok(None) => panic!("the bag ended without an error"),
            Err(error) => break error.to_string(),
        }
    };
    assert!(
        error.contains("ground_truth_frame") && error.contains("lz4.bag") && error.contains("/tf"),
        "{error}"
    );
}

#[test]
fn the_lidar_to_imu_extrinsic_comes_from_tf_static() {
    for bag in ["lz4.bag", "ros2_mcap"] {
        // The fixture's `/tf_static` places `lidar` 0.1 m ahead of and 0.2 m above `imu_link`.
        let got = scans(bag, "/velodyne/points", "/odom", "");
        for (index, scan) in got.iter().enumerate() {
            let extrinsic = scan
                .imu_from_sensor
                .unwrap_or_else(|| panic!("{bag} scan {index}: no extrinsic"));
            let t = extrinsic.translation.vector;
            assert!(
                (t - nalgebra::Vector3::new(0.1, 0.0, 0.2)).norm() < 1e-12,
                "{bag}: {t:?}"
            );
            assert!(extrinsic.rotation.angle() < 1e-12);
        }
        // Livox's frame is not in the static tree: no extrinsic rather than a wrong one.
        let livox = scans(bag, "/livox/custom", "/odom", "");
        assert!(livox.iter().all(|scan| scan.imu_from_sensor.is_none()), "{bag}");
    }
}
