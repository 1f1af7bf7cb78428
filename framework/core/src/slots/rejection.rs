//! Why a verifier refused a loop, read from the reason it gave in its [`Verdict`](crate::slots::Verdict):
//! the classes the run's statistics (`rejected_by`) and the replay's accounting of the true loops it
//! dropped count by.

/// Why the verifier refused a loop, read from the reason it gave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RejectionKind {
    /// The clouds overlap badly where they overlap (`truncated MSE: …`).
    TruncatedMse,
    /// The clouds see through each other (`free space: …`): two look-alike places, or a wrong alignment.
    FreeSpace,
    /// An intra-robot loop farther from the robot's own odometry than odometry drifts (`odometry: …`).
    Odometry,
    /// An inter-robot loop that puts a robot in the other's view at one moment where that one's scan
    /// shows it absent (`peer unseen: …`).
    PeerUnseen,
    /// Not consistent with the other loops of its robot pair (`PCM: …`), or withheld with a set that
    /// was not granted.
    Consistency,
    /// Accepted once, then taken back.
    Retracted,
    /// Anything else (a keyframe unknown to the graph, an unusable covariance, another verifier's own
    /// reasons).
    Other,
}

impl RejectionKind {
    pub fn of(reason: &str) -> Self {
        match reason {
            r if r.starts_with("truncated MSE") => Self::TruncatedMse,
            r if r.starts_with("free space") => Self::FreeSpace,
            r if r.starts_with("odometry") => Self::Odometry,
            r if r.starts_with("peer unseen") => Self::PeerUnseen,
            r if r.starts_with("PCM") => Self::Consistency,
            r if r.starts_with("retracted") => Self::Retracted,
            _ => Self::Other,
        }
    }

    /// The key of `LoopStats::rejected_by`.
    pub fn key(self) -> &'static str {
        match self {
            Self::TruncatedMse => "truncated_mse",
            Self::FreeSpace => "free_space",
            Self::Odometry => "odometry",
            Self::PeerUnseen => "peer_unseen",
            Self::Consistency => "consistency",
            Self::Retracted => "retracted",
            Self::Other => "other",
        }
    }

    /// A check of the loop's own clouds (its alignment), not a judgement against the other loops.
    pub fn is_alignment_check(self) -> bool {
        matches!(self, Self::TruncatedMse | Self::FreeSpace)
    }
}
