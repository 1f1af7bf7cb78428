//! What a robot running in its own process has told its peers, kept so that a peer that joins late or
//! comes back after a restart (a new protocol session) can be brought up to date: the robot's odometry
//! chain, its descriptors and the inter-robot loops it accepted with that peer (every loop it announced,
//! when it shares the fleet's loops). In the SKiD-SLAM
//! pipeline (Sec. III) descriptors and chains are broadcast once per keyframe; on a real network a peer
//! that was not listening then would never learn them, and would find no loops with this robot.
//!
//! The replay is batched (one `OdomChain` per contiguous run of keyframes, descriptor batches of up to
//! [`REPLAY_BATCH`] entries) so a catch-up is a handful of messages, not one per keyframe.

use std::collections::BTreeSet;

use skid_core::{KeyframeId, RobotId};
use skid_protocol::{DescriptorBatch, Message, OdomChain};

/// Most chain edges or descriptor entries in one replayed message.
pub const REPLAY_BATCH: usize = 128;

/// Everything worth replaying to a peer that (re)appears.
#[derive(Debug, Default)]
pub struct CatchUp {
    chain: Vec<OdomChain>,
    descriptors: Vec<DescriptorBatch>,
    /// `Loops` messages and the peer each went to (`None`: every peer).
    loops: Vec<(Option<RobotId>, Message)>,
    /// Peer descriptors already handed to the index (replays from peers repeat them).
    seen_descriptors: BTreeSet<KeyframeId>,
}

impl CatchUp {
    /// Remembers the messages `robot` is about to send that a late peer would need; `loops_to_fleet`
    /// when its `Loops` messages go to every peer (`loops.fleet_loops`).
    pub fn record(&mut self, robot: RobotId, outbox: &[Message], loops_to_fleet: bool) {
        for message in outbox {
            match message {
                Message::OdomChain(chain) if chain.robot == robot => self.chain.push(chain.clone()),
                Message::Descriptors(batch) if batch.robot == robot => self.descriptors.push(batch.clone()),
                Message::Loops(_) if loops_to_fleet => self.loops.push((None, message.clone())),
                Message::Loops(_) => {
                    if let skid_core::slots::Destination::Robot(peer) =
                        crate::messages::destination(robot, message)
                    {
                        self.loops.push((Some(peer), message.clone()));
                    }
                }
                _ => {}
            }
        }
    }

    /// The messages that bring `peer` up to date, batched.
    pub fn replay_for(&self, peer: RobotId) -> Vec<Message> {
        let mut messages = Vec::new();
        let mut current: Option<OdomChain> = None;
        for link in &self.chain {
            match current.as_mut() {
                // Chain messages overlap: each repeats the steps before its newest.
                Some(run)
                    if (link.from_index..link.to_index).contains(&run.to_index)
                        && run.edges.len() < REPLAY_BATCH =>
                {
                    let repeated = (run.to_index - link.from_index) as usize;
                    run.edges.extend(link.edges.iter().skip(repeated).copied());
                    run.to_index = link.to_index;
                }
                Some(run) if link.from_index >= run.from_index && link.to_index <= run.to_index => {}
                _ => {
                    if let Some(run) = current.replace(link.clone()) {
                        messages.push(Message::OdomChain(run));
                    }
                }
            }
        }
        messages.extend(current.map(Message::OdomChain));
        let mut batch: Option<DescriptorBatch> = None;
        for entry in &self.descriptors {
            match batch.as_mut() {
                Some(open) if open.kind == entry.kind && open.entries.len() < REPLAY_BATCH => {
                    open.entries.extend(entry.entries.iter().cloned());
                }
                _ => {
                    if let Some(full) = batch.replace(entry.clone()) {
                        messages.push(Message::Descriptors(full));
                    }
                }
            }
        }
        messages.extend(batch.map(Message::Descriptors));
        messages.extend(
            self.loops
                .iter()
                .filter(|(to, _)| to.is_none_or(|to| to == peer))
                .map(|(_, message)| message.clone()),
        );
        messages
    }

