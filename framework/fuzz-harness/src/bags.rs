//! The bag harnesses: a ROS 1 bag and an MCAP file opened and read to the end (bounded), every message
//! decoded by its type as the `bag` source does; and the ROS message decoders alone on raw bytes.

use std::path::Path;

use skid_bag::msgs::livox::{decode_livox_custom, is_livox_custom};
use skid_bag::msgs::markers::decode_marker_array;
use skid_bag::msgs::motion;
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2, raw_points};
use skid_bag::{Bag, Encoding, MessageReader, WireReader};

/// Messages read from one fuzz input at most (a container may announce millions of tiny records).
const MAX_MESSAGES: usize = 4096;

/// The message types SKiD decodes, in the order the first byte of a `ros_messages` input picks them.
const MESSAGE_TYPES: [&str; 8] = [
    "sensor_msgs/PointCloud2",
    "sensor_msgs/Imu",
    "nav_msgs/Odometry",
    "geometry_msgs/PoseStamped",
    "tf2_msgs/TFMessage",
    "nav_msgs/Path",
    "visualization_msgs/MarkerArray",
    "livox_ros_driver2/CustomMsg",
];

/// Decodes one message of `message_type`; errors are expected, panics are defects.
fn decode_message(message_type: &str, definition: &str, data: &[u8], encoding: Encoding) {
    let Ok(mut reader) = WireReader::new(data, encoding) else {
        return;
    };
    match message_type {
        "sensor_msgs/PointCloud2" => {
            if let Ok(cloud) = PointCloud2::decode(&mut reader)
                && let Ok(layout) = CloudLayout::detect(&cloud.fields)
            {
                let decoded = raw_points(&cloud, &layout);
                assert!(
                    decoded
                        .points
                        .iter()
                        .all(|p| p.x.is_finite() && p.y.is_finite() && p.z.is_finite()),
                    "a non-finite point left the PointCloud2 decoder"
                );
            }
        }
        "sensor_msgs/Imu" => drop(motion::decode_imu(&mut reader)),
        "nav_msgs/Odometry" => drop(motion::decode_odometry(&mut reader)),
        "geometry_msgs/PoseStamped" => drop(motion::decode_pose_stamped(&mut reader)),
        "tf2_msgs/TFMessage" => drop(motion::decode_tf_message(&mut reader)),
        "nav_msgs/Path" => drop(motion::decode_path(&mut reader)),
        "visualization_msgs/MarkerArray" => drop(decode_marker_array(&mut reader)),
        other if is_livox_custom(other) => drop(decode_livox_custom(&mut reader, other, definition)),
        _ => {}
    }
}

/// Opens a bag file and reads and decodes its messages.
fn read_bag(path: &Path) {
    let Ok(mut bag) = Bag::open(path) else {
        return;
    };
    let _ = bag.connections();
    for _ in 0..MAX_MESSAGES {
        match bag.next_message() {
            Ok(Some(message)) => {
                let connection = &message.connection;
                decode_message(
                    &connection.message_type,
                    &connection.definition,
                    &message.data,
                    connection.encoding,
                );
            }
            Ok(None) | Err(_) => return,
        }
    }
}

pub fn ros1_bag(data: &[u8]) {
    crate::scratch::with_file("fuzz.bag", data, read_bag);
}

pub fn mcap_bag(data: &[u8]) {
    crate::scratch::with_file("fuzz.mcap", data, read_bag);
}

/// The first byte picks the type (low bits) and the serialization (high bit: CDR, else ROS 1).
pub fn ros_messages(data: &[u8]) {
    let Some((&selector, message)) = data.split_first() else {
        return;
    };
    let message_type = MESSAGE_TYPES[usize::from(selector & 0x07)];
    let encoding = if selector & 0x80 != 0 {
        Encoding::Cdr
    } else {
        Encoding::Ros1
    };
    decode_message(message_type, "", message, encoding);
}
