//! Frames of other robots. A robot places each robot it has merged with (it holds accepted loops with
//! it) from its back-end: the pose of that robot's first keyframe in the frame of its own first keyframe.
//! It sends these to its peers (`Frames` messages) when they change, and keeps what its peers send. A
//! direct frame between this robot and a peer can then be checked against the cycle through a third
//! robot that has merged with both ([`FrameBook::through_others`]): aliasing that fools one pair of
//! robots rarely fools two pairs into the same wrong frame.
//!
//! A robot also joins robots it never closed a loop with through the robots that did
//! ([`FrameBook::joined`]), neighbour by neighbour, as DPGO lets an agent enter the global frame through
//! any aligned neighbour (Tian et al., "Distributed Certifiably Correct Pose-Graph Optimization", 2021).
//! A join is only as good as the chain behind it: chains through different robots that disagree leave
//! the robot out, and when a link of the chain withdraws its merge, the join goes with it.

use std::collections::{BTreeMap, BTreeSet};

use skid_core::{Pose, RobotId};

use super::placements::PlacementHistory;

/// A frame that moved less than this (translation) since it was last sent is not sent again.
const RESEND_M: f64 = 0.25;
/// A frame that turned less than this since it was last sent is not sent again.
const RESEND_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// Chains through different robots that place a robot further apart than this (the verifier's default
/// cycle tolerance) leave it out: at least one of them holds a false merge.
const JOIN_DISAGREEMENT_M: f64 = 5.0;
const JOIN_DISAGREEMENT_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// Where a robot sits in this robot's frame, and how this robot knows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JoinedFrame {
    /// The pose of that robot's first keyframe in the frame of this robot's first keyframe.
    pub own_first_from_robot_first: Pose,
    /// This robot's accepted loops with it (0 when joined through another robot).
    pub loops: u32,
    /// The robot whose report placed it, `None` when this robot holds loops with it.
    pub via: Option<RobotId>,
}

/// This robot's frames of its merged peers, and its peers' reports of theirs.
#[derive(Debug, Default)]
pub(crate) struct FrameBook {
    /// This robot's current frames: peer → own_first_from_peer_first.
    own: BTreeMap<RobotId, (Pose, u32)>,
    /// The frames last sent.
    sent: BTreeMap<RobotId, Pose>,
    /// Each peer's last report: peer → (robot → peer_first_from_robot_first).
    reported: BTreeMap<RobotId, BTreeMap<RobotId, Pose>>,
    /// Robots this robot's back-end places through the fleet's loops alone (it holds no loop with them,
    /// `loops.fleet_loops`): robot → (own_first_from_robot_first, the robot at the other end of most of
    /// those loops). They are never reported to peers: such a frame rests on loops between other robots,
    /// and a verifier that checked those robots' merge against it would confirm the merge by itself.
    through_fleet: BTreeMap<RobotId, (Pose, RobotId)>,
    /// Every placement of every robot in this robot's frame (directly or through others), by the
    /// host's clock.
    placements: PlacementHistory,
}

impl FrameBook {
    /// Replaces this robot's frames (peer → own_first_from_peer_first and the loops behind it).
    pub(crate) fn set_own(&mut self, own: BTreeMap<RobotId, (Pose, u32)>) {
        self.own = own;
    }

    /// Replaces the frames of the robots the back-end places through the fleet's loops alone.
    pub(crate) fn set_through_fleet(&mut self, through_fleet: BTreeMap<RobotId, (Pose, RobotId)>) {
        self.through_fleet = through_fleet;
    }

    /// This robot's current frames.
    pub(crate) fn own(&self) -> &BTreeMap<RobotId, (Pose, u32)> {
        &self.own
    }

    /// This robot's current frames as a `Frames` message states them.
    pub(crate) fn own_list(&self) -> Vec<(RobotId, Pose, u32)> {
        self.own
            .iter()
            .map(|(robot, (pose, loops))| (*robot, *pose, *loops))
            .collect()
    }

    /// The frames to send now, when they differ from the ones last sent (a frame appeared, left, or
    /// moved); they count as sent.
    pub(crate) fn take_due(&mut self) -> Option<Vec<(RobotId, Pose, u32)>> {
        let moved = |robot: &RobotId, pose: &Pose| {
            self.sent
                .get(robot)
                .is_none_or(|last| skid_core::pose::moved_beyond(last, pose, RESEND_M, RESEND_RAD))
        };
        let changed =
            self.own.len() != self.sent.len() || self.own.iter().any(|(robot, (pose, _))| moved(robot, pose));
        if !changed {
            return None;
        }
        self.sent = self
            .own
            .iter()
            .map(|(robot, (pose, _))| (*robot, *pose))
            .collect();
        Some(self.own_list())
    }

