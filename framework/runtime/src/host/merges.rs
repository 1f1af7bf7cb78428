//! The frames of merged robots at work: this robot's frames of the robots it holds accepted loops with
//! (from its back-end) are refreshed and sent to its peers when they change; a peer's report is kept,
//! and the verifier re-judges its loops against the frames it now composes through that peer
//! ([`super::frame_book`]).

use std::collections::BTreeMap;

use skid_config::ResolvedConfig;
use skid_core::{KeyframeId, Pose, RobotId};
use skid_protocol::{FrameMsg, Frames, Message, PoseMsg};

use super::RobotHost;
use crate::error::RuntimeError;

/// A robot's first keyframe.
fn first_keyframe(robot: RobotId) -> KeyframeId {
    KeyframeId { robot, index: 0 }
}

impl RobotHost {
    /// Recomputes this robot's frames of its merged peers from the back-end: the pose of each peer's
    /// first keyframe in the frame of this robot's first keyframe, for every peer it holds accepted
    /// loops with (carried from the peer's earliest keyframe in the graph by the peer's odometry when
    /// the first one is not in the graph); and the frames of the robots its back-end places through the
    /// fleet's loops alone, kept apart
    /// ([`super::frame_book::FrameBook::set_through_fleet`]).
    pub(crate) fn refresh_frames(&mut self) {
        let Some(graph) = self.plugins.backend.as_ref().map(|backend| backend.graph()) else {
            return;
        };
        let Some(own_first) = graph.pose(first_keyframe(self.robot)) else {
            return;
        };
        let peer_first = |peer: RobotId| {
            graph.pose(first_keyframe(peer)).or_else(|| {
                // The distributed graph holds a peer only where loops touch it: its first keyframe is
                // then placed from the earliest one the graph holds, along the peer's odometry.
                let held = self.graph.keyframes_of(peer).next()?;
                let odometry_held = self.chains.pose(held)?;
                let odometry_first = self.chains.pose(first_keyframe(peer))?;
                Some(graph.pose(held)? * odometry_held.inverse() * odometry_first)
            })
        };
        let mut loops_with: BTreeMap<RobotId, u32> = BTreeMap::new();
        for closure in self.loops.accepted().values() {
            for robot in [closure.target.robot, closure.source.robot] {
                if robot != self.robot {
                    *loops_with.entry(robot).or_default() += 1;
                }
            }
        }
        // Robots only the fleet's loops place, each with the robot at the other end of most of them.
        let mut fleet_ends: BTreeMap<RobotId, BTreeMap<RobotId, u32>> = BTreeMap::new();
        for closure in self.fleet_loops.in_backend() {
            let ends = [closure.target.robot, closure.source.robot];
            for (robot, other) in [(ends[0], ends[1]), (ends[1], ends[0])] {
                if robot != self.robot && robot != other && !loops_with.contains_key(&robot) {
                    *fleet_ends.entry(robot).or_default().entry(other).or_default() += 1;
                }
            }
        }
        let own = loops_with
            .into_iter()
            .filter_map(|(peer, loops)| Some((peer, (own_first.inverse() * peer_first(peer)?, loops))))
            .collect();
        let through_fleet = fleet_ends
            .into_iter()
            .filter_map(|(robot, others)| {
                let (via, _) = others.into_iter().max_by_key(|&(other, loops)| (loops, other))?;
                Some((robot, (own_first.inverse() * peer_first(robot)?, via)))
            })
            .collect();
        self.frames.set_own(own);
        self.frames.set_through_fleet(through_fleet);
        let now_nanos = self.now_nanos();
        self.frames.note_joined(self.robot, now_nanos);
    }

    /// A `Frames` message when this robot's frames changed since it last sent them.
    pub(crate) fn frames_message_if_due(&mut self) -> Option<Message> {
        self.refresh_frames();
        let frames = self.frames.take_due()?;
        let now_nanos = self.now_nanos();
        self.frame_repeats.changed((), now_nanos);
        Some(self.frames_message(frames))
    }

    /// A `Frames` message stating `frames` (robot, own_first_from_robot_first, loops).
    pub(crate) fn frames_message(&self, frames: Vec<(RobotId, Pose, u32)>) -> Message {
        Message::Frames(Frames {
            robot: self.robot,
            frames: frames
                .into_iter()
                .map(|(robot, pose, loops)| FrameMsg {
                    robot,
                    sender_first_from_robot_first: PoseMsg::from_pose(&pose),
                    loops,
                })
                .collect(),
        })
    }

    /// Keeps a peer's frames and lets the verifier re-judge the loops against the new cycles.
    pub(crate) fn on_frames(
        &mut self,
        config: &ResolvedConfig,
        from: RobotId,
        frames: Frames,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        let report: BTreeMap<RobotId, Pose> = frames
            .frames
            .iter()
            .filter_map(|frame| Some((frame.robot, frame.sender_first_from_robot_first.to_pose()?)))
            .collect();
        self.frames.record_report(from, report);
        self.reconsider_loops(config, outbox)
    }

    /// Lets the verifier re-judge the loops submitted so far against the graph as it is now: new frames
    /// through third robots, new keyframes on which a frame hypothesis's predictions can be checked.
    pub(crate) fn reconsider_loops(
        &mut self,
        config: &ResolvedConfig,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        if config.loops.fleet_loops {
            self.reconsider_fleet_loops(config)?;
        }
        match self.reconsidered(config, false)? {
            Some(verdict) => self.apply_verdict(config, verdict, outbox),
            None => Ok(()),
        }
    }
}
