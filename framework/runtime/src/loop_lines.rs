//! Every loop the robots submitted, placed in robot 0's map frame (or in one robot's own map frame) and
//! classed by where it stands: what the run record's `/loops` markers, the plots and live viewers draw,
//! from one table of classes.

use skid_core::slots::RejectionKind;
use skid_core::{KeyframeId, Pose};
use skid_eval::plot::LoopClass;

use crate::host::{LoopStanding, RobotHost};

/// The loop classes drawn: the record's marker namespace and colour (RGBA), and the plots' class.
pub const LOOP_CLASSES: [(&str, [f32; 4], LoopClass); 4] = [
    ("accepted", [0.1, 0.8, 0.2, 1.0], LoopClass::Accepted),
    (
        "rejected by the alignment check",
        [1.0, 0.6, 0.0, 1.0],
        LoopClass::Rejected,
    ),
    (
        "rejected as inconsistent",
        [0.9, 0.1, 0.1, 1.0],
        LoopClass::Rejected,
    ),
    ("undecided", [0.6, 0.6, 0.6, 1.0], LoopClass::Undecided),
];

/// Which of [`LOOP_CLASSES`] a loop belongs to, given its standing and, when rejected, the reason.
fn loop_class(standing: LoopStanding, rejection_reason: Option<&str>) -> usize {
    match standing {
        LoopStanding::Accepted => 0,
        LoopStanding::Undecided => 3,
        // The PCM verifier names its checks of a loop's own clouds `truncated MSE: …` and `free space: …`;
        // every other refusal (consistency, retraction) is a judgement on the loop against the others.
        LoopStanding::Rejected
            if rejection_reason.is_some_and(|r| RejectionKind::of(r).is_alignment_check()) =>
        {
            1
        }
        LoopStanding::Rejected => 2,
    }
}

/// The plots' class of a `/loops` marker namespace the record writes, `None` for any other.
pub fn loop_class_of_namespace(namespace: &str) -> Option<LoopClass> {
    LOOP_CLASSES
        .iter()
        .find(|(name, _, _)| *name == namespace)
        .map(|(_, _, class)| *class)
}

/// One submitted loop between two keyframe positions in a map frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedLoop {
    /// Its index in [`LOOP_CLASSES`].
    pub class: usize,
    pub target_m: [f64; 3],
    pub source_m: [f64; 3],
}

/// Where a keyframe sits in robot 0's map frame, when its robot's frame is known there.
fn keyframe_in_map(robots: &[RobotHost], frames: &[Option<Pose>], id: KeyframeId) -> Option<[f64; 3]> {
    let position = robots.iter().position(|robot| robot.robot() == id.robot)?;
    let frame = frames.get(position).copied().flatten()?;
    let translation = (frame * robots[position].keyframe_pose(id.index)?)
        .translation
        .vector;
    Some([translation.x, translation.y, translation.z])
}

/// `host`'s submitted loops whose two ends `place` can put in a frame.
fn classed_loops(host: &RobotHost, place: &dyn Fn(KeyframeId) -> Option<[f64; 3]>) -> Vec<PlacedLoop> {
    let mut placed = Vec::new();
    for standing in host.standing_loops() {
        let closure = standing.closure;
        if let (Some(target_m), Some(source_m)) = (place(closure.target), place(closure.source)) {
            placed.push(PlacedLoop {
                class: loop_class(standing.standing, standing.reason),
                target_m,
                source_m,
            });
        }
    }
    placed
}

/// The loops whose two robots are both placed in robot 0's frame (`frames`, one per robot).
pub(crate) fn placed_loops(robots: &[RobotHost], frames: &[Option<Pose>]) -> Vec<PlacedLoop> {
    robots
        .iter()
        .flat_map(|robot| classed_loops(robot, &|id| keyframe_in_map(robots, frames, id)))
        .collect()
}

/// The loops `host` submitted, in its own map frame: each end where `host`'s back-end holds it (a peer's
/// keyframe is there once a loop joined that peer), or at its odometry pose for the host's own keyframes
/// outside the graph.
pub fn own_frame_loops(host: &RobotHost) -> Vec<PlacedLoop> {
    classed_loops(host, &|id| {
        let in_graph = host.backend_graph().and_then(|graph| graph.pose(id));
        let pose = if id.robot == host.robot() {
            in_graph.or_else(|| host.keyframe_pose(id.index))
        } else {
            in_graph
        }?;
        let t = pose.translation.vector;
        Some([t.x, t.y, t.z])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loops_are_classed_by_standing_and_rejection_reason() {
        let class = |standing, reason| LOOP_CLASSES[loop_class(standing, reason)].0;
        assert_eq!(class(LoopStanding::Accepted, None), "accepted");
        assert_eq!(class(LoopStanding::Undecided, None), "undecided");
        let mse = Some("truncated MSE: 0.4 m² above 0.25 m²");
        assert_eq!(
            class(LoopStanding::Rejected, mse),
            "rejected by the alignment check"
        );
        let retracted = Some("retracted: no longer consistent with the others");
        assert_eq!(
            class(LoopStanding::Rejected, retracted),
            "rejected as inconsistent"
        );
        assert_eq!(class(LoopStanding::Rejected, None), "rejected as inconsistent");
        assert_eq!(
            loop_class_of_namespace("rejected as inconsistent"),
            Some(LoopClass::Rejected)
        );
        assert_eq!(loop_class_of_namespace("someone else's markers"), None);
    }
}
