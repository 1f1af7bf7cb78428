//! The peer clouds a robot asked for, holds and waits on: a peer's keyframe cloud is fetched only for
//! its loop candidates (SKiD-SLAM, Sec. III), so each inter-robot candidate either finds the cloud here
//! or waits for it; unanswered requests are asked again with a doubling wait.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;

use skid_core::{Cloud, KeyframeId};

/// A loop candidate waiting for (or ready with) its clouds.
#[derive(Clone, Copy, Debug)]
pub struct PendingCandidate {
    pub target: KeyframeId,
    pub source: KeyframeId,
    pub yaw_hint_rad: Option<f64>,
}

/// When a cloud request was last sent, in the host's clock, and how long to wait before asking again (0:
/// the first retry period); the wait doubles with each retry so a congested link is not flooded with
/// copies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct CloudRequestState {
    sent_nanos: u64,
    wait_nanos: u64,
}

/// Why a received cloud was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CloudRefusal {
    /// The second answer to a request that was sent again: harmless.
    AlreadyHeld,
    /// Nobody asked for it.
    Unrequested,
}

/// Peer clouds held, requested, and the candidates waiting for them.
#[derive(Debug, Default)]
pub(crate) struct PeerClouds {
    held: HashMap<KeyframeId, Arc<Cloud>>,
    /// Peer keyframes whose cloud was requested and has not arrived.
    requested: BTreeMap<KeyframeId, CloudRequestState>,
    /// Requests whose candidates all expired: not asked again, but their cloud is still taken when it
    /// comes late (later candidates may want it).
    given_up: BTreeSet<KeyframeId>,
    /// Candidates waiting for a cloud, each with when it began to wait.
    waiting: Vec<(PendingCandidate, u64)>,
    /// Clouds that arrived while a copy was held already (the link carried them twice).
    received_again: u64,
}

impl PeerClouds {
    pub(crate) fn get(&self, id: KeyframeId) -> Option<Arc<Cloud>> {
        self.held.get(&id).cloned()
    }

    /// Holds a cloud no one asked for over a link: a prior map's, loaded with the run.
    pub(crate) fn hold(&mut self, id: KeyframeId, cloud: Arc<Cloud>) {
        self.held.insert(id, cloud);
    }

    pub(crate) fn holds(&self, id: KeyframeId) -> bool {
        self.held.contains_key(&id)
    }

    /// Whether the cloud of `id` is held or asked for.
    pub(crate) fn knows(&self, id: KeyframeId) -> bool {
        self.held.contains_key(&id) || self.requested.contains_key(&id)
    }

    /// Parks a candidate until its target's cloud comes; true when the cloud must be requested now (it
    /// was not requested before).
    pub(crate) fn wait_for(&mut self, candidate: PendingCandidate, now_nanos: u64) -> bool {
        self.waiting.push((candidate, now_nanos));
        if self.requested.contains_key(&candidate.target) {
            return false;
        }
        self.given_up.remove(&candidate.target);
        let state = CloudRequestState {
            sent_nanos: now_nanos,
            wait_nanos: 0,
        };
        self.requested.insert(candidate.target, state);
        true
    }

    /// When the oldest unanswered request was (last) sent.
    pub(crate) fn oldest_request_nanos(&self) -> Option<u64> {
        self.requested.values().map(|state| state.sent_nanos).min()
    }

    /// Candidates still waiting for a cloud.
    pub(crate) fn waiting(&self) -> usize {
        self.waiting.len()
    }

    /// Drops the candidates that have waited `expiry_nanos` or longer, and stops asking for clouds no
    /// candidate waits for any more; returns how many candidates expired.
    pub(crate) fn expire(&mut self, now_nanos: u64, expiry_nanos: u64) -> usize {
        let before = self.waiting.len();
        self.waiting
            .retain(|&(_, since_nanos)| now_nanos.saturating_sub(since_nanos) < expiry_nanos);
        let expired = before - self.waiting.len();
        if expired > 0 {
            let still_wanted: BTreeSet<KeyframeId> = self
                .waiting
                .iter()
                .map(|(candidate, _)| candidate.target)
                .collect();
            let abandoned: Vec<KeyframeId> = self
                .requested
                .keys()
                .filter(|id| !still_wanted.contains(id))
                .copied()
                .collect();
            for id in abandoned {
                self.requested.remove(&id);
                self.given_up.insert(id);
            }
        }
        expired
    }

