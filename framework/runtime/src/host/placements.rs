//! Where and when a robot placed each other robot in its frame over the run: one [`Placement`] from the
//! moment a robot entered this robot's frame until it left it (its merge withdrawn, or the chain it
//! joined through broken) or its frame jumped by more than a false merge's bound. A merge that is
//! granted on look-alike places and withdrawn later, or overturned by a stronger hypothesis, stays on
//! record: the time a robot spent placed wrongly is what a user of the map would have seen, and the time
//! to a true merge is when the placement that stands began, not when the robot first appeared.

use std::collections::BTreeMap;

use skid_core::{Pose, RobotId};

/// A frame that moves farther than this between two notes starts a new placement (the false-merge
/// bound of every SKiD benchmark, so that a placement holds one frame hypothesis).
pub const PLACEMENT_JUMP_M: f64 = 2.0;
/// A frame that turns farther than this between two notes starts a new placement.
pub const PLACEMENT_JUMP_DEG: f64 = 5.0;

/// One stretch of time over which a robot stood placed in this robot's frame at one hypothesis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// When the robot was placed (this host's clock: scan time in a fleet run).
    pub since_nanos: u64,
    /// When it left this robot's frame or its frame jumped; `None` while it stands.
    pub until_nanos: Option<u64>,
    /// The placed robot's first keyframe in this robot's first keyframe's frame, as last noted.
    pub own_first_from_robot_first: Pose,
}

/// Every robot's placements in this robot's frame, oldest first.
#[derive(Debug, Default)]
pub(crate) struct PlacementHistory {
    by_robot: BTreeMap<RobotId, Vec<Placement>>,
}

impl PlacementHistory {
    /// Notes the robots placed now (robot → own_first_from_robot_first): a robot that is no longer
    /// placed, or whose frame jumped, closes its placement; a robot newly placed (or placed anew after
    /// a jump) opens one; a frame that moved a little updates the placement that stands.
    pub(crate) fn note(&mut self, placed: &BTreeMap<RobotId, Pose>, now_nanos: u64) {
        for (robot, history) in &mut self.by_robot {
            let Some(open) = history.last_mut().filter(|p| p.until_nanos.is_none()) else {
                continue;
            };
            match placed.get(robot) {
                Some(frame) if !jumped(&open.own_first_from_robot_first, frame) => {
                    open.own_first_from_robot_first = *frame;
                }
                _ => open.until_nanos = Some(now_nanos),
            }
        }
        for (robot, frame) in placed {
            let history = self.by_robot.entry(*robot).or_default();
            if history.last().is_none_or(|p| p.until_nanos.is_some()) {
                history.push(Placement {
                    since_nanos: now_nanos,
                    until_nanos: None,
                    own_first_from_robot_first: *frame,
                });
            }
        }
    }

    /// Every robot's placements, oldest first.
    pub(crate) fn all(&self) -> &BTreeMap<RobotId, Vec<Placement>> {
        &self.by_robot
    }

    /// When each robot was first placed; a robot that left and came back keeps its first time.
    pub(crate) fn first_placed_nanos(&self) -> BTreeMap<RobotId, u64> {
        self.by_robot
            .iter()
            .filter_map(|(robot, history)| Some((*robot, history.first()?.since_nanos)))
            .collect()
    }
}

fn jumped(before: &Pose, now: &Pose) -> bool {
    skid_core::pose::moved_beyond(before, now, PLACEMENT_JUMP_M, PLACEMENT_JUMP_DEG.to_radians())
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_testkit::scene::x_yaw_pose as pose;

    #[test]
    fn a_withdrawn_or_overturned_placement_stays_on_record() {
        let (r1, r2) = (RobotId(1), RobotId(2));
        let mut history = PlacementHistory::default();
        history.note(&BTreeMap::from([(r1, pose(140.0, 90.0))]), 7);
        history.note(&BTreeMap::from([(r1, pose(140.5, 90.0))]), 8);
        history.note(&BTreeMap::new(), 20);
        history.note(&BTreeMap::from([(r1, pose(0.5, 0.0)), (r2, pose(3.0, 0.0))]), 45);
        // Robot 2's frame turns by 10°: another hypothesis, another placement.
        history.note(&BTreeMap::from([(r1, pose(0.6, 0.0)), (r2, pose(3.0, 10.0))]), 50);
        let r1_history = &history.all()[&r1];
        assert_eq!(r1_history.len(), 2, "{r1_history:?}");
        assert_eq!(
            (r1_history[0].since_nanos, r1_history[0].until_nanos),
            (7, Some(20))
        );
        assert_eq!(
            r1_history[0].own_first_from_robot_first,
            pose(140.5, 90.0),
            "a small move updates the placement that stands"
        );
        assert_eq!((r1_history[1].since_nanos, r1_history[1].until_nanos), (45, None));
        let r2_history = &history.all()[&r2];
        assert_eq!(
            r2_history
                .iter()
                .map(|p| (p.since_nanos, p.until_nanos))
                .collect::<Vec<_>>(),
            vec![(45, Some(50)), (50, None)]
        );
        assert_eq!(history.first_placed_nanos(), BTreeMap::from([(r1, 7), (r2, 45)]));
    }
}
