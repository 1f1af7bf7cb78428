//! Assembling scans from a bag's interleaved messages: each point cloud waits (a few clouds at most)
//! until the IMU and ground-truth topics have passed its stamp, then takes the IMU samples since the
//! previous scan and the ground truth interpolated at its stamp. Clouds are `sensor_msgs/PointCloud2` or
//! Livox's `CustomMsg` (decoded from the definition the bag stores).

use std::collections::VecDeque;
use std::sync::Arc;

use skid_bag::msgs::livox::{decode_livox_custom, is_livox_custom};
use skid_bag::msgs::motion::{self, StampedPose};
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2, PointField, raw_points};
use std::path::{Path, PathBuf};

use skid_bag::{BagError, Connection, MessageReader, RawMessage, WireReader, require_topic};
use skid_core::{ImuSample, Pose, RawPoint, Scan};

use crate::static_frames::StaticFrames;

/// The topics one robot reads.
#[derive(Clone, Debug)]
pub struct Topics {
    pub points: String,
    pub imu: Option<String>,
    pub ground_truth: Option<String>,
    /// The child frame taken from a `/tf` ground-truth topic.
    pub ground_truth_frame: String,
    /// The static transform topic (`/tf_static`) the LiDAR→IMU extrinsic is read from, when the
    /// recording has it.
    pub tf_static: Option<String>,
}

/// Clouds decoded ahead of the IMU and ground truth at most; past it a cloud goes out without waiting.
const MAX_PENDING_SCANS: usize = 8;
/// Ground truth further than this from a scan stamp (outside the recorded poses) is not used.
const GROUND_TRUTH_TOLERANCE_NANOS: u64 = 100_000_000;

/// Turns a message stream (a bag, or live topics) into scans.
pub struct ScanAssembler {
    messages: Box<dyn MessageReader>,
    /// What errors name: the bag's path, or the live source's description.
    label: PathBuf,
    topics: Topics,
    drop_zero: bool,
    pending: VecDeque<Scan>,
    imu: VecDeque<ImuSample>,
    ground_truth: VecDeque<(u64, Pose)>,
    latest_imu_nanos: Option<u64>,
    latest_ground_truth_nanos: Option<u64>,
    previous_scan_nanos: Option<u64>,
    cloud_index: u64,
    other_index: u64,
    layout: Option<(Vec<PointField>, CloudLayout)>,
    ended: bool,
    extrinsic: Extrinsic,
}

/// What the LiDAR→IMU extrinsic is found from: the static transforms and the frames the cloud and
/// IMU messages name.
#[derive(Default)]
struct Extrinsic {
    frames: StaticFrames,
    cloud_frame: Option<String>,
    imu_frame: Option<String>,
    imu_from_sensor: Option<Pose>,
    reported: bool,
}

impl Extrinsic {
    /// `imu_from_sensor` once the frames are known and the static tree connects them.
    fn resolve(&mut self, label: &Path) -> Option<Pose> {
        if self.imu_from_sensor.is_none()
            && let (Some(cloud), Some(imu)) = (&self.cloud_frame, &self.imu_frame)
            && !self.frames.is_empty()
        {
            self.imu_from_sensor = self.frames.transform(imu, cloud);
            if !self.reported {
                self.reported = true;
                match self.imu_from_sensor {
                    Some(pose) => tracing::info!(
                        "{}: LiDAR→IMU extrinsic from the static transforms ({imu} ← {cloud}): translation {:?} m",
                        label.display(),
                        pose.translation.vector.as_slice()
                    ),
                    None => tracing::warn!(
                        "{}: the static transforms do not connect the IMU frame `{imu}` and the cloud frame `{cloud}`; no extrinsic",
                        label.display()
                    ),
                }
            }
        }
        self.imu_from_sensor
    }
}

impl ScanAssembler {
    /// Checks the topics against the bag (when it lists its topics up front) and selects them.
    pub fn new(
        mut messages: Box<dyn MessageReader>,
        label: PathBuf,
        topics: Topics,
        drop_zero: bool,
    ) -> Result<Self, BagError> {
        let mut selected = vec![topics.points.clone()];
        selected.extend(topics.imu.iter().cloned());
        selected.extend(topics.ground_truth.iter().cloned());
        for topic in &selected {
            if let Some(connection) = require_topic(messages.as_ref(), &label, topic)? {
                check_type(&label, &topics, &connection)?;
            }
        }
        // The static transforms are read when the recording has them (or may have: a stream that does
        // not list its topics up front); their absence is no error.
        let mut topics = topics;
        topics.tf_static = topics.tf_static.filter(|topic| {
            !messages.connections_complete()
                || messages
                    .connections()
                    .iter()
                    .any(|c| c.topic == *topic && c.message_type == "tf2_msgs/TFMessage")
        });
        selected.extend(topics.tf_static.iter().cloned());
        messages.select_topics(&selected);
        Ok(Self {
            messages,
            label,
            topics,
            drop_zero,
            pending: VecDeque::new(),
            imu: VecDeque::new(),
            ground_truth: VecDeque::new(),
            latest_imu_nanos: None,
            latest_ground_truth_nanos: None,
            previous_scan_nanos: None,
            cloud_index: 0,
            other_index: 0,
            layout: None,
            ended: false,
            extrinsic: Extrinsic::default(),
        })
    }

