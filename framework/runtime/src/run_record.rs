//! `run.mcap`, the run record: what a run estimated, as ROS 2 messages in an MCAP file that Foxglove
//! Studio, Lichtblick, `ros2 bag play` and `rosbags` open with no SKiD code (CDR, `ros2msg` schemas).
//!
//! Frames: `map` is robot 0's map frame; each robot `i` has `robot<i>/map` (its optimised frame, placed in
//! `map` on `/tf_static` where the back-end knows it), `robot<i>/odom` (its odometry frame) and
//! `robot<i>/base_link` (the sensor). Topics, per robot `i`:
//!
//! | topic | type | content |
//! |---|---|---|
//! | `/robot<i>/odometry` | `nav_msgs/Odometry` | the odometry, one per scan |
//! | `/tf` | `tf2_msgs/TFMessage` | per scan: `robot<i>/odom → base_link` and the correction `robot<i>/map → odom` |
//! | `/robot<i>/keyframes` | `sensor_msgs/PointCloud2` | each keyframe's cloud at its optimised pose, in `robot<i>/map`, thinned to `output.record_voxel_m` |
//! | `/robot<i>/path` | `nav_msgs/Path` | the optimised trajectory (the poses of `trajectory.tum`), once at the end |
//! | `/robot<i>/ground_truth` | `nav_msgs/Path` | the ground truth in the simulator's or dataset's world frame, when known |
//! | `/map` | `sensor_msgs/PointCloud2` | the merged map (`map.ply`), in `map` |
//! | `/loops` | `visualization_msgs/MarkerArray` | loop closures as lines in `map`: accepted, rejected by the verifier's checks of the alignment (the truncated MSE, the free space), rejected as inconsistent (PCM, GNC) or retracted, and undecided, each a namespace and a colour |

use std::path::{Path, PathBuf};

use skid_bag::Encoding;
use skid_bag::write::viz::{self, FrameTransform, LineListMarker, VizType};
use skid_bag::write::{McapWriter, WrittenType, encode};
use skid_core::msgs::PoseWire;
use skid_core::pose::pose_to_wire;
use skid_core::{Point, Pose, RawPoint};

use crate::error::RuntimeError;
use crate::error::output_error;
use crate::host::RobotHost;
use crate::loop_lines::{LOOP_CLASSES, placed_loops};
use crate::map_clouds::RobotClouds;

fn raw_points(points: &[Point]) -> Vec<RawPoint> {
    points
        .iter()
        .map(|p| RawPoint::new(p.x, p.y, p.z, p.intensity, 0.0, RawPoint::UNKNOWN_RING))
        .collect()
}

/// The record's writer with its error mapping.
struct Record {
    writer: McapWriter,
}

impl Record {
    fn topic(&mut self, name: &str, message_type: &str, definition: &str) -> Result<u16, RuntimeError> {
        let added = self.writer.add_topic(name, message_type, definition);
        added.map_err(|e| output_error(self.writer.path(), e))
    }

    fn write(&mut self, channel: u16, stamp_nanos: u64, data: &[u8]) -> Result<(), RuntimeError> {
        let written = self.writer.write(channel, stamp_nanos, data);
        written.map_err(|e| output_error(self.writer.path(), e))
    }

    fn topic_of(&mut self, name: &str, kind: WrittenType) -> Result<u16, RuntimeError> {
        self.topic(name, kind.name(Encoding::Cdr), &kind.definition(Encoding::Cdr))
    }

    fn viz_topic(&mut self, name: &str, kind: VizType) -> Result<u16, RuntimeError> {
        self.topic(name, kind.name(), &kind.definition())
    }
}

/// A frame has one parent: robot 0's `map` goes under the prior's `prior/map` through the first
/// localised robot placed in it, and a localised robot outside robot 0's frame hangs its own map there.
fn prior_transforms(
    robots: &[RobotHost],
    frames: &[Option<Pose>],
    in_prior: &[Option<Pose>],
    stamp_nanos: u64,
) -> Vec<FrameTransform> {
    let transform = |child: String, prior_from_child: Pose| FrameTransform {
        stamp_nanos,
        parent: "prior/map".to_owned(),
        child,
        parent_from_child: pose_to_wire(&prior_from_child),
    };
    let mut transforms: Vec<FrameTransform> = frames
        .iter()
        .zip(in_prior)
        .find_map(|(frame, prior)| Some(transform("map".to_owned(), (*prior)? * frame.as_ref()?.inverse())))
        .into_iter()
        .collect();
    for ((robot, frame), prior) in robots.iter().zip(frames).zip(in_prior) {
        if let (None, Some(prior_from_map)) = (frame, prior) {
            transforms.push(transform(
                format!("robot{}/map", robot.robot().0),
                *prior_from_map,
            ));
        }
    }
    transforms
}

