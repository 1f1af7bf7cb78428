//! One robot's live ROS 2 topics, put on zenoh the way `rmw_zenoh` publishes (see [`crate::keys`]), as a
//! [`HostObserver`] of the robot's host. Frames are the run record's: `robot<i>/map` (the robot's
//! optimised frame), `robot<i>/odom` and `robot<i>/base_link` (the sensor). Topics of robot `i`:
//!
//! | topic | type | when |
//! |---|---|---|
//! | `/robot<i>/odometry` | `nav_msgs/Odometry` | every scan, in `robot<i>/odom` |
//! | `/tf` | `tf2_msgs/TFMessage` | every scan: `odom → base_link` and the back-end's correction `map → odom` |
//! | `/robot<i>/path` | `nav_msgs/Path` | after every optimisation: the optimised trajectory, in `robot<i>/map` |
//! | `/robot<i>/loops` | `visualization_msgs/MarkerArray` | after every optimisation: the robot's loops by standing, and each peer's keyframes as the robot's graph places them |
//! | `/robot<i>/map` | `sensor_msgs/PointCloud2` | every `map_every` optimisations and at the end: the keyframe clouds at their optimised poses, thinned |
//! | `/robot<i>/localisation` | `std_msgs/String` | with a prior map (`[prior]`), at the first scan and whenever it changes: the robot's standing in the prior as JSON (`localised`, `through_session_robot`, `via_robot`, `loops`) |
//!
//! Once a robot is localised in a prior map, every scan's `/tf` also places its `robot<i>/map` in
//! `prior/map`, where its loops with the prior put it.
//!
//! Odometry and transforms are dropped when the network falls behind (a viewer must never stall a
//! robot); paths, loops and maps, rarer and each complete in itself, are sent reliably.

use skid_bag::Encoding;
use skid_bag::write::encode;
use skid_bag::write::viz::{self, FrameTransform, LineListMarker};
use skid_core::pose::pose_to_wire;
use skid_core::{KeyframeId, Pose, RawPoint, RobotId};
use skid_runtime::{HostObserver, LOOP_CLASSES, Localisation, RobotHost, own_frame_loops};
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;

use crate::keys::{Ros2Type, attachment, data_key, publisher_token};
use crate::{LiveError, LiveSettings, SharedSession};

/// The prior map's frame, as the run record names it.
const PRIOR_MAP_FRAME: &str = "prior/map";

/// One topic: its zenoh publisher, its liveliness token and what its attachments carry.
struct Topic {
    name: String,
    publisher: Publisher<'static>,
    gid: [u8; 16],
    sequence: i64,
    _token: LivelinessToken,
}

impl Topic {
    fn put(&mut self, message: Vec<u8>) {
        self.sequence += 1;
        let now_nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX));
        let sent = self
            .publisher
            .put(message)
            .attachment(attachment(self.sequence, now_nanos, &self.gid))
            .wait();
        if let Err(error) = sent {
            tracing::warn!(topic = %self.name, %error, "live ROS 2 output: message not sent");
        }
    }
}

/// Robot `i`'s live ROS 2 output.
pub struct Ros2Live {
    robot: RobotId,
    settings: LiveSettings,
    frames: [String; 3],
    odometry: Topic,
    tf: Topic,
    path: Topic,
    loops: Topic,
    map: Topic,
    localisation: Topic,
    /// The standing last published on `localisation`.
    last_standing: Option<String>,
    /// The latest correction `map → odom` (identity until the first optimisation).
    map_from_odom: Pose,
    optimizations_seen: u32,
    _node: LivelinessToken,
}

impl std::fmt::Debug for Ros2Live {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Live").field("robot", &self.robot).finish()
    }
}

