//! The graph a replayed verifier sees, as `skid run`'s host gives it to its own: the odometry chains
//! known so far, the optimised poses of the robot's back-end where it holds them, and the frames of
//! other robots known through third robots (the host's frame book). Each robot places the robots it
//! holds accepted loops with (the pose of that robot's first keyframe in the frame of its own first
//! keyframe, [`merged_frames`]); a verifier judging a pair (a, b) is given, for each third robot c that
//! both a frame of c and c's own frame of the other robot are known through, the composition of the
//! two. In batch mode the one graph places every robot for every robot, so the frames through c are the
//! one graph's frames of robots it merged through c.

use std::collections::BTreeMap;

use skid_core::pose::moved_beyond;
use skid_core::slots::{GraphView, LoopClosure, RelativePose};
use skid_core::{KeyframeId, Pose, RobotId};
use skid_geometry::OdometryChains;

/// Each robot's frames of the robots it merged with: robot → (merged robot → robot_first_from_merged_first).
pub(crate) type FrameTables = BTreeMap<RobotId, BTreeMap<RobotId, Pose>>;

/// A frame that moved less than this (translation) is not reported again, as `skid run` resends frames.
const REPORT_AGAIN_M: f64 = 0.25;
/// A frame that turned less than this is not reported again.
const REPORT_AGAIN_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// The frames of the robots that `me` holds accepted loops with (`loops`): the pose of each one's
/// first keyframe in the frame of `me`'s first keyframe, with `first_pose` giving a robot's first
/// keyframe's pose in the graph.
pub(crate) fn merged_frames<'a>(
    me: RobotId,
    first_pose: impl Fn(RobotId) -> Option<Pose>,
    loops: impl Iterator<Item = &'a LoopClosure>,
) -> BTreeMap<RobotId, Pose> {
    let Some(me_first) = first_pose(me) else {
        return BTreeMap::new();
    };
    let mut frames = BTreeMap::new();
    for closure in loops {
        let other = match (closure.target.robot == me, closure.source.robot == me) {
            (true, false) => closure.source.robot,
            (false, true) => closure.target.robot,
            _ => continue,
        };
        if frames.contains_key(&other) {
            continue;
        }
        if let Some(other_first) = first_pose(other) {
            frames.insert(other, me_first.inverse() * other_first);
        }
    }
    frames
}

/// Whether a robot's frames changed enough since it last reported them (`last`) to be reported again:
/// a frame appeared, left, or moved.
pub(crate) fn worth_reporting(last: Option<&BTreeMap<RobotId, Pose>>, now: &BTreeMap<RobotId, Pose>) -> bool {
    let Some(last) = last else {
        return !now.is_empty();
    };
    last.len() != now.len()
        || now.iter().any(|(robot, pose)| {
            last.get(robot)
                .is_none_or(|before| moved_beyond(before, pose, REPORT_AGAIN_M, REPORT_AGAIN_RAD))
        })
}

/// A verifier's view: the chains, a back-end's poses, and the frames through third robots.
pub(crate) struct VerifierView<'a> {
    pub chains: &'a OdometryChains,
    /// The back-end's graph, whose optimised poses come first.
    pub backend: Option<&'a dyn GraphView>,
    pub tables: &'a FrameTables,
    /// The robot whose verifier this is, which must be one of a pair for frames through others (a
    /// robot's frame book composes its own frames); `None` for batch mode's one verifier.
    pub me: Option<RobotId>,
}

impl GraphView for VerifierView<'_> {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        self.backend
            .and_then(|graph| graph.pose(id))
            .or_else(|| self.chains.pose(id))
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        self.chains.between(target, source)
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        self.chains.keyframes()
    }

    fn loops(&self) -> Vec<LoopClosure> {
        self.backend.map_or_else(Vec::new, |graph| graph.loops())
    }

    fn frames_through_others(&self, a: RobotId, b: RobotId) -> Vec<(RobotId, Pose)> {
        match self.me {
            Some(me) if me == b => self
                .compose(b, a)
                .into_iter()
                .map(|(via, b_first_from_a_first)| (via, b_first_from_a_first.inverse()))
                .collect(),
            Some(me) if me != a => Vec::new(),
            _ => self.compose(a, b),
        }
    }
}