    /// Whether an IMU topic is read (configured, and checked against the recording's topics when it
    /// lists them up front).
    pub fn reads_imu(&self) -> bool {
        self.topics.imu.is_some()
    }

    /// The next scan in the order the clouds were recorded, `None` at the end of the bag.
    pub fn next_scan(&mut self) -> Result<Option<Scan>, BagError> {
        loop {
            if let Some(front) = self.pending.front() {
                if self.ended || self.has_passed(front.stamp_nanos) || self.pending.len() > MAX_PENDING_SCANS
                {
                    let scan = self.pending.pop_front();
                    return Ok(scan.map(|scan| self.complete(scan)));
                }
            } else if self.ended {
                return Ok(None);
            }
            match self.messages.next_message()? {
                None => self.ended = true,
                Some(message) => self.take(message)?,
            }
        }
    }

    /// Whether every auxiliary topic has a message at or after `stamp_nanos`.
    fn has_passed(&self, stamp_nanos: u64) -> bool {
        let passed = |topic: &Option<String>, latest: Option<u64>| {
            topic.is_none() || latest.is_some_and(|t| t >= stamp_nanos)
        };
        passed(&self.topics.imu, self.latest_imu_nanos)
            && passed(&self.topics.ground_truth, self.latest_ground_truth_nanos)
    }

    fn message_error(&self, message: &RawMessage, index: u64, problem: impl ToString) -> BagError {
        BagError::Message {
            path: self.label.clone(),
            topic: message.connection.topic.clone(),
            index,
            message: problem.to_string(),
        }
    }

    fn take(&mut self, message: RawMessage) -> Result<(), BagError> {
        let topic = message.connection.topic.as_str();
        if topic == self.topics.points {
            check_type(&self.label, &self.topics, &message.connection)?;
            let index = self.cloud_index;
            self.cloud_index += 1;
            let scan = self
                .decode_cloud(&message)
                .map_err(|problem| self.message_error(&message, index, problem))?;
            self.pending.push_back(scan);
            return Ok(());
        }
        let index = self.other_index;
        self.other_index += 1;
        let mut reader = WireReader::new(&message.data, message.connection.encoding)
            .map_err(|problem| self.message_error(&message, index, problem))?;
        if self.topics.tf_static.as_deref() == Some(topic) {
            let transforms = motion::decode_tf_message(&mut reader)
                .map_err(|problem| self.message_error(&message, index, problem))?;
            for transform in transforms {
                if let Some(pose) = to_pose(&transform) {
                    self.extrinsic
                        .frames
                        .insert(&transform.frame_id, &transform.child_frame_id, pose);
                }
            }
        } else if self.topics.imu.as_deref() == Some(topic) {
            check_type(&self.label, &self.topics, &message.connection)?;
            if self.extrinsic.imu_frame.is_none() {
                let frame = reader
                    .clone()
                    .header()
                    .map(|header| header.frame_id)
                    .unwrap_or_default();
                self.extrinsic.imu_frame = Some(frame).filter(|f| !f.is_empty());
            }
            let sample = motion::decode_imu(&mut reader)
                .map_err(|problem| self.message_error(&message, index, problem))?;
            self.latest_imu_nanos = Some(self.latest_imu_nanos.unwrap_or(0).max(sample.stamp_nanos));
            self.imu.push_back(sample);
        } else if self.topics.ground_truth.as_deref() == Some(topic) {
            let poses = decode_poses(&message.connection, &mut reader, &self.topics.ground_truth_frame)
                .map_err(|problem| self.message_error(&message, index, problem))?;
            for pose in poses {
                let stamp = pose.stamp_nanos;
                let pose = to_pose(&pose).ok_or_else(|| {
                    self.message_error(
                        &message,
                        index,
                        "the pose is not finite or its quaternion is zero",
                    )
                })?;
                self.latest_ground_truth_nanos = Some(self.latest_ground_truth_nanos.unwrap_or(0).max(stamp));
                self.ground_truth.push_back((stamp, pose));
            }
        }
        Ok(())
    }