impl Ros2Live {
    /// Declares robot `robot`'s node and publishers on `session`.
    pub fn new(session: &SharedSession, robot: RobotId, settings: LiveSettings) -> Result<Self, LiveError> {
        let name = format!("robot{}", robot.0);
        let namespace = format!("/{name}");
        let node_id = session.next_entity_id();
        let node = session.token(&crate::keys::node_token(
            settings.domain_id,
            &session.id(),
            node_id,
            &namespace,
            "skid",
        ))?;
        let topic = |topic: String, kind: Ros2Type, reliable: bool| -> Result<Topic, LiveError> {
            let entity_id = session.next_entity_id();
            let token = session.token(&publisher_token(
                settings.domain_id,
                &session.id(),
                (node_id, entity_id),
                (&namespace, "skid"),
                &topic,
                kind,
            ))?;
            let congestion = if reliable {
                CongestionControl::Block
            } else {
                CongestionControl::Drop
            };
            let publisher = session
                .session()
                .declare_publisher(data_key(settings.domain_id, &topic, kind))
                .congestion_control(congestion)
                .wait()
                .map_err(|e| LiveError::Zenoh(format!("declaring the publisher of {topic}: {e}")))?;
            let mut gid = [0u8; 16];
            gid[..4].copy_from_slice(&robot.0.to_le_bytes());
            gid[4..8].copy_from_slice(&entity_id.to_le_bytes());
            Ok(Topic {
                name: topic,
                publisher,
                gid,
                sequence: 0,
                _token: token,
            })
        };
        Ok(Self {
            robot,
            odometry: topic(format!("{namespace}/odometry"), Ros2Type::Odometry, false)?,
            tf: topic("/tf".to_owned(), Ros2Type::TfMessage, false)?,
            path: topic(format!("{namespace}/path"), Ros2Type::Path, true)?,
            loops: topic(format!("{namespace}/loops"), Ros2Type::MarkerArray, true)?,
            map: topic(format!("{namespace}/map"), Ros2Type::PointCloud2, true)?,
            localisation: topic(format!("{namespace}/localisation"), Ros2Type::String, true)?,
            last_standing: None,
            frames: [
                format!("{name}/map"),
                format!("{name}/odom"),
                format!("{name}/base_link"),
            ],
            settings,
            map_from_odom: Pose::identity(),
            optimizations_seen: 0,
            _node: node,
        })
    }

    /// The correction from odometry to the optimised frame at the newest keyframe with both poses.
    fn correction(host: &RobotHost) -> Option<Pose> {
        let index = host.scans().iter().rev().find_map(|scan| scan.keyframe)?;
        let id = KeyframeId {
            robot: host.robot(),
            index,
        };
        Some(host.keyframe_pose(index)? * host.chains().pose(id)?.inverse())
    }

    /// Publishes the robot's standing in the prior map, `placed`, when it has changed (a run with a prior
    /// only).
    fn publish_standing(&mut self, placed: Option<&Localisation>) {
        if !self.settings.prior {
            return;
        }
        let standing = serde_json::json!({
            "robot": self.robot.0,
            "localised": placed.is_some(),
            "through_session_robot": placed.and_then(|p| p.session_robot),
            "via_robot": placed.and_then(|p| p.via).map(|robot| robot.0),
            "loops": placed.map_or(0, |p| p.loops),
        })
        .to_string();
        if self.last_standing.as_deref() != Some(standing.as_str()) {
            self.localisation.put(encode::string(Encoding::Cdr, &standing));
            self.last_standing = Some(standing);
        }
    }

    fn publish_map(&mut self, host: &RobotHost, stamp_nanos: u64) {
        let mut points = Vec::new();
        for (&index, keyframe) in host.keyframes() {
            if let Some(pose) = host.keyframe_pose(index) {
                points.extend(keyframe.cloud.view().transformed(&pose).points);
            }
        }
        let thinned = skid_geometry::voxel_downsample(&points, self.settings.voxel_m as f32);
        let raw: Vec<RawPoint> = thinned
            .iter()
            .map(|p| RawPoint::new(p.x, p.y, p.z, p.intensity, 0.0, RawPoint::UNKNOWN_RING))
            .collect();
        let message = encode::point_cloud2(Encoding::Cdr, 0, stamp_nanos, &self.frames[0], &raw);
        self.map.put(message);
    }

