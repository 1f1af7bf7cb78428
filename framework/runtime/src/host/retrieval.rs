//! The second place inter-robot candidates are looked for: when a peer's descriptor arrives.
//!
//! A robot queries each new keyframe of its own against the descriptors its index holds (the paper's
//! retrieval, Sec. III-B), so a candidate between its keyframe `a` and a peer's keyframe `b` is found
//! by whichever robot makes its keyframe after the other's descriptor has arrived. Two robots that pass
//! a place within one link delay of each other, or a robot that passes every place first while its
//! peers' descriptors of it are still on the way, leave such pairs unseen on both sides: the longer the
//! delays (a weak link, a congested one, a slow machine), the more of them.
//!
//! So each descriptor carries the newest keyframe of every peer the sender's index held when it looked
//! for its candidates ([`skid_protocol::DescriptorEntry::newest_held`]), and the receiver queries it
//! against its own keyframes newer than that: the ones the sender could not see. When such a pair is
//! found on arrival, neither robot saw it when making its keyframe (a robot that held the other's
//! descriptor then would have looked itself, and the other keyframe did not exist yet when that
//! descriptor arrived), so both robots would find it on arrival; one of the two, the pair's owner, does
//! ([`owns_pair`], spread over the fleet like a round-robin schedule). Each keyframe pair is looked for
//! once across the fleet whatever the delays; a lost descriptor still loses its pairs, as before.

use std::time::Instant;

use skid_config::ResolvedConfig;
use skid_core::slots::DescriptorBuf;
use skid_core::{KeyframeId, RobotId, Slot};

use super::RobotHost;
use super::candidate_queue::QueuedCandidate;
use super::loop_book::LoopEvent;
use super::peer_clouds::PendingCandidate;
use crate::error::RuntimeError;

/// Whether `me` looks for the candidates of the pair with `peer` that neither robot saw: of the two,
/// the lower id when the ids' sum is even, the higher one when it is odd.
pub(crate) fn owns_pair(me: RobotId, peer: RobotId) -> bool {
    let (low, high) = (me.0.min(peer.0), me.0.max(peer.0));
    if (low + high).is_multiple_of(2) {
        me.0 == low
    } else {
        me.0 == high
    }
}

/// Whether an own keyframe is one the sender of a descriptor could not see: newer than the newest of
/// this robot's keyframes it held (`None`: it held none).
pub(crate) fn unseen_by_sender(own_index: u32, newest_held: Option<u32>) -> bool {
    newest_held.is_none_or(|held| own_index > held)
}

/// What the sender held of this robot's keyframes in this robot's current session: `newest_held`,
/// unless it names a keyframe newer than this robot's newest (`newest_own`). A sender cannot hold a
/// keyframe that was not made yet, so such a figure describes an earlier session of this robot (the
/// process was restarted and makes its keyframes again); the sender saw none of the current ones, and
/// every own keyframe is unseen.
pub(crate) fn held_this_session(newest_held: Option<u32>, newest_own: Option<u32>) -> Option<u32> {
    match (newest_held, newest_own) {
        (Some(held), Some(own)) if held <= own => Some(held),
        _ => None,
    }
}

impl RobotHost {
    /// The largest descriptor distance of a candidate: `[loops] max_descriptor_distance`, or the
    /// descriptor's own threshold when that is 0.
    pub(crate) fn candidate_distance_limit(&self, config: &ResolvedConfig) -> f64 {
        let limit = config.loops.max_descriptor_distance;
        if limit > 0.0 {
            limit
        } else {
            self.plugins
                .descriptor
                .as_ref()
                .map_or(f64::INFINITY, |descriptor| descriptor.match_threshold())
        }
    }

    /// Queries a peer keyframe's descriptor that just entered the index against this robot's own
    /// keyframes the peer had not seen when it looked for candidates (`newest_held`: the newest of them
    /// it held), when this robot owns the pair; what it finds joins the candidate budget like any
    /// inter-robot candidate.
    pub(crate) fn query_arrived_descriptor(
        &mut self,
        config: &ResolvedConfig,
        peer_keyframe: KeyframeId,
        descriptor: &DescriptorBuf,
        newest_held: Option<u32>,
    ) -> Result<(), RuntimeError> {
        let me = self.robot;
        let newest_own = self.own.keyframes().keys().next_back().copied();
        let newest_held = held_this_session(newest_held, newest_own);
        let nothing_unseen = newest_own.is_none_or(|newest| !unseen_by_sender(newest, newest_held));
        // With a prior and without own loops, robots close loops with the prior only.
        let prior_only = !crate::prior::closes_own_loops(config);
        if !config.loops.inter_robot || prior_only || nothing_unseen || !owns_pair(me, peer_keyframe.robot) {
            return Ok(());
        }
        let limit = self.candidate_distance_limit(config);
        let Some(index) = self.index.as_mut() else {
            return Ok(());
        };
        let started = Instant::now();
        let exclude =
            |candidate: KeyframeId| candidate.robot != me || !unseen_by_sender(candidate.index, newest_held);
        let found = index.query(descriptor, config.loops.candidates, &exclude);
        self.add_stage_ms("retrieval", started.elapsed().as_secs_f64() * 1e3);
        let found = found.map_err(|error| self.plugin_error(config, Slot::Descriptor, error))?;
        let raised_nanos = self.now_nanos();
        for place in found.into_iter().filter(|place| place.distance <= limit) {
            self.loops.count(LoopEvent::InterCandidate);
            self.loops.count(LoopEvent::InterOnArrival);
            // The index's hint turns the peer's (query) points into the own keyframe's frame; the
            // candidate registers the own keyframe (source) onto the peer's (target), the other way.
            let queued = QueuedCandidate {
                candidate: PendingCandidate {
                    target: peer_keyframe,
                    source: place.id,
                    yaw_hint_rad: place.yaw_hint_rad.map(|yaw| -yaw),
                },
                distance: place.distance,
                raised_nanos,
            };
            self.queue_candidate(config, queued);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_pair_has_exactly_one_owner_and_the_owners_are_spread() {
        let robots = 16u32;
        let mut owned = vec![0usize; robots as usize];
        for i in 0..robots {
            for j in (0..robots).filter(|&j| j != i) {
                let (a, b) = (
                    owns_pair(RobotId(i), RobotId(j)),
                    owns_pair(RobotId(j), RobotId(i)),
                );
                assert!(a != b, "robots {i} and {j}: exactly one owns the pair");
                owned[i as usize] += usize::from(a);
            }
        }
        // 120 pairs over 16 robots: each owns 7 or 8.
        assert!(owned.iter().all(|&n| (7..=8).contains(&n)), "{owned:?}");
    }

    #[test]
    fn only_keyframes_newer_than_the_senders_newest_are_unseen() {
        assert!(unseen_by_sender(0, None));
        assert!(unseen_by_sender(7, Some(6)));
        assert!(!unseen_by_sender(6, Some(6)));
        assert!(!unseen_by_sender(2, Some(6)));
    }

    #[test]
    fn a_sender_that_held_keyframes_not_made_yet_saw_an_earlier_session() {
        assert_eq!(held_this_session(Some(4), Some(9)), Some(4));
        assert_eq!(held_this_session(Some(9), Some(9)), Some(9));
        // Robot restarted: the sender held keyframe 30 of the process before; this one made 9.
        assert_eq!(held_this_session(Some(30), Some(9)), None);
        assert_eq!(held_this_session(Some(3), None), None);
        assert_eq!(held_this_session(None, Some(9)), None);
    }
}
