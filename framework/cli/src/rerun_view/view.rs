//! One robot's entities in the Rerun recording, logged by a [`HostObserver`] on the `scan_time`
//! timeline. Robot `i`'s entities sit under `robot<i>/` in the robot's own map frame; robot 0's map is
//! the world, and robot 0's view places each peer's subtree (`robot<j>`) where robot 0's graph puts
//! that peer's odometry frame once a loop has joined them.
//!
//! | entity | archetype | when |
//! |---|---|---|
//! | `robot<i>/pose` | `Transform3D` and `robot<i>/position` `Points3D` | every scan: the odometry corrected by the back-end |
//! | `robot<i>/path` | `LineStrips3D` | after every optimisation: the optimised trajectory |
//! | `robot<i>/loops` | `LineStrips3D` | after every optimisation: the robot's loops, coloured by standing |
//! | `robot<i>/map` | `Points3D` | every `map_every` optimisations and at the end |
//! | `link/robot<i>/sent_bytes`, `received_bytes` | `Scalars` | every scan: bytes through the transport so far |
//! | `link/robot<i>/cloud_wait_s` | `Scalars` | every scan: how long the oldest unanswered cloud request has waited |

use skid_core::{KeyframeId, Pose};
use skid_runtime::{HostObserver, LOOP_CLASSES, RobotHost, own_frame_loops};

/// The timeline every entity is logged on.
pub const TIMELINE: &str = "scan_time";

fn position(pose: &Pose) -> [f32; 3] {
    let t = pose.translation.vector;
    [t.x as f32, t.y as f32, t.z as f32]
}

fn transform(pose: &Pose) -> rerun::Transform3D {
    let q = pose.rotation.quaternion();
    rerun::Transform3D::from_translation_rotation(
        position(pose),
        rerun::Quaternion::from_xyzw([q.i as f32, q.j as f32, q.k as f32, q.w as f32]),
    )
}

fn rgba(channels: [f32; 4]) -> rerun::Color {
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    rerun::Color::from_unmultiplied_rgba(
        byte(channels[0]),
        byte(channels[1]),
        byte(channels[2]),
        byte(channels[3]),
    )
}

/// Robot `i`'s part of the recording.
pub struct RerunView {
    stream: rerun::RecordingStream,
    name: String,
    map_every: u32,
    optimizations_seen: u32,
    /// The latest correction `map → odom` (identity until the first optimisation).
    map_from_odom: Pose,
}

impl std::fmt::Debug for RerunView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RerunView").field("robot", &self.name).finish()
    }
}

impl RerunView {
    pub fn new(stream: rerun::RecordingStream, robot: skid_core::RobotId, map_every: u32) -> Self {
        Self {
            stream,
            name: format!("robot{}", robot.0),
            map_every,
            optimizations_seen: 0,
            map_from_odom: Pose::identity(),
        }
    }

    fn log(&self, entity: &str, what: &impl rerun::AsComponents) {
        if let Err(error) = self.stream.log(format!("{}/{entity}", self.name), what) {
            tracing::warn!(robot = %self.name, entity, %error, "rerun: not logged");
        }
    }

    fn at(&self, stamp_nanos: u64) {
        self.stream.set_duration_secs(TIMELINE, stamp_nanos as f64 * 1e-9);
    }

    fn log_map(&self, host: &RobotHost) {
        let mut points = Vec::new();
        for (&index, keyframe) in host.keyframes() {
            if let Some(pose) = host.keyframe_pose(index) {
                points.extend(keyframe.cloud.view().transformed(&pose).points);
            }
        }
        let thinned = skid_geometry::voxel_downsample(&points, 0.5);
        let positions: Vec<[f32; 3]> = thinned.iter().map(|p| [p.x, p.y, p.z]).collect();
        self.log("map", &rerun::Points3D::new(positions).with_radii([0.1f32]));
    }

    fn log_loops(&self, host: &RobotHost) {
        let lines = own_frame_loops(host);
        let strips: Vec<[[f32; 3]; 2]> = lines
            .iter()
            .map(|l| {
                let f = |p: [f64; 3]| [p[0] as f32, p[1] as f32, p[2] as f32];
                [f(l.target_m), f(l.source_m)]
            })
            .collect();
        let colors: Vec<rerun::Color> = lines.iter().map(|l| rgba(LOOP_CLASSES[l.class].1)).collect();
        self.log("loops", &rerun::LineStrips3D::new(strips).with_colors(colors));
    }

    /// Robot 0 places each peer it has joined in its own (the world's) frame.
    fn log_peer_frames(&self, host: &RobotHost) {
        if host.robot().0 != 0 {
            return;
        }
        for (peer, odom_in_map) in host.joined_peers() {
            if let Err(error) = self
                .stream
                .log(format!("robot{}", peer.0), &transform(&odom_in_map))
            {
                tracing::warn!(%error, "rerun: peer frame not logged");
            }
        }
    }
}

impl HostObserver for RerunView {
    fn scan(&mut self, host: &RobotHost) {
        let Some(scan) = host.scans().last() else {
            return;
        };
        self.at(scan.stamp_nanos);
        let pose = self.map_from_odom * scan.world_from_sensor;
        self.log("pose", &transform(&pose));
        self.log(
            "position",
            &rerun::Points3D::new([position(&pose)]).with_radii([0.4f32]),
        );
        let counters = host.protocol().counters().snapshot();
        let wait_s = host.oldest_cloud_request_nanos().map_or(0.0, |sent_nanos| {
            scan.stamp_nanos.saturating_sub(sent_nanos) as f64 * 1e-9
        });
        for (name, value) in [
            ("sent_bytes", counters.sent_total.bytes as f64),
            ("received_bytes", counters.received_total.bytes as f64),
            ("cloud_wait_s", wait_s),
        ] {
            let entity = format!("link/{}/{name}", self.name);
            if let Err(error) = self.stream.log(entity, &rerun::Scalars::single(value)) {
                tracing::warn!(robot = %self.name, %error, "rerun: link statistic not logged");
            }
        }
    }

    fn optimized(&mut self, host: &RobotHost) {
        let Some(last) = host.scans().last() else {
            return;
        };
        self.at(last.stamp_nanos);
        if let Some(index) = host.scans().iter().rev().find_map(|scan| scan.keyframe) {
            let id = KeyframeId {
                robot: host.robot(),
                index,
            };
            if let (Some(optimised), Some(odometry)) = (host.keyframe_pose(index), host.chains().pose(id)) {
                self.map_from_odom = optimised * odometry.inverse();
            }
        }
        let path: Vec<[f32; 3]> = host
            .optimised_trajectory()
            .iter()
            .map(|(_, pose)| position(pose))
            .collect();
        self.log("path", &rerun::LineStrips3D::new([path]));
        self.log_loops(host);
        self.log_peer_frames(host);
        self.optimizations_seen += 1;
        if self.map_every > 0 && self.optimizations_seen.is_multiple_of(self.map_every) {
            self.log_map(host);
        }
    }

    fn finished(&mut self, host: &RobotHost) {
        if let Some(last) = host.scans().last() {
            self.at(last.stamp_nanos);
        }
        self.log_map(host);
        if let Err(error) = self.stream.flush_blocking() {
            tracing::warn!(robot = %self.name, %error, "rerun: the recording was not flushed");
        }
    }
}
