//! The inter-robot messages of design guide §6 (SKiD-SLAM's descriptor-first exchange, Sec. III of the
//! paper: robots share light global descriptors, and clouds only for loop candidates) and their
//! semantic checks, run on every received message after postcard decoding.

use serde::{Deserialize, Serialize};
use skid_core::{KeyframeId, RobotId};

use crate::codec::{CodecError, CompressedPoints, DescriptorValues};
use crate::wire::{InformationMsg, PoseMsg};

/// The kind of a message, as written in the envelope.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[repr(u8)]
pub enum MessageKind {
    Hello = 1,
    Heartbeat = 2,
    Descriptors = 3,
    CloudRequest = 4,
    Cloud = 5,
    OdomChain = 6,
    Loops = 7,
    Frames = 8,
}

impl MessageKind {
    /// Every kind, in wire-code order.
    pub const ALL: [MessageKind; 8] = [
        Self::Hello,
        Self::Heartbeat,
        Self::Descriptors,
        Self::CloudRequest,
        Self::Cloud,
        Self::OdomChain,
        Self::Loops,
        Self::Frames,
    ];

    /// The code written in the envelope.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The kind with wire code `code`.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.code() == code)
    }

    /// Short snake_case name, used as the key in metrics.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Hello => "hello",
            Self::Heartbeat => "heartbeat",
            Self::Descriptors => "descriptors",
            Self::CloudRequest => "cloud_request",
            Self::Cloud => "cloud",
            Self::OdomChain => "odom_chain",
            Self::Loops => "loops",
            Self::Frames => "frames",
        }
    }

    /// Control messages are small and get the tighter size limit.
    pub const fn is_control(self) -> bool {
        matches!(self, Self::Hello | Self::Heartbeat | Self::CloudRequest)
    }

    /// Index into per-kind arrays.
    pub(crate) const fn index(self) -> usize {
        self as usize - 1
    }
}

/// What a robot can do, announced in `Hello` and `Heartbeat`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Capabilities {
    /// Descriptor kind this robot sends (`solid`, `scan_context`, …); peers with another kind cannot
    /// match against it.
    pub descriptor_kind: String,
    /// Number of values in each descriptor.
    pub descriptor_len: u32,
    /// The robot answers `CloudRequest`s.
    pub serves_clouds: bool,
    /// Largest message the robot accepts, in bytes.
    pub max_message_bytes: u32,
}

/// `Hello` (on start and when a peer appears) and `Heartbeat` (periodic) share this body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeerStatus {
    pub robot: RobotId,
    /// Index of the newest keyframe, `None` before the first one.
    pub latest_keyframe: Option<u32>,
    pub capabilities: Capabilities,
    /// The robot's source has ended and it waits for nothing from its peers (no candidate queued, no
    /// cloud asked for): unless a peer's new descriptors raise candidates, it will ask for nothing more.
    /// Robots that linger after their source ends stop once every robot of the fleet says so (protocol
    /// version 3; a version-2 status reads as not settled).
    pub settled: bool,
}

/// The body of `Hello` and `Heartbeat` in protocol version 2, which had no `settled`.
#[derive(Deserialize)]
pub(crate) struct PeerStatusV2 {
    robot: RobotId,
    latest_keyframe: Option<u32>,
    capabilities: Capabilities,
}

impl From<PeerStatusV2> for PeerStatus {
    fn from(old: PeerStatusV2) -> Self {
        Self {
            robot: old.robot,
            latest_keyframe: old.latest_keyframe,
            capabilities: old.capabilities,
            settled: false,
        }
    }
}

/// One keyframe's descriptor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DescriptorEntry {
    pub keyframe_index: u32,
    pub stamp_nanos: u64,
    pub values: DescriptorValues,
    /// What the sender's index held when it looked for this keyframe's candidates: the newest keyframe
    /// of each peer whose descriptor it had. A receiver whose newer keyframes the sender did not hold
    /// looks for those candidates itself (at most [`MAX_HELD_PEERS`] entries).
    pub newest_held: Vec<HeldKeyframe>,
}

/// The newest keyframe of `robot` a robot's descriptor index held.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct HeldKeyframe {
    pub robot: RobotId,
    pub keyframe_index: u32,
}

/// Most [`DescriptorEntry::newest_held`] entries a message may carry (one per peer of a fleet).
pub const MAX_HELD_PEERS: usize = 1024;