impl VerifierView<'_> {
    /// `to`'s first keyframe in the frame of `from`'s, through each third robot that `from` placed and
    /// that placed `to`.
    fn compose(&self, from: RobotId, to: RobotId) -> Vec<(RobotId, Pose)> {
        let Some(placed_by_from) = self.tables.get(&from) else {
            return Vec::new();
        };
        placed_by_from
            .iter()
            .filter(|(via, _)| **via != from && **via != to)
            .filter_map(|(via, from_first_from_via_first)| {
                let via_first_from_to_first = self.tables.get(via)?.get(&to)?;
                Some((*via, from_first_from_via_first * via_first_from_to_first))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn pose(x: f64, y: f64, yaw_deg: f64) -> Pose {
        Pose::new(Vector3::new(x, y, 0.0), Vector3::z() * yaw_deg.to_radians())
    }

    fn close(a: &Pose, b: &Pose) -> bool {
        (a.inverse() * b).translation.vector.norm() < 1e-9 && (a.inverse() * b).rotation.angle() < 1e-9
    }

    #[test]
    fn frames_compose_through_a_third_robot_for_either_end_of_a_pair() {
        let (r0, r1, r2) = (RobotId(0), RobotId(1), RobotId(2));
        let (r0_from_r2, r2_from_r1) = (pose(10.0, 0.0, 90.0), pose(5.0, 2.0, -30.0));
        let tables: FrameTables = BTreeMap::from([
            (r0, BTreeMap::from([(r2, r0_from_r2)])),
            (r1, BTreeMap::from([(r2, r2_from_r1.inverse())])),
            (r2, BTreeMap::from([(r0, r0_from_r2.inverse()), (r1, r2_from_r1)])),
        ]);
        let chains = OdometryChains::default();
        let view = |me| VerifierView {
            chains: &chains,
            backend: None,
            tables: &tables,
            me,
        };
        let expected = r0_from_r2 * r2_from_r1;
        for me in [None, Some(r0), Some(r1)] {
            let through = view(me).frames_through_others(r0, r1);
            assert_eq!(through.len(), 1, "{me:?}");
            assert_eq!(through[0].0, r2);
            assert!(close(&through[0].1, &expected), "{me:?}: {:?}", through[0].1);
        }
        assert!(
            view(Some(r2)).frames_through_others(r0, r1).is_empty(),
            "only a robot of the pair asks"
        );
        assert!(
            view(None).frames_through_others(r0, r2).is_empty(),
            "no third robot between 0 and 2"
        );
    }

    #[test]
    fn frames_are_reported_again_only_when_they_move() {
        let r1 = RobotId(1);
        let last = BTreeMap::from([(r1, pose(1.0, 0.0, 0.0))]);
        assert!(worth_reporting(None, &last));
        assert!(!worth_reporting(None, &BTreeMap::new()));
        assert!(!worth_reporting(
            Some(&last),
            &BTreeMap::from([(r1, pose(1.1, 0.0, 0.2))])
        ));
        assert!(worth_reporting(
            Some(&last),
            &BTreeMap::from([(r1, pose(1.3, 0.0, 0.0))])
        ));
        assert!(worth_reporting(
            Some(&last),
            &BTreeMap::from([(r1, pose(1.0, 0.0, 1.0))])
        ));
        assert!(worth_reporting(Some(&last), &BTreeMap::new()));
    }

    #[test]
    fn a_robot_places_only_the_robots_it_holds_loops_with() {
        let (r0, r1, r2) = (RobotId(0), RobotId(1), RobotId(2));
        let first = |robot: RobotId| Some(pose(10.0 * f64::from(robot.0), 0.0, 0.0));
        let loop_between = |a: RobotId, b: RobotId| LoopClosure {
            id: skid_core::LoopId(u64::from(a.0) * 10 + u64::from(b.0)),
            target: KeyframeId { robot: a, index: 3 },
            source: KeyframeId { robot: b, index: 4 },
            target_from_source: Pose::identity(),
            information: skid_core::Information::identity(),
        };
        let loops = [loop_between(r0, r1), loop_between(r1, r2), loop_between(r1, r1)];
        let frames = merged_frames(r1, first, loops.iter());
        assert_eq!(frames.len(), 2);
        assert!(close(&frames[&r0], &pose(-10.0, 0.0, 0.0)));
        assert!(close(&frames[&r2], &pose(10.0, 0.0, 0.0)));
        assert!(merged_frames(r0, first, loops.iter()).contains_key(&r1));
        assert!(merged_frames(r0, |_| None, loops.iter()).is_empty());
    }
}
