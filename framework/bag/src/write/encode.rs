//! Serializing the messages SKiD writes into bags — `sensor_msgs/PointCloud2` (x, y, z, intensity as
//! float32, ring as uint16, time as float32 seconds from the header stamp: the Velodyne layout),
//! `sensor_msgs/Imu` and `nav_msgs/Odometry` — and their definitions, which ROS 1 connection records
//! and MCAP schemas carry so that readers without the packages installed can decode them. The
//! definitions are the fields of the ROS `.msg` files (comments left out); ROS 1 also needs each
//! type's MD5 sum, the published ones for these standard types.

use skid_msgs::{ImuSample, RawPoint};

use super::wire_writer::WireWriter;
use crate::msgs::point_cloud2::datatype;
use crate::wire::Encoding;

/// A message type SKiD writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WrittenType {
    PointCloud2,
    Imu,
    Odometry,
}

impl WrittenType {
    /// The type name as ROS 1 (`pkg/Type`) or ROS 2 (`pkg/msg/Type`) spells it.
    pub fn name(self, encoding: Encoding) -> &'static str {
        match (self, encoding) {
            (WrittenType::PointCloud2, Encoding::Ros1) => "sensor_msgs/PointCloud2",
            (WrittenType::PointCloud2, Encoding::Cdr) => "sensor_msgs/msg/PointCloud2",
            (WrittenType::Imu, Encoding::Ros1) => "sensor_msgs/Imu",
            (WrittenType::Imu, Encoding::Cdr) => "sensor_msgs/msg/Imu",
            (WrittenType::Odometry, Encoding::Ros1) => "nav_msgs/Odometry",
            (WrittenType::Odometry, Encoding::Cdr) => "nav_msgs/msg/Odometry",
        }
    }

    /// The ROS 1 MD5 sum of the type (from the ROS distribution's generated code).
    pub fn md5sum(self) -> &'static str {
        match self {
            WrittenType::PointCloud2 => "1158d486dd51d683ce2f1be655c3c181",
            WrittenType::Imu => "6a62c6daae103f4ff57a132d6f95cec2",
            WrittenType::Odometry => "cd5e73d190d741a2f92e81eda573aca7",
        }
    }

    /// The full definition text: the type's fields, then each dependency's section.
    pub fn definition(self, encoding: Encoding) -> String {
        let (main, dependencies): (&str, &[&str]) = match self {
            WrittenType::PointCloud2 => (POINT_CLOUD2, &["std_msgs/Header", "sensor_msgs/PointField"]),
            WrittenType::Imu => (
                IMU,
                &[
                    "std_msgs/Header",
                    "geometry_msgs/Quaternion",
                    "geometry_msgs/Vector3",
                ],
            ),
            WrittenType::Odometry => (
                ODOMETRY,
                &[
                    "std_msgs/Header",
                    "geometry_msgs/PoseWithCovariance",
                    "geometry_msgs/Pose",
                    "geometry_msgs/Point",
                    "geometry_msgs/Quaternion",
                    "geometry_msgs/TwistWithCovariance",
                    "geometry_msgs/Twist",
                    "geometry_msgs/Vector3",
                ],
            ),
        };
        full_definition(main, dependencies, encoding)
    }
}

/// A type's full definition text: its own fields, then one `MSG:` section per type it uses (and, in ROS 2,
/// `builtin_interfaces/Time`, which every header uses).
pub(crate) fn full_definition(main: &str, dependencies: &[&str], encoding: Encoding) -> String {
    let mut text = main.to_owned();
    let mut sections: Vec<&str> = dependencies.to_vec();
    if encoding == Encoding::Cdr {
        sections.push("builtin_interfaces/Time");
    }
    for name in sections {
        text.push_str(&"=".repeat(80));
        text.push_str("\nMSG: ");
        text.push_str(name);
        text.push('\n');
        text.push_str(dependency(name, encoding));
    }
    text
}

const POINT_CLOUD2: &str = "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\n\
bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n";
const IMU: &str = "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n\
geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n\
geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n";
const ODOMETRY: &str = "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n\
geometry_msgs/TwistWithCovariance twist\n";

fn dependency(name: &str, encoding: Encoding) -> &'static str {
    match (name, encoding) {
        ("std_msgs/Header", Encoding::Ros1) => "uint32 seq\ntime stamp\nstring frame_id\n",
        ("std_msgs/Header", Encoding::Cdr) => "builtin_interfaces/Time stamp\nstring frame_id\n",
        ("builtin_interfaces/Time", _) => "int32 sec\nuint32 nanosec\n",
        ("sensor_msgs/PointField", _) => {
            "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\n\
uint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n"
        }
        ("geometry_msgs/Quaternion", _) => "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
        ("geometry_msgs/Vector3" | "geometry_msgs/Point", _) => "float64 x\nfloat64 y\nfloat64 z\n",
        ("geometry_msgs/PoseWithCovariance", _) => "geometry_msgs/Pose pose\nfloat64[36] covariance\n",
        ("geometry_msgs/Pose", _) => "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
        ("geometry_msgs/TwistWithCovariance", _) => "geometry_msgs/Twist twist\nfloat64[36] covariance\n",
        ("geometry_msgs/Twist", _) => "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
        ("geometry_msgs/PoseStamped", _) => "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
        ("geometry_msgs/TransformStamped", _) => {
            "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"
        }
        ("geometry_msgs/Transform", _) => {
            "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"
        }
        ("std_msgs/ColorRGBA", _) => "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n",
        ("builtin_interfaces/Duration", _) => "int32 sec\nuint32 nanosec\n",
        ("sensor_msgs/CompressedImage", _) => "std_msgs/Header header\nstring format\nuint8[] data\n",
        ("visualization_msgs/UVCoordinate", _) => "float32 u\nfloat32 v\n",
        ("visualization_msgs/MeshFile", _) => "string filename\nuint8[] data\n",
        ("visualization_msgs/Marker", _) => MARKER,
        _ => "",
    }
}