    /// Drops descriptors of a peer's batch that were handled before (a peer's replay after this robot
    /// restarted or joined late repeats them); false when nothing new is left.
    pub fn keep_new_descriptors(&mut self, batch: &mut DescriptorBatch) -> bool {
        let robot = batch.robot;
        batch.entries.retain(|entry| {
            self.seen_descriptors.insert(KeyframeId {
                robot,
                index: entry.keyframe_index,
            })
        });
        !batch.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::Pose;
    use skid_protocol::{ChainEdge, DescriptorEntry, DescriptorValues, InformationMsg, PoseMsg};

    fn chain(robot: RobotId, to: u32) -> Message {
        let edge = ChainEdge {
            target_from_source: PoseMsg::from_pose(&Pose::identity()),
            information: InformationMsg::from_information(&skid_core::Information::identity()),
        };
        Message::OdomChain(OdomChain {
            robot,
            from_index: to.saturating_sub(1),
            to_index: to,
            edges: if to == 0 { Vec::new() } else { vec![edge] },
            world_from_first: PoseMsg::from_pose(&Pose::identity()),
        })
    }

    fn descriptor(robot: RobotId, index: u32) -> Message {
        Message::Descriptors(DescriptorBatch {
            robot,
            kind: "solid".into(),
            entries: vec![DescriptorEntry {
                keyframe_index: index,
                stamp_nanos: u64::from(index),
                values: DescriptorValues::F32(vec![index as f32; 4]),
                newest_held: Vec::new(),
            }],
        })
    }

    #[test]
    fn replay_batches_the_chain_and_descriptors() {
        let robot = RobotId(1);
        let mut catch_up = CatchUp::default();
        for index in 0..300 {
            catch_up.record(robot, &[chain(robot, index), descriptor(robot, index)], false);
        }
        let replay = catch_up.replay_for(RobotId(0));
        let chains: Vec<&OdomChain> = replay
            .iter()
            .filter_map(|m| match m {
                Message::OdomChain(c) => Some(c),
                _ => None,
            })
            .collect();
        assert_eq!(chains.len(), 3);
        assert_eq!((chains[0].from_index, chains[0].to_index), (0, 128));
        assert_eq!(chains[0].edges.len(), 128);
        assert_eq!(chains[2].to_index, 299);
        let covered: usize = chains.iter().map(|c| c.edges.len()).sum();
        assert_eq!(covered, 299);
        let entries: usize = replay
            .iter()
            .filter_map(|m| match m {
                Message::Descriptors(b) => Some(b.entries.len()),
                _ => None,
            })
            .sum();
        assert_eq!(entries, 300);
        for message in &replay {
            message.validate().unwrap();
        }
    }

    #[test]
    fn overlapping_chain_messages_replay_each_step_once() {
        let robot = RobotId(3);
        let edge = ChainEdge {
            target_from_source: PoseMsg::from_pose(&Pose::identity()),
            information: InformationMsg::from_information(&skid_core::Information::identity()),
        };
        let mut catch_up = CatchUp::default();
        // Each message carries the steps into its keyframe from up to three keyframes before.
        for index in 0..10u32 {
            let from_index = index.saturating_sub(3);
            let message = Message::OdomChain(OdomChain {
                robot,
                from_index,
                to_index: index,
                edges: vec![edge; (index - from_index) as usize],
                world_from_first: PoseMsg::from_pose(&Pose::identity()),
            });
            catch_up.record(robot, &[message], false);
        }
        let replay = catch_up.replay_for(RobotId(0));
        let [Message::OdomChain(chain)] = replay.as_slice() else {
            panic!("one chain expected, got {replay:?}");
        };
        assert_eq!((chain.from_index, chain.to_index), (0, 9));
        assert_eq!(chain.edges.len(), 9);
        Message::OdomChain(chain.clone()).validate().unwrap();
    }

    #[test]
    fn loops_go_to_the_peer_they_join_or_to_every_peer_when_the_fleet_shares_them() {
        let (me, peer, third) = (RobotId(0), RobotId(1), RobotId(2));
        let closure = skid_core::slots::LoopClosure {
            id: skid_core::LoopId(1),
            target: KeyframeId::new(0, 4),
            source: KeyframeId::new(1, 7),
            target_from_source: Pose::identity(),
            information: skid_core::Information::identity(),
        };
        let message = crate::messages::loops_message(me, std::slice::from_ref(&closure), &[]);
        let is_loops =
            |replay: Vec<Message>| replay.iter().filter(|m| matches!(m, Message::Loops(_))).count();
        // The loop messages replayed to the peer the loop joins and to a third robot.
        let replayed = |loops_to_fleet| {
            let mut catch_up = CatchUp::default();
            catch_up.record(me, std::slice::from_ref(&message), loops_to_fleet);
            (
                is_loops(catch_up.replay_for(peer)),
                is_loops(catch_up.replay_for(third)),
            )
        };
        assert_eq!(replayed(false), (1, 0));
        assert_eq!(replayed(true), (1, 1));
    }

    #[test]
    fn repeated_descriptors_are_dropped() {
        let mut catch_up = CatchUp::default();
        let Message::Descriptors(mut first) = descriptor(RobotId(2), 5) else {
            unreachable!()
        };
        let mut again = first.clone();
        assert!(catch_up.keep_new_descriptors(&mut first));
        assert!(!catch_up.keep_new_descriptors(&mut again));
    }
}
