//! What a merge did, as `merge.json` and the command's table: per session whether and where it was
//! placed, per robot whether it was localised and by how many loops, and the frame error against the
//! ground truth where both sessions know it.

use serde::Serialize;
use skid_session::PoseRecord;

/// One robot of a session being merged.
#[derive(Clone, Debug, Serialize)]
pub struct RobotOutcome {
    /// Its id in its own session.
    pub robot: u32,
    /// Its id in the merged session, when its session was placed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_robot: Option<u32>,
    /// The verifier granted it a set of loops with the sessions before it.
    pub localised: bool,
    /// The loops of that set.
    pub loops: usize,
    /// The robot of the merged session (so far) its loops were with.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub through_robot: Option<u32>,
    /// Whether it has a place in the merged map frame.
    pub placed: bool,
}

/// One session after the first.
#[derive(Clone, Debug, Serialize)]
pub struct SessionOutcome {
    pub path: String,
    pub name: String,
    pub placed: bool,
    /// Why it was not placed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Where its map frame sits in the merged one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_from_session: Option<PoseRecord>,
    /// Against the ground truth: median position (m) and rotation (°) error of its keyframes placed in
    /// the merged frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_deg: Option<f64>,
    pub keyframes: usize,
    pub robots: Vec<RobotOutcome>,
    /// Seconds its localisation took.
    pub localise_s: f64,
}

/// The whole merge.
#[derive(Clone, Debug, Serialize)]
pub struct MergeReport {
    pub base: String,
    pub out: String,
    pub sessions: Vec<SessionOutcome>,
    /// Robots and keyframes of the merged session, and points of its map.
    pub robots: usize,
    pub keyframes: usize,
    pub map_points: usize,
    pub wall_s: f64,
}
