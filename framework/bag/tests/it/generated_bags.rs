//! Every container and compression (ROS 1 none/bz2/lz4, indexed or not; ROS 2 MCAP and sqlite3; bare
//! MCAP with zstd or lz4 chunks) and every driver layout (Velodyne, Ouster organised with NaN holes,
//! Hesai absolute times, Livox, big-endian float64 in big-endian CDR) decode to the values the
//! independent writer put in.

use crate::generated;

use generated::{CLOUDS, COMPLETE_BAGS, IMU_PER_CLOUD, KINDS, expected_rows, fixtures};
use skid_bag::msgs::motion::{decode_imu, decode_odometry, decode_pose_stamped, decode_tf_message};
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2, raw_points};
use skid_bag::{Bag, MessageReader, RawMessage, WireReader};

fn read_topic(bag: &str, topic: &str) -> Vec<RawMessage> {
    let mut bag = Bag::open(&fixtures().join(bag)).unwrap();
    bag.select_topics(&[topic.to_owned()]);
    let mut messages = Vec::new();
    while let Some(message) = bag.next_message().unwrap() {
        messages.push(message);
    }
    messages
}

#[test]
fn every_layout_in_every_container_decodes_to_the_written_values() {
    for bag in COMPLETE_BAGS {
        for kind in KINDS {
            let clouds = read_topic(bag, &format!("/{kind}/points"));
            assert_eq!(clouds.len(), CLOUDS, "{bag} {kind}");
            for (index, message) in clouds.iter().enumerate() {
                let mut reader = WireReader::new(&message.data, message.connection.encoding).unwrap();
                let cloud = PointCloud2::decode(&mut reader).unwrap();
                let layout = CloudLayout::detect(&cloud.fields).unwrap();
                let decoded = raw_points(&cloud, &layout);
                let expected = expected_rows(kind, index);
                assert_eq!(decoded.points.len(), expected.len(), "{bag} {kind} {index}");
                assert_eq!(
                    decoded.points.len() + decoded.dropped_non_finite,
                    cloud.point_count()
                );
                if kind == "ouster" {
                    assert!(
                        cloud.height > 1 && decoded.dropped_non_finite > 0,
                        "{bag}: organised with holes"
                    );
                }
                for (point, row) in decoded.points.iter().zip(&expected) {
                    let context = format!("{bag} {kind} cloud {index}");
                    assert_eq!(
                        [point.x, point.y, point.z, point.intensity],
                        row[..4],
                        "{context}"
                    );
                    assert!(
                        (point.time_offset_s - row[4]).abs() < 1e-6,
                        "{context}: {} vs {}",
                        point.time_offset_s,
                        row[4]
                    );
                    assert_eq!(f32::from(point.ring), row[5], "{context}");
                }
            }
        }
    }
}

#[test]
fn imu_and_ground_truth_messages_decode_in_every_container() {
    for bag in COMPLETE_BAGS {
        let imu = read_topic(bag, "/imu");
        assert_eq!(imu.len(), CLOUDS * IMU_PER_CLOUD, "{bag}");
        for (k, message) in imu.iter().enumerate() {
            let sample =
                decode_imu(&mut WireReader::new(&message.data, message.connection.encoding).unwrap())
                    .unwrap();
            assert_eq!(sample.accel_mps2[2], 9.81, "{bag}");
            assert_eq!(sample.gyro_radps[0], 0.01 * (k % IMU_PER_CLOUD) as f64, "{bag}");
            assert_eq!(sample.stamp_nanos, message.log_time_nanos, "{bag}");
        }
        let odometry = read_topic(bag, "/odom");
        let poses = read_topic(bag, "/pose");
        let tf = read_topic(bag, "/tf");
        assert_eq!(
            (odometry.len(), poses.len(), tf.len()),
            (CLOUDS, CLOUDS, CLOUDS),
            "{bag}"
        );
        for ((odometry, pose), tf) in odometry.iter().zip(&poses).zip(&tf) {
            let odometry =
                decode_odometry(&mut WireReader::new(&odometry.data, odometry.connection.encoding).unwrap())
                    .unwrap();
            let pose =
                decode_pose_stamped(&mut WireReader::new(&pose.data, pose.connection.encoding).unwrap())
                    .unwrap();
            let transforms =
                decode_tf_message(&mut WireReader::new(&tf.data, tf.connection.encoding).unwrap()).unwrap();
            assert_eq!(odometry.child_frame_id, "lidar");
            assert_eq!(odometry.translation_m, pose.translation_m);
            assert_eq!(odometry.rotation_xyzw, pose.rotation_xyzw);
            assert_eq!(transforms.len(), 2);
            assert_eq!(transforms[1].child_frame_id, "lidar");
            assert_eq!(transforms[1].translation_m, pose.translation_m);
            assert_eq!(transforms[1].stamp_nanos, pose.stamp_nanos);
        }
        let statics = read_topic(bag, "/tf_static");
        let extrinsic = decode_tf_message(
            &mut WireReader::new(&statics[0].data, statics[0].connection.encoding).unwrap(),
        )
        .unwrap();
        assert_eq!(
            (
                extrinsic[0].frame_id.as_str(),
                extrinsic[0].child_frame_id.as_str()
            ),
            ("imu_link", "lidar")
        );
        assert_eq!(extrinsic[0].translation_m, [0.1, 0.0, 0.2]);
    }
}

