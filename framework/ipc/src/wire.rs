//! The one wire type skid-ipc adds to those of `skid-msgs`: the header of a graph update.
//!
//! SAFETY (for the `ZeroCopySend` derive, the only reason this module allows `unsafe_code`): the type is
//! `#[repr(C)]`, holds only fixed-size integers, has no padding (8 + 4 · 4 bytes) and no pointers, so a
//! copy in shared memory means the same in every process that maps it.

use iceoryx2::prelude::ZeroCopySend;

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
