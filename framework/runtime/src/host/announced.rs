//! What this robot told each peer about the inter-robot loops it found with that peer (or, with
//! `loops.fleet_loops`, the whole fleet about every loop it found): the pairs it retracted (the accepted
//! ones are in the loop book) and when the audience's state is next repeated (see `repeats`). A repeat
//! states the whole current set, accepted and retracted, so a peer that lost any earlier message ends
//! with the same loops as the sender.

use std::collections::{BTreeMap, BTreeSet};

use skid_core::{KeyframeId, RobotId};

use super::repeats::Repeats;

/// A loop's keyframe pair, `(target, source)`.
pub(crate) type Pair = (KeyframeId, KeyframeId);

/// Who a set of own loops is stated to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Audience {
    /// The one peer the loops join this robot with.
    Peer(RobotId),
    /// Every peer (`loops.fleet_loops`): every loop this robot found, its intra-robot ones too.
    Fleet,
}

/// The own loops announced to each audience.
#[derive(Debug, Default)]
pub(crate) struct Announced {
    retracted: BTreeMap<Audience, BTreeSet<Pair>>,
    repeats: Repeats<Audience>,
}

impl Announced {
    /// A loop was announced to `audience` as accepted at `now_nanos`.
    pub(crate) fn accepted(&mut self, audience: Audience, pair: Pair, now_nanos: u64) {
        if let Some(retracted) = self.retracted.get_mut(&audience) {
            retracted.remove(&pair);
        }
        self.repeats.changed(audience, now_nanos);
    }

    /// A loop was announced to `audience` as retracted at `now_nanos`.
    pub(crate) fn retracted(&mut self, audience: Audience, pair: Pair, now_nanos: u64) {
        self.retracted.entry(audience).or_default().insert(pair);
        self.repeats.changed(audience, now_nanos);
    }

    /// The pairs announced to `audience` as retracted.
    pub(crate) fn retracted_with(&self, audience: Audience) -> Vec<Pair> {
        self.retracted
            .get(&audience)
            .map(|pairs| pairs.iter().copied().collect())
            .unwrap_or_default()
    }

    /// Whether any peer's loops are still to be stated again.
    pub(crate) fn pending(&self) -> bool {
        self.repeats.pending()
    }

    /// The audiences whose loops are to be stated again at `now_nanos`.
    pub(crate) fn take_due(&mut self, now_nanos: u64) -> Vec<Audience> {
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
        let peer = Audience::Peer(RobotId(1));
        announced.retracted(peer, pair(3), 0);
        announced.retracted(peer, pair(4), 0);
        announced.accepted(peer, pair(3), 1);
        assert_eq!(announced.retracted_with(peer), vec![pair(4)]);
        assert!(announced.retracted_with(Audience::Peer(RobotId(2))).is_empty());
        assert!(announced.retracted_with(Audience::Fleet).is_empty());
        assert!(announced.take_due(1).is_empty());
        assert_eq!(announced.take_due(3_000_000_000), vec![peer]);
    }
}
