//! The `ros2` source receives scans live from an independent ROS 2 publisher: a Python process
//! (`tests/fixtures/publish_ros2.py`, eclipse-zenoh + rosbags' CDR serializer, run with `$SKID_PYTHON`)
//! that publishes PointCloud2 and Imu under rmw_zenoh's key expressions with its attachment.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.

use std::path::Path;
use std::process::Command;

use skid_core::slots::Source;
use skid_core::{PluginContext, RobotId};
use skid_source_ros2::{Ros2Config, Ros2Source};

#[test]
fn scans_arrive_live_from_an_rmw_zenoh_publisher() {
    let port = skid_testkit::net::free_tcp_ports::<1>()[0];
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let config = Ros2Config {
        points_topic: "/robot{robot}/points".to_owned(),
        imu_topic: "/robot{robot}/imu".to_owned(),
        connect: Vec::new(),
        listen: vec![endpoint.clone()],
        idle_timeout_s: 15.0,
        ..Ros2Config::default()
    };
    let context = PluginContext {
        robot: RobotId(1),
        fleet_size: 2,
        ..PluginContext::default()
    };
    let mut source = Ros2Source::open(config, &context).unwrap();
    let expected_dir = tempfile::tempdir().unwrap();
    let python = std::env::var("SKID_PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/publish_ros2.py");
    let mut publisher = Command::new(&python)
        .arg(&script)
        .arg(&endpoint)
        .arg("robot1")
        .arg("5")
        .arg(expected_dir.path())
        .spawn()
        .unwrap_or_else(|e| panic!("{python}: {e} (SKID_PYTHON must have eclipse-zenoh, rosbags, numpy)"));
    let mut scans = Vec::new();
    while let Some(scan) = source.next_scan().unwrap() {
        scans.push(scan);
        if scans.len() == 5 {
            break;
        }
    }
    let status = publisher.wait().unwrap();
    assert!(
        status.success(),
        "the publisher failed (needs eclipse-zenoh, rosbags, numpy in SKID_PYTHON)"
    );
    assert_eq!(scans.len(), 5);
    for (index, scan) in scans.iter().enumerate() {
        assert_eq!(scan.robot, RobotId(1));
        assert_eq!(scan.sequence as usize, index);
        let bytes = std::fs::read(expected_dir.path().join(format!("{index}.f32"))).unwrap();
        let rows: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        assert_eq!(scan.points.len(), rows.len() / 6, "scan {index}");
        for (point, row) in scan.points.iter().zip(rows.chunks_exact(6)) {
            assert_eq!(
                [point.x, point.y, point.z, point.intensity, point.time_offset_s],
                row[..5]
            );
            assert_eq!(f32::from(point.ring), row[5]);
        }
        if index > 0 {
            assert_eq!(
                scan.imu.len(),
                10,
                "scan {index}: the IMU samples since the previous scan"
            );
            assert!(scan.imu.iter().all(|s| (s.accel_mps2[2] - 9.81).abs() < 1e-12));
        }
    }
}

#[test]
fn bad_parameters_are_refused_before_connecting() {
    let context = PluginContext::default();
    let error = Ros2Source::open(
        Ros2Config {
            connect: Vec::new(),
            listen: Vec::new(),
            ..Ros2Config::default()
        },
        &context,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(error.contains("ros2") && error.contains("endpoints"), "{error}");
    let error = Ros2Source::open(
        Ros2Config {
            idle_timeout_s: f64::NAN,
            ..Ros2Config::default()
        },
        &context,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(error.contains("idle_timeout_s"), "{error}");
}
