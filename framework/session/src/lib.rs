//! A SKiD session on disk: what a run leaves behind so that a later run can relocalise in its map, grow
//! it, or merge it with another session.
//!
//! The layout follows the session folder of LT-mapper (Kim et al., "LT-mapper: A Modular Framework for
//! LiDAR-based Lifelong Mapping", ICRA 2022): one pose graph per session, the keyframe scans and their
//! place descriptors beside it, and one anchor per session. SKiD's sessions hold several robots, so each
//! robot has its folder and its map frame's place in the session's map frame (robot 0's map).
//!
//! ## Layout (format `skid-session`, version 1)
//!
//! ```text
//! session/
//!   session.json                 the manifest: format and version, the SKiD version, the run's name,
//!                                the descriptor (kind, parameters, length), the effective configuration
//!                                (TOML text) and, per robot, where its map frame sits in the session's
//!   robot<i>/keyframes.json      per keyframe: index, stamp (ns), pose in the robot's map frame (the
//!                                back-end's optimised estimate), the odometry's pose, the true pose
//!                                when the source knew it (`ground_truth`, optional), the point count
//!   robot<i>/descriptors.bin     the keyframes' descriptors (below)
//!   robot<i>/pose_graph.g2o      the robot's pose graph: its keyframes and the peers' it held (vertex id
//!                                = robot · 10⁶ + keyframe index), odometry edges and the accepted loops
//!   robot<i>/clouds/<index>.ply  each keyframe's cloud in its sensor frame, binary PLY (x y z intensity),
//!                                at the resolution registration used (the keyframe's voxel centroids)
//! ```
//!
//! Poses in JSON are `{"translation_m": [x, y, z], "rotation_xyzw": [qx, qy, qz, qw]}`, the pose of the
//! named frame's child in its parent (`map_from_sensor` places the sensor in the map).
//!
//! `descriptors.bin` is little-endian: the 8 bytes `SKIDDESC`, a `u32` format version (1), a `u32`
//! descriptor length `n` and a `u64` entry count, then per entry a `u32` keyframe index and `n` `f32`
//! values. Every length is checked against the file's size before anything is allocated.
//!
//! A reader refuses a session of another format or a newer version, a manifest whose robots, keyframes
//! and descriptors disagree, and truncated or malformed files, naming the file and the entry.

mod descriptors;
mod error;
mod info;
mod join;
mod manifest;
mod model;
mod place;
mod read;
mod truth;
mod write;

pub use descriptors::{DecodedDescriptors, decode_descriptors, encode_descriptors};
pub use error::SessionError;
pub use info::{RobotInfo, SessionInfo};
pub use join::{JoinPart, Joined, PartClouds, write_joined};
pub use manifest::PoseRecord;
pub use model::{DescriptorSpec, Session, SessionKeyframe, SessionRobot};
pub use place::{AGREE_DEG, AGREE_M, RobotStanding, SessionPlacement, place_session, weighted_mean};
pub use read::{read_keyframe_cloud, read_session};
pub use truth::{median_errors, world_from_map_pairs};
pub use write::write_session;

/// The manifest's `format` value.
pub const FORMAT_NAME: &str = "skid-session";

/// The version this crate writes; it reads this one and every older one.
pub const FORMAT_VERSION: u32 = 1;

/// The manifest's file name inside a session folder.
pub const MANIFEST_FILE: &str = "session.json";

/// The session folder `path` names: itself, or the `session` folder of a run folder that holds one.
pub fn session_folder(path: &std::path::Path) -> std::path::PathBuf {
    let inside = path.join("session");
    if !path.join(MANIFEST_FILE).exists() && inside.join(MANIFEST_FILE).exists() {
        inside
    } else {
        path.to_path_buf()
    }
}

/// The folder of robot `robot` inside a session folder.
pub fn robot_folder(robot: u32) -> String {
    format!("robot{robot}")
}

/// The cloud file of keyframe `index`, relative to its robot's folder.
pub fn cloud_file(index: u32) -> String {
    format!("clouds/{index:06}.ply")
}