    fn publish_loops(&mut self, host: &RobotHost, stamp_nanos: u64) {
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
        for line in own_frame_loops(host) {
            markers[line.class].segments.push((line.target_m, line.source_m));
        }
        // Each peer's keyframes as this robot's graph places them, joined in order.
        if let Some(graph) = host.backend_graph() {
            for (peer, _) in host.joined_peers() {
                let positions: Vec<[f64; 3]> = host
                    .graph_keyframes_of(peer)
                    .filter_map(|id| graph.pose(id))
                    .map(|pose| {
                        let t = pose.translation.vector;
                        [t.x, t.y, t.z]
                    })
                    .collect();
                markers.push(LineListMarker {
                    namespace: format!("peer robot{}", peer.0),
                    id: 100 + peer.0 as i32,
                    rgba: [0.2, 0.4, 1.0, 1.0],
                    line_width_m: 0.2,
                    segments: positions.windows(2).map(|w| (w[0], w[1])).collect(),
                });
            }
        }
        self.loops
            .put(viz::line_markers(stamp_nanos, &self.frames[0], &markers));
    }
}

impl HostObserver for Ros2Live {
    fn scan(&mut self, host: &RobotHost) {
        let Some(scan) = host.scans().last() else {
            return;
        };
        let pose = pose_to_wire(&scan.world_from_sensor);
        let message = encode::odometry(
            Encoding::Cdr,
            host.scans().len() as u32,
            scan.stamp_nanos,
            (&self.frames[1], &self.frames[2]),
            pose.translation_m,
            pose.rotation_xyzw,
        );
        self.odometry.put(message);
        let mut transforms = vec![
            FrameTransform {
                stamp_nanos: scan.stamp_nanos,
                parent: self.frames[1].clone(),
                child: self.frames[2].clone(),
                parent_from_child: pose,
            },
            FrameTransform {
                stamp_nanos: scan.stamp_nanos,
                parent: self.frames[0].clone(),
                child: self.frames[1].clone(),
                parent_from_child: pose_to_wire(&self.map_from_odom),
            },
        ];
        let placed = if self.settings.prior {
            host.localisation()
        } else {
            None
        };
        if let Some(placed) = &placed {
            transforms.push(FrameTransform {
                stamp_nanos: scan.stamp_nanos,
                parent: PRIOR_MAP_FRAME.to_owned(),
                child: self.frames[0].clone(),
                parent_from_child: pose_to_wire(&placed.prior_from_map),
            });
        }
        self.tf.put(viz::tf_message(&transforms));
        self.publish_standing(placed.as_ref());
    }

    fn optimized(&mut self, host: &RobotHost) {
        let stamp_nanos = host.scans().last().map_or(0, |scan| scan.stamp_nanos);
        self.map_from_odom = Self::correction(host).unwrap_or(self.map_from_odom);
        let poses: Vec<(u64, skid_core::msgs::PoseWire)> = host
            .optimised_trajectory()
            .iter()
            .map(|(stamp, pose)| (*stamp, pose_to_wire(pose)))
            .collect();
        self.path.put(viz::path(stamp_nanos, &self.frames[0], &poses));
        self.publish_loops(host, stamp_nanos);
        self.optimizations_seen += 1;
        if self.settings.map_every > 0 && self.optimizations_seen.is_multiple_of(self.settings.map_every) {
            self.publish_map(host, stamp_nanos);
        }
    }

    fn finished(&mut self, host: &RobotHost) {
        let stamp_nanos = host.scans().last().map_or(0, |scan| scan.stamp_nanos);
        self.publish_map(host, stamp_nanos);
    }
}
