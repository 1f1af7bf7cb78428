//! What this robot told each peer about the inter-robot loops it found with that peer: the pairs it
//! retracted (the accepted ones are in the loop book) and when the peer's state is next repeated (see
//! `repeats`). A repeat states the whole current set, accepted and retracted, so a peer that lost any
//! earlier message ends with the same loops as the sender.

use std::collections::{BTreeMap, BTreeSet};

use skid_core::{KeyframeId, RobotId};

use super::repeats::Repeats;

/// A loop's keyframe pair, `(target, source)`.
pub(crate) type Pair = (KeyframeId, KeyframeId);

/// The own loops announced to each peer.
#[derive(Debug, Default)]
pub(crate) struct Announced {
    retracted: BTreeMap<RobotId, BTreeSet<Pair>>,
    repeats: Repeats<RobotId>,
}

impl Announced {
    /// A loop with `peer` was announced as accepted at `now_nanos`.
    pub(crate) fn accepted(&mut self, peer: RobotId, pair: Pair, now_nanos: u64) {
        if let Some(retracted) = self.retracted.get_mut(&peer) {
            retracted.remove(&pair);
        }
        self.repeats.changed(peer, now_nanos);
    }

    /// A loop with `peer` was announced as retracted at `now_nanos`.
    pub(crate) fn retracted(&mut self, peer: RobotId, pair: Pair, now_nanos: u64) {
        self.retracted.entry(peer).or_default().insert(pair);
        self.repeats.changed(peer, now_nanos);
    }

    /// The pairs retracted with `peer`.
    pub(crate) fn retracted_with(&self, peer: RobotId) -> Vec<Pair> {
        self.retracted
            .get(&peer)
            .map(|pairs| pairs.iter().copied().collect())
            .unwrap_or_default()
    }

    /// Whether any peer's loops are still to be stated again.
    pub(crate) fn pending(&self) -> bool {
        self.repeats.pending()
    }

    /// The peers whose loops are to be stated again at `now_nanos`.
    pub(crate) fn take_due(&mut self, now_nanos: u64) -> Vec<RobotId> {
        self.repeats.take_due(now_nanos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(index: u32) -> Pair {
        let id = |robot, index| KeyframeId {
            robot: RobotId(robot),
            index,
        };
        (id(0, index), id(1, index))
    }

    #[test]
    fn a_pair_accepted_again_is_no_longer_stated_as_retracted() {
        let mut announced = Announced::default();
        announced.retracted(RobotId(1), pair(3), 0);
        announced.retracted(RobotId(1), pair(4), 0);
        announced.accepted(RobotId(1), pair(3), 1);
        assert_eq!(announced.retracted_with(RobotId(1)), vec![pair(4)]);
        assert!(announced.retracted_with(RobotId(2)).is_empty());
        assert!(announced.take_due(1).is_empty());
        assert_eq!(announced.take_due(3_000_000_000), vec![RobotId(1)]);
    }
}