#[test]
fn message_types_are_named_alike_in_ros1_and_ros2_bags() {
    for bag in COMPLETE_BAGS {
        let bag = Bag::open(&fixtures().join(bag)).unwrap();
        let unindexed = !bag.connections_complete();
        let types: Vec<(String, String)> = bag
            .connections()
            .iter()
            .map(|c| (c.topic.clone(), c.message_type.clone()))
            .collect();
        if unindexed {
            assert!(
                types.is_empty(),
                "an unindexed bag learns its topics while reading"
            );
            continue;
        }
        assert!(
            types.contains(&(
                "/velodyne/points".to_owned(),
                "sensor_msgs/PointCloud2".to_owned()
            )),
            "{types:?}"
        );
        assert!(
            types.contains(&("/imu".to_owned(), "sensor_msgs/Imu".to_owned())),
            "{types:?}"
        );
        assert!(
            types.contains(&("/tf".to_owned(), "tf2_msgs/TFMessage".to_owned())),
            "{types:?}"
        );
    }
}

#[test]
fn a_bag_cut_short_by_a_crashed_recorder_reads_up_to_the_cut() {
    let complete = read_topic("none.bag", "/imu").len();
    let crashed = read_topic("crashed.bag", "/imu");
    assert!(
        !crashed.is_empty() && crashed.len() <= complete,
        "{} of {complete}",
        crashed.len()
    );
}

#[test]
fn livox_custom_messages_decode_from_the_definition_in_the_bag() {
    use skid_bag::msgs::livox::{decode_livox_custom, is_livox_custom};
    for bag in ["none.bag", "bz2.bag", "lz4.bag", "unindexed.bag", "ros2_mcap"] {
        let messages = read_topic(bag, "/livox/custom");
        assert_eq!(messages.len(), CLOUDS, "{bag}");
        for (index, message) in messages.iter().enumerate() {
            let connection = &message.connection;
            assert!(
                is_livox_custom(&connection.message_type),
                "{bag}: {}",
                connection.message_type
            );
            let mut reader = WireReader::new(&message.data, connection.encoding).unwrap();
            let cloud =
                decode_livox_custom(&mut reader, &connection.message_type, &connection.definition).unwrap();
            let expected = expected_rows("livox_custom", index);
            assert_eq!(cloud.points.len(), expected.len(), "{bag} {index}");
            for (point, row) in cloud.points.iter().zip(&expected) {
                assert_eq!(
                    [point.x, point.y, point.z, point.intensity],
                    row[..4],
                    "{bag} {index}"
                );
                assert!((point.time_offset_s - row[4]).abs() < 1e-6, "{bag} {index}");
                assert_eq!(f32::from(point.ring), row[5]);
            }
            // Offsets start 5 ms before the header stamp (timebase) and may be negative.
            assert!(cloud.points.iter().any(|p| p.time_offset_s < 0.0));
        }
    }
}
