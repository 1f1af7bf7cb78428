//! The peer clouds a robot asked for, holds and waits on: a peer's keyframe cloud is fetched only for
//! its loop candidates (SKiD-SLAM, Sec. III), so each inter-robot candidate either finds the cloud here
//! or waits for it; unanswered requests are asked again with a doubling wait.

use std::collections::{BTreeMap, HashMap};
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
    waiting: Vec<PendingCandidate>,
}

impl PeerClouds {
    pub(crate) fn get(&self, id: KeyframeId) -> Option<Arc<Cloud>> {
        self.held.get(&id).cloned()
    }

    pub(crate) fn holds(&self, id: KeyframeId) -> bool {
        self.held.contains_key(&id)
    }

    /// Parks a candidate until its target's cloud comes; true when the cloud must be requested now (it
    /// was not requested before).
    pub(crate) fn wait_for(&mut self, candidate: PendingCandidate, now_nanos: u64) -> bool {
        self.waiting.push(candidate);
        if self.requested.contains_key(&candidate.target) {
            return false;
        }
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

    /// Checks that a cloud arriving for `id` is wanted, before it is decoded.
    pub(crate) fn check_wanted(&self, id: KeyframeId) -> Result<(), CloudRefusal> {
        if self.held.contains_key(&id) {
            Err(CloudRefusal::AlreadyHeld)
        } else if !self.requested.contains_key(&id) {
            Err(CloudRefusal::Unrequested)
        } else {
            Ok(())
        }
    }

    /// Keeps a requested cloud; returns the candidates that waited for it.
    pub(crate) fn receive(&mut self, id: KeyframeId, cloud: Cloud) -> Vec<PendingCandidate> {
        self.held.insert(id, Arc::new(cloud));
        self.requested.remove(&id);
        let (ready, still_waiting) = self.waiting.iter().partition(|candidate| candidate.target == id);
        self.waiting = still_waiting;
        ready
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
        assert!(clouds.due(1000, period).is_empty());
    }
}
