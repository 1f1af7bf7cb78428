//! Decoders for the ROS message types SKiD reads, written from the `.msg` definitions of `sensor_msgs`,
//! `nav_msgs`, `geometry_msgs` and `tf2_msgs` (ROS 1 Noetic and ROS 2 Humble define them identically
//! field by field; only the header and the serialization differ, see [`crate::wire`]).

pub mod definition;
pub mod livox;
pub mod markers;
pub mod motion;
pub mod point_cloud2;
