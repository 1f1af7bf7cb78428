//! Well-formed messages a robot still refuses from its peers (issue #20, hostile and broken peers):
//! descriptors of another kind or length, loops that are not between the sender and this robot or name
//! a keyframe this robot does not have, clouds nobody asked for, stamps an hour away from this robot's
//! clock. Each class is counted for `summary.json` and warned about with a rate limit, so a flooding
//! peer cannot flood the log either. What the protocol itself refuses (malformed bytes, a sender that
//! is not who the transport says, copies and replays) is in the message counters instead.

use std::collections::BTreeMap;
use std::fmt::Display;

use skid_core::RobotId;

use crate::warn_limit::WarnLimiter;

/// Stamps further than this from the robot's own newest scan stamp suggest a peer's clock is off.
pub const CLOCK_OFFSET_WARNING_NANOS: u64 = 10 * 60 * 1_000_000_000;

/// Counts of refused peer messages, by class.
#[derive(Clone, Debug, Default)]
pub struct PeerFaults {
    by_class: BTreeMap<&'static str, WarnLimiter>,
    /// Rate limits of the warnings about malformed messages (counted by the protocol's counters).
    malformed: BTreeMap<&'static str, WarnLimiter>,
}

impl PeerFaults {
    /// Counts one fault of `class` in a message `from` a peer, and warns about it when due.
    pub fn record(&mut self, robot: RobotId, from: RobotId, class: &'static str, detail: impl Display) {
        let limiter = self.by_class.entry(class).or_default();
        if let Some(count) = limiter.occurrence() {
            tracing::warn!(robot = %robot, %from, class, count, "peer message refused: {detail}");
        }
    }

    /// Warns, with a rate limit per class, about a message the protocol refused as malformed (the
    /// protocol's counters count it).
    pub fn note_malformed(
        &mut self,
        robot: RobotId,
        from: RobotId,
        class: &'static str,
        error: impl Display,
    ) {
        if let Some(count) = self.malformed.entry(class).or_default().occurrence() {
            tracing::warn!(robot = %robot, %from, class, count, %error, "malformed message dropped");
        }
    }

    /// Faults so far by class (for `summary.json`).
    pub fn snapshot(&self) -> BTreeMap<String, u64> {
        self.by_class
            .iter()
            .map(|(class, limiter)| ((*class).to_owned(), limiter.count()))
            .collect()
    }

    /// Faults of one class so far.
    pub fn count(&self, class: &str) -> u64 {
        self.by_class.get(class).map_or(0, WarnLimiter::count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_by_class() {
        let mut faults = PeerFaults::default();
        for _ in 0..3 {
            faults.record(
                RobotId(0),
                RobotId(3),
                "loop_not_shared",
                "a loop between 1 and 2",
            );
        }
        faults.record(RobotId(0), RobotId(3), "cloud_unrequested", "keyframe 3/9");
        assert_eq!(faults.count("loop_not_shared"), 3);
        assert_eq!(faults.snapshot().get("cloud_unrequested"), Some(&1));
        assert_eq!(faults.count("descriptor_wrong_kind"), 0);
    }
}