    fn decode_cloud(&mut self, message: &RawMessage) -> Result<Scan, skid_bag::DecodeError> {
        let mut reader = WireReader::new(&message.data, message.connection.encoding)?;
        let connection = &message.connection;
        if is_livox_custom(&connection.message_type) {
            let cloud = decode_livox_custom(&mut reader, &connection.message_type, &connection.definition)?;
            self.note_cloud_frame(&cloud.header.frame_id);
            return Ok(self.scan_of(
                connection,
                cloud.header.stamp_nanos,
                cloud.points,
                cloud.dropped_non_finite,
            ));
        }
        let cloud = PointCloud2::decode(&mut reader)?;
        self.note_cloud_frame(&cloud.header.frame_id);
        let layout = match &self.layout {
            Some((fields, layout)) if *fields == cloud.fields => layout.clone(),
            _ => {
                let layout = CloudLayout::detect(&cloud.fields)?;
                self.layout = Some((cloud.fields.clone(), layout.clone()));
                layout
            }
        };
        let decoded = raw_points(&cloud, &layout);
        Ok(self.scan_of(
            connection,
            cloud.header.stamp_nanos,
            decoded.points,
            decoded.dropped_non_finite,
        ))
    }

    fn note_cloud_frame(&mut self, frame: &str) {
        if self.extrinsic.cloud_frame.is_none() && !frame.is_empty() {
            self.extrinsic.cloud_frame = Some(frame.to_owned());
        }
    }

    fn scan_of(
        &self,
        connection: &Connection,
        stamp_nanos: u64,
        mut points: Vec<RawPoint>,
        dropped: usize,
    ) -> Scan {
        if self.drop_zero {
            points.retain(|p| p.x != 0.0 || p.y != 0.0 || p.z != 0.0);
        }
        if dropped > 0 {
            tracing::debug!("{}: dropped {dropped} non-finite points", connection.topic);
        }
        Scan {
            stamp_nanos,
            points,
            ..Scan::default()
        }
    }

    /// Attaches the IMU samples since the previous scan and the interpolated ground truth.
    fn complete(&mut self, mut scan: Scan) -> Scan {
        let stamp = scan.stamp_nanos;
        let after = self.previous_scan_nanos;
        while let Some(sample) = self.imu.front() {
            if sample.stamp_nanos > stamp {
                break;
            }
            if after.is_none_or(|previous| sample.stamp_nanos > previous) {
                scan.imu.push(*sample);
            }
            self.imu.pop_front();
        }
        scan.ground_truth_world_from_sensor = self.ground_truth_at(stamp);
        scan.imu_from_sensor = self.extrinsic.resolve(&self.label);
        self.previous_scan_nanos = Some(stamp);
        scan
    }

    fn ground_truth_at(&mut self, stamp: u64) -> Option<Pose> {
        // Keep the last pose at or before the stamp as the start of the next bracket.
        while self.ground_truth.len() > 1 && self.ground_truth[1].0 <= stamp {
            self.ground_truth.pop_front();
        }
        let (t0, p0) = *self.ground_truth.front()?;
        match self.ground_truth.get(1) {
            Some(&(t1, p1)) if t0 <= stamp && stamp <= t1 && t1 > t0 => {
                Some(p0.lerp_slerp(&p1, (stamp - t0) as f64 / (t1 - t0) as f64))
            }
            _ => (t0.abs_diff(stamp) <= GROUND_TRUTH_TOLERANCE_NANOS).then_some(p0),
        }
    }
}

/// Refuses a topic whose type is not what its role needs, naming the file, topic and type.
fn check_type(label: &Path, topics: &Topics, connection: &Arc<Connection>) -> Result<(), BagError> {
    let expected: &[&str] = if connection.topic == topics.points {
        &[
            "sensor_msgs/PointCloud2",
            "livox_ros_driver/CustomMsg",
            "livox_ros_driver2/CustomMsg",
        ]
    } else if topics.imu.as_deref() == Some(connection.topic.as_str()) {
        &["sensor_msgs/Imu"]
    } else {
        &[
            "nav_msgs/Odometry",
            "geometry_msgs/PoseStamped",
            "tf2_msgs/TFMessage",
        ]
    };
    if expected.contains(&connection.message_type.as_str()) {
        return Ok(());
    }
    Err(BagError::Message {
        path: label.to_owned(),
        topic: connection.topic.clone(),
        index: 0,
        message: format!(
            "carries {}, not {}",
            connection.message_type,
            expected.join(" or ")
        ),
    })
}

fn decode_poses(
    connection: &Connection,
    reader: &mut WireReader<'_>,
    frame: &str,
) -> Result<Vec<StampedPose>, skid_bag::DecodeError> {
    match connection.message_type.as_str() {
        "nav_msgs/Odometry" => Ok(vec![motion::decode_odometry(reader)?]),
        "geometry_msgs/PoseStamped" => Ok(vec![motion::decode_pose_stamped(reader)?]),
        _ => {
            if frame.is_empty() {
                return Err(skid_bag::DecodeError(
                    "a /tf ground-truth topic needs `ground_truth_frame`, the child frame to follow"
                        .to_owned(),
                ));
            }
            let mut transforms = motion::decode_tf_message(reader)?;
            transforms.retain(|t| t.child_frame_id == frame);
            Ok(transforms)
        }
    }
}

/// A ROS pose as an isometry, `None` when it is not finite or its quaternion has no direction.
pub(crate) fn to_pose(pose: &StampedPose) -> Option<Pose> {
    skid_core::pose::pose_from_wire(&pose.wire())
}
