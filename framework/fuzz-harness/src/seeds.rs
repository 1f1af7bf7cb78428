//! Valid inputs a fuzzer starts from, one small set per target, made with SKiD's writers: the mutations
//! of well-formed files reach much deeper into a reader than random bytes do. The corpus replay runs
//! them too, so a reader that starts refusing its own writer's output fails `cargo test`.

use skid_bag::write::{BagFormat, RobotBagWriter};
use skid_core::{Information, KeyframeId, Point, Pose, RobotId};
use skid_io::pcd::{PcdData, PcdWriteOptions, pcd_bytes};
use skid_io::ply::{PlyFormat, ply_bytes};
use skid_msgs::{ImuSample, RawPoint};
use skid_protocol::{
    Capabilities, ChainEdge, CloudMsg, CloudRequest, CompressedPoints, DescriptorBatch, DescriptorEncoding,
    DescriptorEntry, DescriptorValues, InformationMsg, LoopMsg, Loops, Message, OdomChain, PeerStatus,
    PoseMsg, ProtocolConfig, encode,
};

/// A small cloud with one NaN point, so readers' non-finite handling is reached.
fn points() -> Vec<Point> {
    let mut points: Vec<Point> = (0..40)
        .map(|i| Point::with_intensity((i % 8) as f32 * 0.5, (i / 8) as f32 * 0.5, -1.25, i as f32))
        .collect();
    points.push(Point::with_intensity(f32::NAN, 1.0, 2.0, 0.0));
    points
}

fn raw_points() -> Vec<RawPoint> {
    points()
        .iter()
        .enumerate()
        .map(|(i, p)| RawPoint::new(p.x, p.y, p.z, p.intensity, i as f32 * 1e-4, (i % 16) as u16))
        .collect()
}

/// A robot at rest: gravity up the z axis, no rotation.
fn imu_sample(stamp_nanos: u64) -> ImuSample {
    ImuSample {
        stamp_nanos,
        accel_mps2: [0.0, 0.0, 9.81],
        gyro_radps: [0.0; 3],
    }
}

fn messages() -> Vec<Message> {
    let robot = RobotId(2);
    let pose = Pose::new(
        nalgebra::Vector3::new(1.0, -2.0, 0.5),
        nalgebra::Vector3::new(0.0, 0.1, 0.7),
    );
    let status = PeerStatus {
        robot,
        latest_keyframe: Some(12),
        capabilities: Capabilities {
            descriptor_kind: "solid".into(),
            descriptor_len: 8,
            serves_clouds: true,
            max_message_bytes: 4 << 20,
        },
        settled: false,
    };
    let values = [0.1f32, 0.4, 0.9, 0.0, 0.3, 0.3, 0.7, 1.0];
    let finite: Vec<Point> = points().into_iter().filter(|p| p.x.is_finite()).collect();
    let mut messages = vec![Message::Hello(status.clone()), Message::Heartbeat(status)];
    for encoding in [
        DescriptorEncoding::F32,
        DescriptorEncoding::U8,
        DescriptorEncoding::U16,
    ] {
        if let Ok(values) = DescriptorValues::encode(&values, encoding) {
            messages.push(Message::Descriptors(DescriptorBatch {
                robot,
                kind: "solid".into(),
                entries: vec![DescriptorEntry {
                    keyframe_index: 3,
                    stamp_nanos: 1_500_000_000,
                    values,
                    newest_held: Vec::new(),
                }],
            }));
        }
    }
    messages.push(Message::CloudRequest(CloudRequest {
        requester: robot,
        keyframes: vec![KeyframeId::new(1, 4)],
    }));
    if let Ok(points) = CompressedPoints::encode(&finite, 0.01, true) {
        messages.push(Message::Cloud(CloudMsg {
            keyframe: KeyframeId::new(2, 4),
            stamp_nanos: 9,
            world_from_sensor: PoseMsg::from_pose(&pose),
            points,
        }));
    }
    let edge = ChainEdge {
        target_from_source: PoseMsg::from_pose(&pose),
        information: InformationMsg::from_information(&(Information::identity() * 20.0)),
    };
    messages.push(Message::OdomChain(OdomChain {
        robot,
        from_index: 1,
        to_index: 3,
        edges: vec![edge, edge],
        world_from_first: PoseMsg::IDENTITY,
    }));
    messages.push(Message::Loops(Loops {
        robot,
        accepted: vec![LoopMsg {
            target: KeyframeId::new(2, 3),
            source: KeyframeId::new(1, 8),
            target_from_source: PoseMsg::from_pose(&pose),
            information: InformationMsg::identity(),
            fitness_m2: 0.02,
        }],
        retracted: vec![(KeyframeId::new(2, 1), KeyframeId::new(3, 2))],
    }));
    messages
}

