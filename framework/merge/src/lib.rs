//! Merging saved sessions into one map (`skid session merge A B … --out C`).
//!
//! Merging is relocalisation with a whole session as the robot: each later session's robots are fed to
//! a fleet of hosts keyframe by keyframe (their clouds and optimised poses, `feed`), with the session
//! built so far as the prior map (`[prior] mode = "localise"`), so every candidate goes through the
//! configured descriptor, coarse and fine registration and verifier (PCM and its earned-merge rules)
//! exactly as a run's loops do. A session is placed only when its localised robots agree on where its
//! map frame goes (`skid_session::place_session`); otherwise it is reported and left out, never forced. The placed sessions
//! are written as one session in the first one's map frame (`skid_session::write_joined`: every robot
//! keeps its keyframes, clouds, descriptors and pose graph), with `map.ply` and `merge.json` beside.
//!
//! This follows the multi-session anchoring of LT-mapper (Kim et al., ICRA 2022), where a session's
//! pose graph joins the central one through an anchor node placed by inter-session loops, and the
//! mission merging of maplab 2.0 (Cramariuc et al., RA-L 2023). Each session keeps its own optimised
//! poses: the merge places whole robots, it does not re-optimise their graphs jointly.

mod feed;
mod map;
mod merge;
mod report;

pub use feed::SessionFeed;
pub use merge::merge_sessions;
pub use report::{MergeReport, RobotOutcome, SessionOutcome};

use std::path::PathBuf;

/// What can stop a merge.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("{}: {source}", path.display())]
    Session {
        path: PathBuf,
        #[source]
        source: skid_session::SessionError,
    },
    #[error("the configuration for localising {}: {source}", path.display())]
    Config {
        path: PathBuf,
        #[source]
        source: skid_config::ConfigError,
    },
    #[error("localising {} in the sessions before it: {source}", path.display())]
    Localise {
        path: PathBuf,
        #[source]
        source: skid_runtime::RuntimeError,
    },
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Invalid(String),
}

/// What to merge.
#[derive(Clone, Debug)]
pub struct MergeRequest {
    /// Session folders (or run folders holding one); the first is the base, whose map frame the
    /// merged session keeps.
    pub sessions: Vec<PathBuf>,
    /// The folder the merged session is written to; it must not exist or be empty.
    pub out: PathBuf,
    /// `section.key=value` settings applied over each session's own configuration when localising it
    /// (the verifier's or the registration's parameters, say).
    pub sets: Vec<String>,
}