    /// Keeps `from`'s report, replacing its previous one.
    pub(crate) fn record_report(&mut self, from: RobotId, frames: BTreeMap<RobotId, Pose>) {
        self.reported.insert(from, frames);
    }

    /// Notes the robots placed in `me`'s frame now, and where.
    pub(crate) fn note_joined(&mut self, me: RobotId, now_nanos: u64) {
        let placed: BTreeMap<RobotId, Pose> = self
            .joined(me)
            .into_iter()
            .map(|(robot, frame)| (robot, frame.own_first_from_robot_first))
            .collect();
        self.placements.note(&placed, now_nanos);
    }

    /// Every placement of every robot in this robot's frame over the run.
    pub(crate) fn placements(&self) -> &PlacementHistory {
        &self.placements
    }

    /// Every robot this robot (`me`) can place: those it merged with directly, those its back-end
    /// places through the fleet's loops, then, round by round, the robots that the robots already placed
    /// report, composed along the chain. A robot that two chains of one round place apart by more than
    /// the disagreement bound is left out.
    pub(crate) fn joined(&self, me: RobotId) -> BTreeMap<RobotId, JoinedFrame> {
        let mut joined: BTreeMap<RobotId, JoinedFrame> = self
            .own
            .iter()
            .map(|(robot, (pose, loops))| {
                let frame = JoinedFrame {
                    own_first_from_robot_first: *pose,
                    loops: *loops,
                    via: None,
                };
                (*robot, frame)
            })
            .collect();
        for (robot, (pose, via)) in &self.through_fleet {
            joined.entry(*robot).or_insert(JoinedFrame {
                own_first_from_robot_first: *pose,
                loops: 0,
                via: Some(*via),
            });
        }
        let mut disputed: BTreeSet<RobotId> = BTreeSet::new();
        loop {
            let mut chains: BTreeMap<RobotId, Vec<(RobotId, Pose)>> = BTreeMap::new();
            for (via, report) in &self.reported {
                let Some(through) = joined.get(via) else {
                    continue;
                };
                for (robot, via_first_from_robot_first) in report {
                    if *robot != me && !joined.contains_key(robot) && !disputed.contains(robot) {
                        let pose = through.own_first_from_robot_first * via_first_from_robot_first;
                        chains.entry(*robot).or_default().push((*via, pose));
                    }
                }
            }
            if chains.is_empty() {
                return joined;
            }
            for (robot, found) in chains {
                let (via, pose) = found[0];
                let agree = found.iter().all(|(_, other)| {
                    !skid_core::pose::moved_beyond(&pose, other, JOIN_DISAGREEMENT_M, JOIN_DISAGREEMENT_RAD)
                });
                if agree {
                    let frame = JoinedFrame {
                        own_first_from_robot_first: pose,
                        loops: 0,
                        via: Some(via),
                    };
                    joined.insert(robot, frame);
                } else {
                    disputed.insert(robot);
                }
            }
        }
    }