fn protocol_seeds() -> Vec<Vec<u8>> {
    let config = ProtocolConfig::default();
    messages()
        .iter()
        .enumerate()
        .filter_map(|(sequence, message)| encode(message, RobotId(2), 5, sequence as u64, &config).ok())
        .collect()
}

fn cloud_file_seeds(target: &str) -> Vec<Vec<u8>> {
    let points = points();
    match target {
        "pcd" => [PcdData::Ascii, PcdData::Binary, PcdData::BinaryCompressed]
            .into_iter()
            .filter_map(|data| pcd_bytes(&points, &PcdWriteOptions::new(data), "seed.pcd".as_ref()).ok())
            .collect(),
        "ply" => [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ]
        .into_iter()
        .map(|format| ply_bytes(&points, format))
        .collect(),
        _ => vec![skid_io::kitti::kitti_bin_bytes(&points)],
    }
}

fn graph_seeds(target: &str) -> Vec<Vec<u8>> {
    let texts: &[&str] = if target == "g2o" {
        &[
            "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n\
             EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400\nFIX 0\n",
            "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.1\nEDGE_SE2 0 1 1 0 0.1 100 0 0 100 0 400\n\
             EDGE_SE2 1 2 1 0 0 100 0 0 100 0 400\n",
        ]
    } else {
        &[
            "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0.1\nEDGE2 0 1 1 0 0.1 100 0 100 400 0 0\nEQUIV 0 1\n",
            "VERTEX3 0 0 0 0 0 0 0\nEDGE3 0 1 1 0 0 0 0 0 100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400\n",
        ]
    };
    texts.iter().map(|text| text.as_bytes().to_vec()).collect()
}

