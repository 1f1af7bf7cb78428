//! ROS 2 (CDR) serialization of the messages a run record needs beside clouds and odometry:
//! `nav_msgs/Path`, `tf2_msgs/TFMessage` and `visualization_msgs/MarkerArray` of line lists, with the
//! `ros2msg` definitions (ROS 2 Jazzy's `.msg` files, comments left out) that MCAP schemas carry so
//! Foxglove Studio, `ros2 bag play` and `rosbags` decode them without SKiD.

use skid_msgs::PoseWire;

use super::encode::full_definition;
use super::wire_writer::WireWriter;
use crate::wire::Encoding;

const LINE_LIST: i32 = 5;
const ADD: i32 = 0;

/// A record message type and its full `ros2msg` definition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VizType {
    Path,
    TfMessage,
    MarkerArray,
}

impl VizType {
    /// The ROS 2 type name (`pkg/msg/Type`).
    pub fn name(self) -> &'static str {
        match self {
            VizType::Path => "nav_msgs/msg/Path",
            VizType::TfMessage => "tf2_msgs/msg/TFMessage",
            VizType::MarkerArray => "visualization_msgs/msg/MarkerArray",
        }
    }

    pub fn definition(self) -> String {
        let (main, dependencies): (&str, &[&str]) = match self {
            VizType::Path => (
                "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n",
                &[
                    "std_msgs/Header",
                    "geometry_msgs/PoseStamped",
                    "geometry_msgs/Pose",
                    "geometry_msgs/Point",
                    "geometry_msgs/Quaternion",
                ],
            ),
            VizType::TfMessage => (
                "geometry_msgs/TransformStamped[] transforms\n",
                &[
                    "geometry_msgs/TransformStamped",
                    "std_msgs/Header",
                    "geometry_msgs/Transform",
                    "geometry_msgs/Vector3",
                    "geometry_msgs/Quaternion",
                ],
            ),
            VizType::MarkerArray => (
                "visualization_msgs/Marker[] markers\n",
                &[
                    "visualization_msgs/Marker",
                    "std_msgs/Header",
                    "geometry_msgs/Pose",
                    "geometry_msgs/Point",
                    "geometry_msgs/Quaternion",
                    "geometry_msgs/Vector3",
                    "std_msgs/ColorRGBA",
                    "builtin_interfaces/Duration",
                    "sensor_msgs/CompressedImage",
                    "visualization_msgs/UVCoordinate",
                    "visualization_msgs/MeshFile",
                ],
            ),
        };
        full_definition(main, dependencies, Encoding::Cdr)
    }
}

/// One `geometry_msgs/TransformStamped`: `child` placed in `parent` at `stamp_nanos` (a pose in ROS's
/// order, translation then quaternion `x, y, z, w`, is SKiD's [`PoseWire`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameTransform {
    pub stamp_nanos: u64,
    pub parent: String,
    pub child: String,
    pub parent_from_child: PoseWire,
}

/// One `LINE_LIST` marker: a line per pair of points, in one colour.
#[derive(Clone, Debug, PartialEq)]
pub struct LineListMarker {
    pub namespace: String,
    pub id: i32,
    pub rgba: [f32; 4],
    pub line_width_m: f64,
    pub segments: Vec<([f64; 3], [f64; 3])>,
}

fn pose(writer: &mut WireWriter, pose: &PoseWire) {
    writer.f64s(&pose.translation_m);
    writer.f64s(&pose.rotation_xyzw);
}

/// A `nav_msgs/Path` in `frame_id` stamped `stamp_nanos`, one `PoseStamped` per `(stamp, pose)`.
pub fn path(stamp_nanos: u64, frame_id: &str, poses: &[(u64, PoseWire)]) -> Vec<u8> {
    let mut writer = WireWriter::new(Encoding::Cdr, 96 + poses.len() * (80 + frame_id.len()));
    writer.header(0, stamp_nanos, frame_id);
    writer.sequence_len(poses.len());
    for (stamp, value) in poses {
        writer.header(0, *stamp, frame_id);
        pose(&mut writer, value);
    }
    writer.into_bytes()
}

/// A `tf2_msgs/TFMessage` holding `transforms`.
pub fn tf_message(transforms: &[FrameTransform]) -> Vec<u8> {
    let mut writer = WireWriter::new(Encoding::Cdr, 16 + transforms.len() * 128);
    writer.sequence_len(transforms.len());
    for transform in transforms {
        writer.header(0, transform.stamp_nanos, &transform.parent);
        writer.string(&transform.child);
        pose(&mut writer, &transform.parent_from_child);
    }
    writer.into_bytes()
}

/// A `visualization_msgs/MarkerArray` of line lists in `frame_id`, added for good (zero lifetime).
pub fn line_markers(stamp_nanos: u64, frame_id: &str, markers: &[LineListMarker]) -> Vec<u8> {
    let points: usize = markers.iter().map(|m| m.segments.len() * 2).sum();
    let mut writer = WireWriter::new(Encoding::Cdr, 256 * markers.len() + points * 24);
    writer.sequence_len(markers.len());
    for marker in markers {
        writer.header(0, stamp_nanos, frame_id);
        writer.string(&marker.namespace);
        writer.i32(marker.id);
        writer.i32(LINE_LIST);
        writer.i32(ADD);
        pose(
            &mut writer,
            &PoseWire {
                translation_m: [0.0; 3],
                rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
        );
        // For a line list only scale.x, the line width, is used.
        writer.f64s(&[marker.line_width_m, 0.0, 0.0]);
        for channel in marker.rgba {
            writer.f32(channel);
        }
        writer.time_nanos(0);
        writer.bool(false);
        writer.sequence_len(marker.segments.len() * 2);
        for (from, to) in &marker.segments {
            writer.f64s(from);
            writer.f64s(to);
        }
        writer.sequence_len(0);
        writer.string("");
        // An empty texture: header, format, data.
        writer.header(0, 0, "");
        writer.string("");
        writer.byte_sequence(&[]);
        writer.sequence_len(0);
        writer.string("");
        writer.string("");
        // An empty mesh file: file name and data.
        writer.string("");
        writer.byte_sequence(&[]);
        writer.bool(false);
    }
    writer.into_bytes()
}
