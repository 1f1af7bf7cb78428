//! The repeats at work (see `repeats`): on the budget's upkeep, each peer whose loop set changed lately
//! is sent its whole set again (accepted and retracted), or under `loops.fleet_loops` the fleet every
//! loop this robot found, and the robot's frames are sent again after they changed.

use skid_core::slots::LoopClosure;
use skid_protocol::Message;

use super::RobotHost;
use super::announced::Audience;
use crate::messages::{loops_message, other_robot};

/// Most loops stated in one message: a long set goes in several, each well under any message limit.
const LOOPS_PER_MESSAGE: usize = 64;

impl RobotHost {
    /// The loop sets and frames due to be sent again at `now_nanos`.
    pub(crate) fn restatements(&mut self, now_nanos: u64) -> Vec<Message> {
        let mut outbox = Vec::new();
        for audience in self.announced.take_due(now_nanos) {
            let accepted: Vec<LoopClosure> = self
                .loops
                .accepted()
                .iter()
                .filter(|(id, closure)| {
                    let stated = match audience {
                        Audience::Peer(peer) => {
                            closure.is_inter_robot()
                                && other_robot(self.robot, (closure.target, closure.source)) == peer
                        }
                        Audience::Fleet => true,
                    };
                    stated && !self.loops.is_from_peer(**id)
                })
                .map(|(_, closure)| closure.clone())
                .collect();
            let retracted = self.announced.retracted_with(audience);
            for chunk in accepted.chunks(LOOPS_PER_MESSAGE) {
                outbox.push(loops_message(self.robot, chunk, &[]));
            }
            for chunk in retracted.chunks(LOOPS_PER_MESSAGE) {
                outbox.push(loops_message(self.robot, &[], chunk));
            }
        }
        if !self.frame_repeats.take_due(now_nanos).is_empty() {
            outbox.push(self.frames_message(self.frames.own_list()));
        }
        outbox
    }
}
