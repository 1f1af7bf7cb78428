//! The wire types skid-ipc adds to those of `skid-msgs`: the header of a graph update and the header of
//! a front-end output.
//!
//! SAFETY (for the `ZeroCopySend` derive, the only reason this module allows `unsafe_code`): the types
//! are `#[repr(C)]`, hold only fixed-size numbers and arrays of them, have no padding (checked by the
//! size tests below) and no pointers, so a copy in shared memory means the same in every process that
//! maps it.

use iceoryx2::prelude::ZeroCopySend;
use skid_msgs::PoseWire;

/// What a graph update carries.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GraphUpdateKind {
    /// Odometry edges between consecutive keyframes of one robot.
    Odometry = 1,
    /// Loop closures the verifier accepted.
    LoopsAccepted = 2,
    /// Loop closures the verifier retracted (PCM's maximum clique changed).
    LoopsRetracted = 3,
}

impl GraphUpdateKind {
    /// The kind with wire code `code`.
    pub fn from_code(code: u32) -> Option<Self> {
        [Self::Odometry, Self::LoopsAccepted, Self::LoopsRetracted]
            .into_iter()
            .find(|kind| *kind as u32 == code)
    }
}

/// Header in front of a slice of `LoopMeasurement`s: an odometry edge is a measurement between two
/// consecutive keyframes of one robot, a loop one between any two keyframes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ZeroCopySend)]
#[type_name("skid/GraphUpdateHeader@1")]
pub struct GraphUpdateHeader {
    pub stamp_nanos: u64,
    pub robot_id: u32,
    /// Per-publisher sequence number.
    pub sequence: u32,
    /// A [`GraphUpdateKind`] code.
    pub kind: u32,
    pub reserved: u32,
}

impl GraphUpdateHeader {
    /// The update kind, if the code is known.
    pub fn kind(&self) -> Option<GraphUpdateKind> {
        GraphUpdateKind::from_code(self.kind)
    }
}

/// What a front-end output says about its scan.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrontEndStatus {
    /// Registered by the odometry; a keyframe when `keyframe_index` is set.
    Registered = 1,
    /// Refused by the odometry (the reason is in `message`); the run goes on.
    Skipped = 2,
    /// Read with no odometry configured.
    NoOdometry = 3,
    /// The source has ended; the last sample of the stream.
    Ended = 4,
    /// The source (`message` starts with `source:`) or the odometry failed; the last sample.
    Failed = 5,
}

impl FrontEndStatus {
    /// The status with wire code `code`.
    pub fn from_code(code: u32) -> Option<Self> {
        [
            Self::Registered,
            Self::Skipped,
            Self::NoOdometry,
            Self::Ended,
            Self::Failed,
        ]
        .into_iter()
        .find(|status| *status as u32 == code)
    }
}

/// Bytes of text a front-end header carries (a skip or failure reason, truncated).
pub const FRONT_END_MESSAGE_BYTES: usize = 192;

/// Header of one front-end output; the keyframe's points follow it.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("skid/FrontEndHeader@2")]
pub struct FrontEndHeader {
    pub stamp_nanos: u64,
    pub keyframe_stamp_nanos: u64,
    /// Outputs published before this one by this front-end (and its earlier incarnations).
    pub output_index: u64,
    pub robot_id: u32,
    /// The scan's sequence number from the source.
    pub sequence: u32,
    /// Points the source gave for the scan.
    pub points: u32,
    /// A [`FrontEndStatus`] code.
    pub status: u32,
    /// The keyframe's index, or `u32::MAX` when the scan is no keyframe.
    pub keyframe_index: u32,
    pub has_ground_truth: u32,
    pub source_ms: f64,
    pub odometry_ms: f64,
    pub world_from_sensor: PoseWire,
    pub keyframe_world_from_sensor: PoseWire,
    pub ground_truth: PoseWire,
    pub message_len: u32,
    /// Bits of [`FRONT_END_DEGENERATE`].
    pub flags: u32,
    pub message: [u8; FRONT_END_MESSAGE_BYTES],
}

/// Set in [`FrontEndHeader::flags`] when the odometry found the scan degenerate.
pub const FRONT_END_DEGENERATE: u32 = 1;

impl Default for FrontEndHeader {
    fn default() -> Self {
        Self {
            stamp_nanos: 0,
            keyframe_stamp_nanos: 0,
            output_index: 0,
            robot_id: 0,
            sequence: 0,
            points: 0,
            status: 0,
            keyframe_index: u32::MAX,
            has_ground_truth: 0,
            source_ms: 0.0,
            odometry_ms: 0.0,
            world_from_sensor: PoseWire::IDENTITY,
            keyframe_world_from_sensor: PoseWire::IDENTITY,
            ground_truth: PoseWire::IDENTITY,
            message_len: 0,
            flags: 0,
            message: [0; FRONT_END_MESSAGE_BYTES],
        }
    }
}

impl FrontEndHeader {
    /// The status, if the code is known.
    pub fn status(&self) -> Option<FrontEndStatus> {
        FrontEndStatus::from_code(self.status)
    }

    /// Stores `text`, cut at a character boundary to fit.
    pub fn set_message(&mut self, text: &str) {
        let mut end = text.len().min(FRONT_END_MESSAGE_BYTES);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        self.message[..end].copy_from_slice(&text.as_bytes()[..end]);
        self.message_len = end as u32;
    }

    /// The stored text.
    pub fn message(&self) -> String {
        let end = (self.message_len as usize).min(FRONT_END_MESSAGE_BYTES);
        String::from_utf8_lossy(&self.message[..end]).into_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_have_no_padding() {
        assert_eq!(std::mem::size_of::<GraphUpdateHeader>(), 8 + 4 * 4);
        let pose = std::mem::size_of::<PoseWire>();
        assert_eq!(
            std::mem::size_of::<FrontEndHeader>(),
            3 * 8 + 6 * 4 + 2 * 8 + 3 * pose + 2 * 4 + FRONT_END_MESSAGE_BYTES
        );
    }

    #[test]
    fn messages_are_cut_at_character_boundaries() {
        let mut header = FrontEndHeader::default();
        header.set_message(&"é".repeat(200));
        assert!(header.message().chars().all(|c| c == 'é'));
        assert!(header.message_len as usize <= FRONT_END_MESSAGE_BYTES);
        assert_eq!(FrontEndStatus::from_code(4), Some(FrontEndStatus::Ended));
    }
}
