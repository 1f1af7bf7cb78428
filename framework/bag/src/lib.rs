//! Reading robot recordings without a ROS installation: ROS 1 bags (v2.0; uncompressed, bz2 and lz4
//! chunks; with or without an index), ROS 2 bags (MCAP or sqlite3 storage, CDR messages) and bare MCAP
//! files, streamed a chunk at a time; the ROS 1 and CDR serializations; and the message types SKiD
//! needs (`sensor_msgs/PointCloud2` in any driver's field layout, `sensor_msgs/Imu`, poses from
//! `nav_msgs/Odometry`, `geometry_msgs/PoseStamped` and `tf2_msgs/TFMessage`).
//!
//! Specifications followed: the ROS bag format 2.0 (wiki.ros.org/Bags/Format/2.0), the MCAP format
//! (mcap.dev/spec), rosbag2's sqlite3 storage schema, ROS 1 message serialization
//! (wiki.ros.org/msg, roscpp serialization) and OMG CDR (XCDR1) as ROS 2 middlewares use it.
//!
//! [`write`] records bags the other way: ROS 1 bags and ROS 2 MCAP bag folders, for `skid sim export`.

mod bag;
mod chunk_codec;
mod connection;
mod error;
mod lz4_block;
mod lz4_frame;
mod mcap_file;
mod mcap_records;
pub mod msgs;
mod ros1;
mod sqlite;
mod wire;
pub mod write;

pub use bag::{Bag, Storage, bag_files, detect_storage, require_topic};
pub use connection::{Connection, MessageBytes, MessageReader, RawMessage, normalise_type};
pub use error::{BagError, DecodeError};
pub use mcap_file::McapReader;
pub use ros1::Ros1Reader;
pub use sqlite::SqliteReader;
pub use wire::{Encoding, Header, WireReader};
