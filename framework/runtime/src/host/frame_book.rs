//! Frames of other robots. A robot places each robot it has merged with (it holds accepted loops with
//! it) from its back-end: the pose of that robot's first keyframe in the frame of its own first keyframe.
//! It sends these to its peers (`Frames` messages) when they change, and keeps what its peers send. A
//! direct frame between this robot and a peer can then be checked against the cycle through a third
//! robot that has merged with both ([`FrameBook::through_others`]): aliasing that fools one pair of
//! robots rarely fools two pairs into the same wrong frame.

use std::collections::BTreeMap;

use skid_core::{Pose, RobotId};

/// A frame that moved less than this (translation) since it was last sent is not sent again.
const RESEND_M: f64 = 0.25;
/// A frame that turned less than this since it was last sent is not sent again.
const RESEND_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// This robot's frames of its merged peers, and its peers' reports of theirs.
#[derive(Debug, Default)]
pub(crate) struct FrameBook {
    /// This robot's current frames: peer → own_first_from_peer_first.
    own: BTreeMap<RobotId, (Pose, u32)>,
    /// The frames last sent.
    sent: BTreeMap<RobotId, Pose>,
    /// Each peer's last report: peer → (robot → peer_first_from_robot_first).
    reported: BTreeMap<RobotId, BTreeMap<RobotId, Pose>>,
}

impl FrameBook {
    /// Replaces this robot's frames (peer → own_first_from_peer_first and the loops behind it).
    pub(crate) fn set_own(&mut self, own: BTreeMap<RobotId, (Pose, u32)>) {
        self.own = own;
    }

    /// This robot's current frames.
    pub(crate) fn own(&self) -> &BTreeMap<RobotId, (Pose, u32)> {
        &self.own
    }

    /// The frames to send now, when they differ from the ones last sent (a frame appeared, left, or
    /// moved); they count as sent.
    pub(crate) fn take_due(&mut self) -> Option<Vec<(RobotId, Pose, u32)>> {
        let moved = |robot: &RobotId, pose: &Pose| {
            self.sent.get(robot).is_none_or(|last| {
                let change = last.inverse() * pose;
                change.translation.vector.norm() > RESEND_M || change.rotation.angle() > RESEND_RAD
            })
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
        Some(
            self.own
                .iter()
                .map(|(robot, (pose, loops))| (*robot, *pose, *loops))
                .collect(),
        )
    }

    /// Keeps `from`'s report, replacing its previous one.
    pub(crate) fn record_report(&mut self, from: RobotId, frames: BTreeMap<RobotId, Pose>) {
        self.reported.insert(from, frames);
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

    fn pose(x: f64, yaw_deg: f64) -> Pose {
        Pose::new(Vector3::new(x, 0.0, 0.0), Vector3::z() * yaw_deg.to_radians())
    }

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
}