impl DescriptorEntry {
    /// The newest keyframe of `robot` the sender held when it looked for this keyframe's candidates;
    /// `None` when it held none.
    pub fn held_of(&self, robot: RobotId) -> Option<u32> {
        self.newest_held
            .iter()
            .find(|held| held.robot == robot)
            .map(|held| held.keyframe_index)
    }
}

/// A batch of descriptors of one kind from one robot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DescriptorBatch {
    pub robot: RobotId,
    /// Descriptor kind of every entry.
    pub kind: String,
    pub entries: Vec<DescriptorEntry>,
}

/// A request for the clouds of some of the receiver's keyframes (loop candidates).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CloudRequest {
    pub requester: RobotId,
    pub keyframes: Vec<KeyframeId>,
}

/// A keyframe cloud: voxel-downsampled points in the sensor frame and the keyframe's odometry pose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CloudMsg {
    pub keyframe: KeyframeId,
    pub stamp_nanos: u64,
    pub world_from_sensor: PoseMsg,
    pub points: CompressedPoints,
}

/// One odometry edge of a chain: keyframe `index` to keyframe `index + 1`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChainEdge {
    /// Pose of keyframe `index + 1` in keyframe `index`'s frame.
    pub target_from_source: PoseMsg,
    pub information: InformationMsg,
}

/// The relative odometry between keyframes `from_index` and `to_index` of `robot`: what a peer needs for
/// PCM's pairwise consistency and for its local copy of the graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OdomChain {
    pub robot: RobotId,
    pub from_index: u32,
    pub to_index: u32,
    /// `to_index − from_index` consecutive edges.
    pub edges: Vec<ChainEdge>,
    /// Odometry pose of keyframe `from_index`, so the receiver can place the chain before any loop.
    pub world_from_first: PoseMsg,
}

/// An inter-robot loop closure; loops are identified across robots by their keyframe pair.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopMsg {
    pub target: KeyframeId,
    pub source: KeyframeId,
    pub target_from_source: PoseMsg,
    pub information: InformationMsg,
    /// Truncated MSE of the alignment in m² (the verifier's fitness).
    pub fitness_m2: f32,
}

/// The sender's accepted and retracted inter-robot loops, so both sides agree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Loops {
    pub robot: RobotId,
    pub accepted: Vec<LoopMsg>,
    /// `(target, source)` pairs of loops PCM no longer keeps.
    pub retracted: Vec<(KeyframeId, KeyframeId)>,
}

/// Where the sender places the robots it has merged with: for each, the pose of that robot's first
/// keyframe in the frame of the sender's first keyframe, from the sender's back-end. Peers compose these
/// with their own frames to check a direct merge against the cycle through the sender.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frames {
    pub robot: RobotId,
    pub frames: Vec<FrameMsg>,
}

/// One robot's frame as the sender holds it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameMsg {
    pub robot: RobotId,
    pub sender_first_from_robot_first: PoseMsg,
    /// Accepted loops the sender holds with that robot.
    pub loops: u32,
}

/// Any inter-robot message.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    Hello(PeerStatus),
    Heartbeat(PeerStatus),
    Descriptors(DescriptorBatch),
    CloudRequest(CloudRequest),
    Cloud(CloudMsg),
    OdomChain(OdomChain),
    Loops(Loops),
    Frames(Frames),
}

/// Why a decoded message is not acceptable.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InvalidMessage {
    #[error(transparent)]
    Codec(#[from] CodecError),
    #[error("{0}")]
    Field(String),
}

fn field(reason: impl Into<String>) -> InvalidMessage {
    InvalidMessage::Field(reason.into())
}

/// Longest descriptor kind name accepted.
pub const MAX_KIND_NAME_BYTES: usize = 32;

impl Message {
    pub fn kind(&self) -> MessageKind {
        match self {
            Self::Hello(_) => MessageKind::Hello,
            Self::Heartbeat(_) => MessageKind::Heartbeat,
            Self::Descriptors(_) => MessageKind::Descriptors,
            Self::CloudRequest(_) => MessageKind::CloudRequest,
            Self::Cloud(_) => MessageKind::Cloud,
            Self::OdomChain(_) => MessageKind::OdomChain,
            Self::Loops(_) => MessageKind::Loops,
            Self::Frames(_) => MessageKind::Frames,
        }
    }