/// Two robots, `a` with a prior, odometry and a labelled wrong loop to `b` (keys: the letter times 2^56
/// plus the pose index).
const JRL_SEED: &str = r#"{"name": "seed", "robots": [97, 98],
 "groundtruth": {"a": [{"key": 6989586621679009792, "type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [0, 0, 0]}]},
 "initialization": {"b": [{"key": 7061644215716937728, "type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [5, 0, 0]}]},
 "measurements": {"a": [
  {"stamp": 10, "measurements": [{"type": "PriorFactorPose3", "key": 6989586621679009792,
    "prior": {"type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [0, 0, 0]},
    "covariance": [1e-6,0,0,0,0,0, 0,1e-6,0,0,0,0, 0,0,1e-6,0,0,0, 0,0,0,1e-4,0,0, 0,0,0,0,1e-4,0, 0,0,0,0,0,1e-4]}]},
  {"stamp": 20, "measurements": [{"type": "BetweenFactorPose3", "key1": 6989586621679009792, "key2": 6989586621679009793,
    "measurement": {"type": "Pose3", "rotation": [0.99, 0, 0, 0.1], "translation": [1, 0, 0]},
    "covariance": [1e-3,0,0,0,0,0, 0,1e-3,0,0,0,0, 0,0,1e-3,0,0,0, 0,0,0,1e-2,0,0, 0,0,0,0,1e-2,0, 0,0,0,0,0,1e-2]},
   {"type": "BetweenFactorPose3", "key1": 6989586621679009793, "key2": 7061644215716937728,
    "measurement": {"type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [4, 0, 0]},
    "covariance": [1e-2,0,0,0,0,0, 0,1e-2,0,0,0,0, 0,0,1e-2,0,0,0, 0,0,0,1e-1,0,0, 0,0,0,0,1e-1,0, 0,0,0,0,0,1e-1]}]}],
  "b": []},
 "potential_outlier_factors": {"a": [[1, 1]]},
 "outlier_factors": {"a": [[1, 1]]}}"#;

/// A two-scan recording with IMU and ground truth, written by SKiD's bag writer.
fn bag_seed(format: BagFormat) -> Option<Vec<u8>> {
    let folder = std::env::temp_dir().join(format!("skid-fuzz-seed-{}-{format:?}", std::process::id()));
    let _ = std::fs::remove_dir_all(&folder);
    std::fs::create_dir_all(&folder).ok()?;
    let path = folder.join(if format == BagFormat::Ros1 {
        "seed.bag"
    } else {
        "seed"
    });
    let mut writer = RobotBagWriter::create(&path, format).ok()?;
    let raw: Vec<RawPoint> = raw_points();
    for scan in 0..2u64 {
        let stamp_nanos = 1_000_000_000 + scan * 100_000_000;
        writer.write_scan(stamp_nanos, &raw).ok()?;
        writer.write_imu(&imu_sample(stamp_nanos + 5_000_000)).ok()?;
    }
    let written = writer.finish().ok()?;
    let file = if format == BagFormat::Ros1 {
        written
    } else {
        std::fs::read_dir(&written)
            .ok()?
            .filter_map(Result::ok)
            .map(|entry| entry.path())
            .find(|path| path.extension().is_some_and(|ext| ext == "mcap"))?
    };
    let bytes = std::fs::read(file).ok();
    let _ = std::fs::remove_dir_all(&folder);
    bytes
}

/// The seeds of `target` (empty for an unknown name).
pub fn seeds(target: &str) -> Vec<Vec<u8>> {
    match target {
        "protocol_message" => protocol_seeds(),
        "pcd" | "ply" | "kitti_bin" => cloud_file_seeds(target),
        "g2o" | "toro" => graph_seeds(target),
        "jrl" => vec![JRL_SEED.as_bytes().to_vec()],
        "ros1_bag" => bag_seed(BagFormat::Ros1).into_iter().collect(),
        "mcap_bag" => bag_seed(BagFormat::Mcap).into_iter().collect(),
        "ros_messages" => ros_message_seeds(),
        "session_descriptors" => session_descriptor_seeds(),
        "session_folder" => session_folder_seed().into_iter().collect(),
        _ => Vec::new(),
    }
}

/// Single messages behind their selector byte (see [`crate::ros_messages`]).
fn ros_message_seeds() -> Vec<Vec<u8>> {
    use skid_bag::Encoding;
    use skid_bag::write::encode;
    let raw: Vec<RawPoint> = raw_points();
    let mut seeds = Vec::new();
    for (flag, encoding) in [(0u8, Encoding::Ros1), (0x80, Encoding::Cdr)] {
        let cloud = encode::point_cloud2(encoding, 1, 1_000_000_000, "lidar", &raw);
        seeds.push([vec![flag], cloud].concat());
        let imu = encode::imu(encoding, 1, "imu", &imu_sample(1_000_000_000));
        seeds.push([vec![flag | 1], imu].concat());
    }
    seeds
}

/// Two descriptor files: three descriptors of four values, and none.
fn session_descriptor_seeds() -> Vec<Vec<u8>> {
    let values = [[0.25f32, 0.5, 0.0, 1.0], [1.0, 0.75, 0.5, 0.25], [0.0; 4]];
    let entries: Vec<(u32, &[f32])> = values
        .iter()
        .enumerate()
        .map(|(i, v)| (i as u32 * 2, &v[..]))
        .collect();
    [entries.as_slice(), &[]]
        .iter()
        .filter_map(|entries| skid_session::encode_descriptors(4, entries).ok())
        .collect()
}

/// A one-robot session of three keyframes as SKiD writes it, its files joined by the separator.
fn session_folder_seed() -> Option<Vec<u8>> {
    use skid_session::{DescriptorSpec, Session, SessionKeyframe, SessionRobot};
    let mut graph = skid_io::g2o::PoseGraph::default();
    let keyframes: Vec<SessionKeyframe> = (0..3u32)
        .map(|index| {
            let pose = Pose::new(
                nalgebra::Vector3::new(f64::from(index) * 1.5, 0.2, 0.0),
                nalgebra::Vector3::new(0.0, 0.0, 0.1 * f64::from(index)),
            );
            graph.vertices.insert(u64::from(index), pose);
            SessionKeyframe {
                index,
                stamp_nanos: 1_000_000_000 + u64::from(index) * 500_000_000,
                map_from_sensor: pose,
                odometry_from_sensor: pose,
                ground_truth: (index != 1).then_some(pose),
                point_count: 40,
                descriptor: (index != 2).then(|| vec![0.5, f32::from(index as u8), 0.25]),
            }
        })
        .collect();
    let session = Session {
        name: "seed".into(),
        skid_version: "0.1.0".into(),
        descriptor: Some(DescriptorSpec {
            kind: "solid".into(),
            params: serde_json::json!({"num_range_bins": 40}),
            length: 3,
        }),
        config_toml: "[run]\nname = \"seed\"\n".into(),
        robots: vec![SessionRobot {
            robot: 0,
            map_from_robot: Some(Pose::identity()),
            keyframes,
            graph,
        }],
    };
    let finite: Vec<Point> = points().into_iter().filter(|p| p.x.is_finite()).collect();
    let folder = std::env::temp_dir().join(format!("skid-session-seed-{}", std::process::id()));
    skid_session::write_session(&folder, &session, |_, _| Some(finite.as_slice())).ok()?;
    let mut joined = Vec::new();
    for (position, name) in crate::SESSION_FILES.iter().enumerate() {
        if position > 0 {
            joined.extend_from_slice(crate::SESSION_FILE_SEPARATOR);
        }
        joined.extend(std::fs::read(folder.join(name)).ok()?);
    }
    let _ = std::fs::remove_dir_all(&folder);
    Some(joined)
}