    /// Requests unanswered for their wait at `now_nanos`, to send again; each retry doubles the wait,
    /// up to 16 periods.
    pub(crate) fn due(&mut self, now_nanos: u64, period_nanos: u64) -> Vec<KeyframeId> {
        let mut again = Vec::new();
        for (&id, state) in &mut self.requested {
            let wait_nanos = state.wait_nanos.max(period_nanos);
            if now_nanos.saturating_sub(state.sent_nanos) >= wait_nanos {
                state.sent_nanos = now_nanos;
                state.wait_nanos = (2 * wait_nanos).min(16 * period_nanos);
                again.push(id);
            }
        }
        again
    }

    /// Clouds that arrived while a copy was held already.
    pub(crate) fn received_again(&self) -> u64 {
        self.received_again
    }

    /// Checks that a cloud arriving for `id` is wanted, before it is decoded; a second copy is counted.
    pub(crate) fn check_wanted(&mut self, id: KeyframeId) -> Result<(), CloudRefusal> {
        if self.held.contains_key(&id) {
            self.received_again += 1;
            Err(CloudRefusal::AlreadyHeld)
        } else if !self.requested.contains_key(&id) && !self.given_up.contains(&id) {
            Err(CloudRefusal::Unrequested)
        } else {
            Ok(())
        }
    }

    /// Keeps a requested cloud; returns the candidates that waited for it.
    pub(crate) fn receive(&mut self, id: KeyframeId, cloud: Cloud) -> Vec<PendingCandidate> {
        self.held.insert(id, Arc::new(cloud));
        self.requested.remove(&id);
        self.given_up.remove(&id);
        let (ready, still_waiting): (Vec<_>, Vec<_>) = self
            .waiting
            .iter()
            .partition(|(candidate, _)| candidate.target == id);
        self.waiting = still_waiting;
        ready.into_iter().map(|(candidate, _)| candidate).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::RobotId;

    fn keyframe(robot: u32, index: u32) -> KeyframeId {
        KeyframeId {
            robot: RobotId(robot),
            index,
        }
    }

    #[test]
    fn a_cloud_is_requested_once_and_retried_with_a_doubling_wait() {
        let mut clouds = PeerClouds::default();
        let candidate = |source| PendingCandidate {
            target: keyframe(1, 7),
            source: keyframe(0, source),
            yaw_hint_rad: None,
        };
        assert!(clouds.wait_for(candidate(3), 0));
        assert!(!clouds.wait_for(candidate(4), 5));
        assert_eq!(clouds.waiting(), 2);
        let period = 10;
        assert!(clouds.due(9, period).is_empty());
        assert_eq!(clouds.due(10, period), vec![keyframe(1, 7)]);
        // The wait is now 20: nothing at 29, again at 30.
        assert!(clouds.due(29, period).is_empty());
        assert_eq!(clouds.due(30, period).len(), 1);
        assert_eq!(
            clouds.check_wanted(keyframe(1, 8)),
            Err(CloudRefusal::Unrequested)
        );
        assert_eq!(clouds.check_wanted(keyframe(1, 7)), Ok(()));
        let ready = clouds.receive(keyframe(1, 7), Cloud::new(Vec::new()));
        assert_eq!(ready.len(), 2);
        assert_eq!(clouds.waiting(), 0);
        assert_eq!(
            clouds.check_wanted(keyframe(1, 7)),
            Err(CloudRefusal::AlreadyHeld)
        );
        assert_eq!(clouds.received_again(), 1);
        assert!(clouds.due(1000, period).is_empty());
    }

    #[test]
    fn candidates_that_wait_too_long_expire_and_their_late_cloud_is_still_taken() {
        let mut clouds = PeerClouds::default();
        let candidate = |target| PendingCandidate {
            target: keyframe(1, target),
            source: keyframe(0, 3),
            yaw_hint_rad: None,
        };
        assert!(clouds.wait_for(candidate(7), 0));
        assert!(clouds.wait_for(candidate(8), 50));
        assert_eq!(clouds.expire(99, 100), 0);
        assert_eq!(clouds.expire(100, 100), 1);
        assert_eq!(clouds.waiting(), 1);
        // Keyframe 7's request is given up: not asked again, but its cloud is taken when it comes.
        assert_eq!(clouds.due(1000, 10), vec![keyframe(1, 8)]);
        assert_eq!(clouds.check_wanted(keyframe(1, 7)), Ok(()));
        assert!(clouds.receive(keyframe(1, 7), Cloud::new(Vec::new())).is_empty());
        assert!(clouds.knows(keyframe(1, 7)) && clouds.knows(keyframe(1, 8)));
        assert!(!clouds.knows(keyframe(1, 9)));
    }
}