    /// The robot the body says it comes from (for clouds, the keyframe's owner).
    pub fn body_robot(&self) -> RobotId {
        match self {
            Self::Hello(status) | Self::Heartbeat(status) => status.robot,
            Self::Descriptors(batch) => batch.robot,
            Self::CloudRequest(request) => request.requester,
            Self::Cloud(cloud) => cloud.keyframe.robot,
            Self::OdomChain(chain) => chain.robot,
            Self::Loops(loops) => loops.robot,
            Self::Frames(frames) => frames.robot,
        }
    }

    /// Semantic checks: finite numbers, unit quaternions, consistent counts and names.
    pub fn validate(&self) -> Result<(), InvalidMessage> {
        match self {
            Self::Hello(status) | Self::Heartbeat(status) => {
                check_kind_name(&status.capabilities.descriptor_kind, true)
            }
            Self::Descriptors(batch) => {
                check_kind_name(&batch.kind, false)?;
                let mut length = None;
                for entry in &batch.entries {
                    entry.values.validate()?;
                    if entry.values.is_empty() {
                        return Err(field(format!(
                            "descriptor of keyframe {} is empty",
                            entry.keyframe_index
                        )));
                    }
                    if *length.get_or_insert(entry.values.len()) != entry.values.len() {
                        return Err(field("descriptors of one batch differ in length"));
                    }
                    if entry.newest_held.len() > MAX_HELD_PEERS {
                        return Err(field(format!(
                            "descriptor of keyframe {} names {} held peers, at most {MAX_HELD_PEERS} allowed",
                            entry.keyframe_index,
                            entry.newest_held.len()
                        )));
                    }
                }
                Ok(())
            }
            Self::CloudRequest(request) => {
                if request.keyframes.is_empty() {
                    return Err(field("cloud request names no keyframe"));
                }
                Ok(())
            }
            Self::Cloud(cloud) => {
                check_pose(&cloud.world_from_sensor, "world_from_sensor")?;
                Ok(cloud.points.validate()?)
            }
            Self::OdomChain(chain) => {
                let expected = chain.to_index.checked_sub(chain.from_index).ok_or_else(|| {
                    field(format!(
                        "odometry chain runs backwards ({} → {})",
                        chain.from_index, chain.to_index
                    ))
                })?;
                if chain.edges.len() as u64 != u64::from(expected) {
                    return Err(field(format!(
                        "odometry chain {} → {} needs {expected} edges, has {}",
                        chain.from_index,
                        chain.to_index,
                        chain.edges.len()
                    )));
                }
                check_pose(&chain.world_from_first, "world_from_first")?;
                for edge in &chain.edges {
                    check_pose(&edge.target_from_source, "odometry edge")?;
                    check_information(&edge.information)?;
                }
                Ok(())
            }
            Self::Loops(loops) => {
                for closure in &loops.accepted {
                    if closure.target.robot == closure.source.robot {
                        return Err(field(format!(
                            "loop {} ↔ {} is not inter-robot",
                            closure.target, closure.source
                        )));
                    }
                    check_pose(&closure.target_from_source, "loop")?;
                    check_information(&closure.information)?;
                    if !closure.fitness_m2.is_finite() {
                        return Err(field("loop fitness is not finite"));
                    }
                }
                Ok(())
            }
            Self::Frames(frames) => {
                let mut seen = std::collections::BTreeSet::new();
                for frame in &frames.frames {
                    if frame.robot == frames.robot {
                        return Err(field(format!("{} reports a frame of itself", frames.robot)));
                    }
                    if !seen.insert(frame.robot) {
                        return Err(field(format!("the frame of {} is reported twice", frame.robot)));
                    }
                    check_pose(&frame.sender_first_from_robot_first, "frame")?;
                }
                Ok(())
            }
        }
    }
}

fn check_kind_name(name: &str, may_be_empty: bool) -> Result<(), InvalidMessage> {
    let ok = (may_be_empty || !name.is_empty())
        && name.len() <= MAX_KIND_NAME_BYTES
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(field(format!(
            "descriptor kind {name:?} is not a short ASCII name"
        )))
    }
}

fn check_pose(pose: &PoseMsg, what: &str) -> Result<(), InvalidMessage> {
    if pose.is_valid() {
        Ok(())
    } else {
        Err(field(format!(
            "{what} pose is not finite or its quaternion is not unit"
        )))
    }
}

fn check_information(information: &InformationMsg) -> Result<(), InvalidMessage> {
    if information.is_finite() {
        Ok(())
    } else {
        Err(field("information matrix is not finite"))
    }
}
