//! Every loop the robots submitted, placed in robot 0's map frame with where it stands: what the run
//! record's markers and the plots draw.

use skid_core::{KeyframeId, Pose};

use crate::host::{LoopStanding, RobotHost};

/// One submitted loop between two keyframe positions in robot 0's map frame.
pub(crate) struct PlacedLoop<'a> {
    pub standing: LoopStanding,
    /// Why the verifier refused it, when it stands rejected.
    pub rejection_reason: Option<&'a str>,
    pub target_m: [f64; 3],
    pub source_m: [f64; 3],
}

/// Where a keyframe sits in robot 0's map frame, when its robot's frame is known there.
fn keyframe_in_map(robots: &[RobotHost], frames: &[Option<Pose>], id: KeyframeId) -> Option<[f64; 3]> {
    let position = robots.iter().position(|robot| robot.robot == id.robot)?;
    let frame = frames.get(position).copied().flatten()?;
    let translation = (frame * robots[position].keyframe_pose(id.index)?)
        .translation
        .vector;
    Some([translation.x, translation.y, translation.z])
}

/// The loops whose two robots are both placed in robot 0's frame (`frames`, one per robot).
pub(crate) fn placed_loops<'a>(robots: &'a [RobotHost], frames: &[Option<Pose>]) -> Vec<PlacedLoop<'a>> {
    let mut placed = Vec::new();
    for robot in robots {
        for (id, &(_, standing)) in &robot.loop_standing {
            let Some(closure) = robot.loops.get(id).or_else(|| robot.pending_closures.get(id)) else {
                continue;
            };
            let ends = (
                keyframe_in_map(robots, frames, closure.target),
                keyframe_in_map(robots, frames, closure.source),
            );
            if let (Some(target_m), Some(source_m)) = ends {
                placed.push(PlacedLoop {
                    standing,
                    rejection_reason: robot.rejection_reasons.get(id).map(String::as_str),
                    target_m,
                    source_m,
                });
            }
        }
    }
    placed
}