/// Writes `<folder>/run.mcap` from the robots' final state; `clouds` holds each robot's keyframe clouds
/// placed in its map frame and thinned for the record, `frames` places each robot's map frame in robot
/// 0's (as [`crate::artifacts::frames_in_alpha`]) and, with a prior map, each localised robot's map
/// frame in the prior's (`in_prior`), `map` is the merged map.
pub(crate) fn write_run_record(
    folder: &Path,
    robots: &[RobotHost],
    clouds: &[RobotClouds],
    (frames, in_prior): (&[Option<Pose>], &[Option<Pose>]),
    map: &[Point],
) -> Result<PathBuf, RuntimeError> {
    let path = folder.join("run.mcap");
    let writer = McapWriter::create(&path).map_err(|e| output_error(&path, e))?;
    let mut record = Record { writer };
    let stamps = robots
        .iter()
        .flat_map(|r| r.scans().iter().map(|s| s.stamp_nanos));
    let (first_nanos, last_nanos) = stamps.fold((u64::MAX, 0), |(lo, hi), s| (lo.min(s), hi.max(s)));
    let first_nanos = first_nanos.min(last_nanos);

    let tf_static = record.viz_topic("/tf_static", VizType::TfMessage)?;
    let mut placed: Vec<FrameTransform> = robots
        .iter()
        .zip(frames)
        .filter_map(|(robot, frame)| {
            Some(FrameTransform {
                stamp_nanos: first_nanos,
                parent: "map".to_owned(),
                child: format!("robot{}/map", robot.robot().0),
                parent_from_child: pose_to_wire(frame.as_ref()?),
            })
        })
        .collect();
    placed.extend(prior_transforms(robots, frames, in_prior, first_nanos));
    record.write(tf_static, first_nanos, &viz::tf_message(&placed))?;

    let tf = record.viz_topic("/tf", VizType::TfMessage)?;
    for (robot, clouds) in robots.iter().zip(clouds) {
        write_robot(&mut record, tf, robot, clouds, last_nanos)?;
    }

    let map_topic = record.topic_of("/map", WrittenType::PointCloud2)?;
    let cloud = encode::point_cloud2(Encoding::Cdr, 0, last_nanos, "map", &raw_points(map));
    record.write(map_topic, last_nanos, &cloud)?;

    let loops_topic = record.viz_topic("/loops", VizType::MarkerArray)?;
    let markers = loop_markers(robots, frames);
    record.write(
        loops_topic,
        last_nanos,
        &viz::line_markers(last_nanos, "map", &markers),
    )?;

    let written = record.writer.finish().map_err(|e| output_error(&path, e))?;
    Ok(written.path)
}

/// One robot's odometry, transforms, keyframe clouds, optimised path and ground truth.
fn write_robot(
    record: &mut Record,
    tf: u16,
    robot: &RobotHost,
    clouds: &RobotClouds,
    last_nanos: u64,
) -> Result<(), RuntimeError> {
    let name = format!("robot{}", robot.robot().0);
    let (map_frame, odom_frame, sensor_frame) = (
        format!("{name}/map"),
        format!("{name}/odom"),
        format!("{name}/base_link"),
    );
    let odometry = record.topic_of(&format!("/{name}/odometry"), WrittenType::Odometry)?;
    let optimised = robot.optimised_trajectory();
    for (sequence, (scan, (_, corrected))) in robot.scans().iter().zip(&optimised).enumerate() {
        let pose = pose_to_wire(&scan.world_from_sensor);
        let frames = (odom_frame.as_str(), sensor_frame.as_str());
        let message = encode::odometry(
            Encoding::Cdr,
            sequence as u32,
            scan.stamp_nanos,
            frames,
            pose.translation_m,
            pose.rotation_xyzw,
        );
        record.write(odometry, scan.stamp_nanos, &message)?;
        let correction = corrected * scan.world_from_sensor.inverse();
        let transforms = [
            FrameTransform {
                stamp_nanos: scan.stamp_nanos,
                parent: odom_frame.clone(),
                child: sensor_frame.clone(),
                parent_from_child: pose,
            },
            FrameTransform {
                stamp_nanos: scan.stamp_nanos,
                parent: map_frame.clone(),
                child: odom_frame.clone(),
                parent_from_child: pose_to_wire(&correction),
            },
        ];
        record.write(tf, scan.stamp_nanos, &viz::tf_message(&transforms))?;
    }

    let keyframes = record.topic_of(&format!("/{name}/keyframes"), WrittenType::PointCloud2)?;
    for keyframe in &clouds.keyframes {
        let message = encode::point_cloud2(
            Encoding::Cdr,
            keyframe.index,
            keyframe.stamp_nanos,
            &map_frame,
            &raw_points(&keyframe.points),
        );
        record.write(keyframes, keyframe.stamp_nanos, &message)?;
    }

    let path_topic = record.viz_topic(&format!("/{name}/path"), VizType::Path)?;
    let poses: Vec<(u64, PoseWire)> = optimised
        .iter()
        .map(|(stamp, pose)| (*stamp, pose_to_wire(pose)))
        .collect();
    record.write(path_topic, last_nanos, &viz::path(last_nanos, &map_frame, &poses))?;

    let truth: Vec<(u64, PoseWire)> = robot
        .scans()
        .iter()
        .filter_map(|scan| Some((scan.stamp_nanos, pose_to_wire(scan.ground_truth.as_ref()?))))
        .collect();
    if !truth.is_empty() {
        let truth_topic = record.viz_topic(&format!("/{name}/ground_truth"), VizType::Path)?;
        record.write(truth_topic, last_nanos, &viz::path(last_nanos, "world", &truth))?;
    }
    Ok(())
}

/// Every robot's submitted loops as line lists, one per class.
fn loop_markers(robots: &[RobotHost], frames: &[Option<Pose>]) -> Vec<LineListMarker> {
    let mut markers: Vec<LineListMarker> = LOOP_CLASSES
        .iter()
        .enumerate()
        .map(|(id, (namespace, rgba, _))| LineListMarker {
            namespace: (*namespace).to_owned(),
            id: id as i32,
            rgba: *rgba,
            line_width_m: 0.3,
            segments: Vec::new(),
        })
        .collect();
    for line in placed_loops(robots, frames) {
        markers[line.class].segments.push((line.target_m, line.source_m));
    }
    markers
}
