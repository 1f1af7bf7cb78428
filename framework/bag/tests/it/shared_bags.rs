//! The shared KITTI 00 bags (written by the independent `rosbags` library, see
//! `$SKID_DATA_DIR/kitti_00_rosbags/PROVENANCE.md`) decode to exactly the KITTI `.bin` scans they carry,
//! through both the ROS 1 (LZ4 chunks) and the ROS 2 MCAP reader.

use std::path::{Path, PathBuf};

use skid_bag::msgs::motion::{decode_imu, decode_odometry};
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2, raw_points};
use skid_bag::{Bag, Encoding, MessageReader, RawMessage, WireReader};
use skid_io::{CloudReadOptions, data_path, kitti::read_kitti_bin};

fn ros1_bag() -> PathBuf {
    data_path("kitti_00_rosbags/kitti00_velodyne_ros1-lz4.bag").unwrap()
}

fn mcap_bag() -> PathBuf {
    data_path("kitti_00_rosbags/kitti00_velodyne_mcap").unwrap()
}

fn messages(path: &Path, topic: &str) -> Vec<RawMessage> {
    let mut bag = Bag::open(path).unwrap();
    bag.require_topic(topic).unwrap().expect("topic listed up front");
    bag.select_topics(&[topic.to_owned()]);
    let mut messages = Vec::new();
    while let Some(message) = bag.next_message().unwrap() {
        assert_eq!(message.connection.topic, topic);
        messages.push(message);
    }
    messages
}

fn check_clouds_equal_kitti_bins(path: &Path, encoding: Encoding) {
    let clouds = messages(path, "/velodyne_points");
    assert_eq!(clouds.len(), 8);
    for (frame, message) in clouds.iter().enumerate() {
        assert_eq!(message.connection.encoding, encoding);
        assert_eq!(message.connection.message_type, "sensor_msgs/PointCloud2");
        let mut reader = WireReader::new(&message.data, encoding).unwrap();
        let cloud = PointCloud2::decode(&mut reader).unwrap();
        let layout = CloudLayout::detect(&cloud.fields).unwrap();
        assert_eq!(
            layout.describe(),
            "xyz float32, intensity intensity (float32), ring ring (uint16), time time (float32), time in s"
        );
        let decoded = raw_points(&cloud, &layout);
        let bin = data_path(format!("kitti_00_lidar_frames_0000_0015/velodyne/{frame:06}.bin")).unwrap();
        let options = CloudReadOptions {
            drop_zero: false,
            ..CloudReadOptions::default()
        };
        let expected = read_kitti_bin(&bin, options).unwrap();
        assert_eq!(decoded.points.len(), expected.points.len(), "frame {frame}");
        assert_eq!(decoded.dropped_non_finite, 0);
        for (index, (got, want)) in decoded.points.iter().zip(&expected.points).enumerate() {
            assert_eq!(
                (got.x.to_bits(), got.y.to_bits(), got.z.to_bits()),
                (want.x.to_bits(), want.y.to_bits(), want.z.to_bits()),
                "frame {frame} point {index}"
            );
            assert_eq!(
                got.intensity,
                want.intensity * 255.0,
                "frame {frame} point {index}"
            );
            assert!(got.ring < 64, "frame {frame} point {index}: ring {}", got.ring);
            assert!(
                (0.0..=0.1).contains(&got.time_offset_s),
                "frame {frame} point {index}"
            );
        }
        if frame == 0 {
            assert_eq!(decoded.points.len(), 124_668);
        }
    }
}

#[test]
fn ros1_lz4_clouds_equal_the_kitti_scans_bit_for_bit() {
    check_clouds_equal_kitti_bins(&ros1_bag(), Encoding::Ros1);
}

#[test]
fn mcap_clouds_equal_the_kitti_scans_bit_for_bit() {
    check_clouds_equal_kitti_bins(&mcap_bag(), Encoding::Cdr);
}

#[test]
fn imu_and_ground_truth_agree_between_the_two_bags() {
    let kitti_times =
        skid_io::kitti::read_kitti_times(data_path("kitti_00_lidar_frames_0000_0015/times.txt").unwrap())
            .unwrap();
    // The PROVENANCE gives 2011-10-03 (the recording day) + times.txt as the stamps; the time of day
    // in the bags is 13:00 UTC, so the day is checked and the spacing compared with times.txt.
    let day_nanos: u64 = 1_317_600_000 * 1_000_000_000;
    let mut per_bag = Vec::new();
    for path in [ros1_bag(), mcap_bag()] {
        let imu: Vec<_> = messages(&path, "/imu/data")
            .iter()
            .map(|m| decode_imu(&mut WireReader::new(&m.data, m.connection.encoding).unwrap()).unwrap())
            .collect();
        let truth: Vec<_> = messages(&path, "/ground_truth")
            .iter()
            .map(|m| decode_odometry(&mut WireReader::new(&m.data, m.connection.encoding).unwrap()).unwrap())
            .collect();
        let cloud_stamps: Vec<u64> = messages(&path, "/velodyne_points")
            .iter()
            .map(|m| {
                PointCloud2::decode(&mut WireReader::new(&m.data, m.connection.encoding).unwrap())
                    .unwrap()
                    .header
                    .stamp_nanos
            })
            .collect();
        assert_eq!(imu.len(), 70);
        assert_eq!(truth.len(), 8);
        assert!(cloud_stamps[0] >= day_nanos && cloud_stamps[0] < day_nanos + 86_400 * 1_000_000_000);
        let origin_nanos = cloud_stamps[0] as f64 - kitti_times[0] * 1e9;
        for (frame, stamp) in cloud_stamps.iter().enumerate() {
            let expected = origin_nanos + kitti_times[frame] * 1e9;
            assert!(
                (*stamp as f64 - expected).abs() < 2e3,
                "frame {frame}: {stamp} vs {expected}"
            );
            assert_eq!(truth[frame].stamp_nanos, *stamp);
            assert_eq!(truth[frame].frame_id, "world");
            assert_eq!(truth[frame].child_frame_id, "velodyne");
        }
        // Gravity is on the world's z axis; at rest-ish driving its norm dominates the specific force.
        let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        assert!(imu.iter().all(|s| (norm(s.accel_mps2) - 9.80665).abs() < 3.0));
        per_bag.push((imu, truth, cloud_stamps));
    }
    let (ros1, mcap) = (&per_bag[0], &per_bag[1]);
    assert_eq!(ros1.2, mcap.2);
    assert_eq!(ros1.1, mcap.1);
    for (a, b) in ros1.0.iter().zip(&mcap.0) {
        assert_eq!(a, b);
    }
}

#[test]
fn a_missing_topic_lists_those_that_exist() {
    for path in [ros1_bag(), mcap_bag()] {
        let bag = Bag::open(&path).unwrap();
        let error = bag.require_topic("/points").unwrap_err().to_string();
        assert!(
            error.contains("/points") && error.contains("/velodyne_points") && error.contains("/imu/data"),
            "{error}"
        );
    }
}