/// Bytes per point in the written cloud layout, and the fields.
const POINT_STEP: u32 = 24;
const FIELDS: [(&str, u32, u8); 6] = [
    ("x", 0, datatype::FLOAT32),
    ("y", 4, datatype::FLOAT32),
    ("z", 8, datatype::FLOAT32),
    ("intensity", 12, datatype::FLOAT32),
    ("ring", 16, datatype::UINT16),
    ("time", 20, datatype::FLOAT32),
];

/// A `PointCloud2` of `points` (one row, little-endian) stamped at `stamp_nanos`.
pub fn point_cloud2(
    encoding: Encoding,
    seq: u32,
    stamp_nanos: u64,
    frame_id: &str,
    points: &[RawPoint],
) -> Vec<u8> {
    let mut writer = WireWriter::new(encoding, points.len() * POINT_STEP as usize + 256);
    writer.header(seq, stamp_nanos, frame_id);
    let width = u32::try_from(points.len()).unwrap_or(u32::MAX);
    writer.u32(1);
    writer.u32(width);
    writer.sequence_len(FIELDS.len());
    for (name, offset, kind) in FIELDS {
        writer.string(name);
        writer.u32(offset);
        writer.u8(kind);
        writer.u32(1);
    }
    writer.bool(false);
    writer.u32(POINT_STEP);
    writer.u32(POINT_STEP.saturating_mul(width));
    let mut data = Vec::with_capacity(points.len() * POINT_STEP as usize);
    for point in points {
        for value in [point.x, point.y, point.z, point.intensity] {
            data.extend_from_slice(&value.to_le_bytes());
        }
        data.extend_from_slice(&point.ring.to_le_bytes());
        data.extend_from_slice(&[0, 0]);
        data.extend_from_slice(&point.time_offset_s.to_le_bytes());
    }
    writer.byte_sequence(&data);
    writer.bool(points.iter().all(RawPoint::is_finite));
    writer.into_bytes()
}

/// An `Imu` message with the sample's rates and specific force (orientation unknown: covariance -1).
pub fn imu(encoding: Encoding, seq: u32, frame_id: &str, sample: &ImuSample) -> Vec<u8> {
    let mut writer = WireWriter::new(encoding, 400);
    writer.header(seq, sample.stamp_nanos, frame_id);
    writer.f64s(&[0.0, 0.0, 0.0, 1.0]);
    let mut unknown = [0.0; 9];
    unknown[0] = -1.0;
    writer.f64s(&unknown);
    writer.f64s(&sample.gyro_radps);
    writer.f64s(&[0.0; 9]);
    writer.f64s(&sample.accel_mps2);
    writer.f64s(&[0.0; 9]);
    writer.into_bytes()
}

/// An `Odometry` message placing `child_frame_id` in `frame_id` (zero twist and covariances).
pub fn odometry(
    encoding: Encoding,
    seq: u32,
    stamp_nanos: u64,
    frames: (&str, &str),
    translation_m: [f64; 3],
    rotation_xyzw: [f64; 4],
) -> Vec<u8> {
    let mut writer = WireWriter::new(encoding, 800);
    writer.header(seq, stamp_nanos, frames.0);
    writer.string(frames.1);
    writer.f64s(&translation_m);
    writer.f64s(&rotation_xyzw);
    writer.f64s(&[0.0; 36]);
    writer.f64s(&[0.0; 6]);
    writer.f64s(&[0.0; 36]);
    writer.into_bytes()
}

/// A `std_msgs/String` message.
pub fn string(encoding: Encoding, text: &str) -> Vec<u8> {
    let mut writer = WireWriter::new(encoding, text.len() + 16);
    writer.string(text);
    writer.into_bytes()
}

/// `visualization_msgs/Marker` as ROS 2 Jazzy defines it.
pub(crate) const MARKER: &str = "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\n\
int32 LINE_STRIP=4\nint32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\n\
int32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\nint32 ARROW_STRIP=12\n\
int32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n\
std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\ngeometry_msgs/Pose pose\n\
geometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\nbuiltin_interfaces/Duration lifetime\n\
bool frame_locked\ngeometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\nstring texture_resource\n\
sensor_msgs/CompressedImage texture\nvisualization_msgs/UVCoordinate[] uv_coordinates\nstring text\n\
string mesh_resource\nvisualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials\n";