    /// Where `b`'s first keyframe sits in `a`'s first keyframe's frame, through each third robot that
    /// this robot (`me`, one of `a` and `b`) has merged with and that reported a frame of the other.
    pub(crate) fn through_others(&self, me: RobotId, a: RobotId, b: RobotId) -> Vec<(RobotId, Pose)> {
        let (other, flip) = match (a == me, b == me) {
            (true, false) => (b, false),
            (false, true) => (a, true),
            _ => return Vec::new(),
        };
        self.reported
            .iter()
            .filter(|(via, _)| **via != other && **via != me)
            .filter_map(|(via, report)| {
                let (me_from_via, _) = self.own.get(via)?;
                let via_from_other = report.get(&other)?;
                let me_from_other = me_from_via * via_from_other;
                Some((
                    *via,
                    if flip {
                        me_from_other.inverse()
                    } else {
                        me_from_other
                    },
                ))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use skid_testkit::scene::x_yaw_pose as pose;

    #[test]
    fn frames_compose_through_a_third_robot_and_are_sent_on_change() {
        let (r0, r1, r2) = (RobotId(0), RobotId(1), RobotId(2));
        let mut book = FrameBook::default();
        book.set_own(BTreeMap::from([(r2, (pose(10.0, 90.0), 6))]));
        assert_eq!(book.take_due(), Some(vec![(r2, pose(10.0, 90.0), 6)]));
        assert_eq!(book.take_due(), None, "unchanged frames are not sent twice");
        book.set_own(BTreeMap::from([(r2, (pose(10.1, 90.0), 7))]));
        assert_eq!(
            book.take_due(),
            None,
            "a 10 cm move is below the resend threshold"
        );
        // Robot 2 places robot 1 5 m along its own x axis, which robot 0 sees turned by 90°.
        book.record_report(
            r2,
            BTreeMap::from([(r1, pose(5.0, 0.0)), (r0, pose(-10.0, -90.0))]),
        );
        let through = book.through_others(r0, r0, r1);
        assert_eq!(through.len(), 1);
        let (via, frame) = through[0];
        assert_eq!(via, r2);
        assert!(
            (frame.translation.vector - Vector3::new(10.1, 5.0, 0.0)).norm() < 1e-9,
            "{frame:?}"
        );
        let back = book.through_others(r0, r1, r0);
        assert!((back[0].1 * frame).translation.vector.norm() < 1e-9);
        assert!(
            book.through_others(r0, r0, r2).is_empty(),
            "robot 2 is no third robot to itself"
        );
        assert!(
            book.through_others(r0, r1, r2).is_empty(),
            "only cycles through this robot"
        );
    }

    #[test]
    fn robots_join_through_chains_that_agree_and_leave_with_them() {
        let (r0, r1, r2, r3) = (RobotId(0), RobotId(1), RobotId(2), RobotId(3));
        let mut book = FrameBook::default();
        // Robot 0 merged with robot 1 only; robot 1 places robot 2, robot 2 places robot 3.
        book.set_own(BTreeMap::from([(r1, (pose(10.0, 90.0), 6))]));
        book.record_report(
            r1,
            BTreeMap::from([(r0, pose(-10.0, -90.0)), (r2, pose(5.0, 0.0))]),
        );
        book.record_report(r2, BTreeMap::from([(r3, pose(1.0, 0.0))]));
        let joined = book.joined(r0);
        assert_eq!(joined[&r1].via, None);
        assert_eq!(joined[&r1].loops, 6);
        assert_eq!(joined[&r2].via, Some(r1));
        assert!(
            (joined[&r2].own_first_from_robot_first.translation.vector - Vector3::new(10.0, 5.0, 0.0)).norm()
                < 1e-9
        );
        assert_eq!(joined[&r3].via, Some(r2), "chains grow neighbour by neighbour");
        assert!(!joined.contains_key(&r0), "a robot does not join itself");
        // A second chain to robot 2 (through robot 3, now merged directly) that disagrees by 20 m leaves
        // robot 2 out; one that agrees keeps it.
        book.set_own(BTreeMap::from([
            (r1, (pose(10.0, 90.0), 6)),
            (r3, (pose(0.0, 0.0), 4)),
        ]));
        book.record_report(r3, BTreeMap::from([(r2, pose(20.0, 0.0))]));
        assert!(!book.joined(r0).contains_key(&r2), "disagreeing chains");
        let half_a_metre_off = Pose::new(Vector3::new(10.5, 5.0, 0.0), Vector3::z() * 90f64.to_radians());
        book.record_report(r3, BTreeMap::from([(r2, half_a_metre_off)]));
        assert_eq!(book.joined(r0)[&r2].via, Some(r1), "agreeing chains");
        // When robot 1 withdraws its merge with robot 2 and robot 3's chain is gone, robot 2 leaves.
        book.set_own(BTreeMap::from([(r1, (pose(10.0, 90.0), 6))]));
        book.record_report(r1, BTreeMap::from([(r0, pose(-10.0, -90.0))]));
        assert!(!book.joined(r0).contains_key(&r2), "the chain was withdrawn");
        assert!(
            !book.joined(r0).contains_key(&r3),
            "robot 3 was only reached through robot 2"
        );
    }

    #[test]
    fn robots_the_fleets_loops_place_are_joined_but_never_reported() {
        let (r0, r1, r2) = (RobotId(0), RobotId(1), RobotId(2));
        let mut book = FrameBook::default();
        // Robot 0 merged with robot 2; its back-end places robot 1 through loops between 1 and 2.
        book.set_own(BTreeMap::from([(r2, (pose(10.0, 90.0), 6))]));
        book.set_through_fleet(BTreeMap::from([(r1, (pose(3.0, 0.0), r2))]));
        let joined = book.joined(r0);
        assert_eq!(joined[&r1].via, Some(r2));
        assert_eq!(joined[&r1].loops, 0);
        assert_eq!(joined[&r1].own_first_from_robot_first, pose(3.0, 0.0));
        assert_eq!(
            book.take_due(),
            Some(vec![(r2, pose(10.0, 90.0), 6)]),
            "only frames of the robot's own loops are sent"
        );
        // A frame the robot holds loops with itself stands before one the fleet's loops give.
        book.set_through_fleet(BTreeMap::from([(r2, (pose(50.0, 0.0), r1))]));
        assert_eq!(book.joined(r0)[&r2].own_first_from_robot_first, pose(10.0, 90.0));
        assert!(book.through_others(r0, r0, r1).is_empty(), "no cycle rests on it");
    }
}
