//! The robot's own keyframe clouds it sent, per peer: a cloud crosses each link once. A peer that asks
//! again (its retry crossed the reply, still queued on a slow link) is not sent a second copy until the
//! reply must have been lost, `resend_after_nanos` after the first (longer than the link can hold a
//! message back), so on a link that loses nothing every cloud is sent once per peer.

use std::collections::HashMap;

use skid_core::{KeyframeId, RobotId};

/// What the robot did with cloud requests, for the run summary.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CloudServing {
    /// Clouds sent for a first request of that peer.
    pub sent: u64,
    /// Clouds sent again after `resend_after` (the first copy was presumably lost).
    pub resent: u64,
    /// Repeated requests answered with nothing, the first copy being still on its way.
    pub repeats_ignored: u64,
}

/// When each (peer, keyframe) cloud was last sent.
#[derive(Debug, Default)]
pub(crate) struct ServedClouds {
    last_sent_nanos: HashMap<(RobotId, KeyframeId), u64>,
    counts: CloudServing,
}

impl ServedClouds {
    /// Whether to send `keyframe`'s cloud to `peer` now; records the send when it says yes.
    pub(crate) fn should_send(
        &mut self,
        peer: RobotId,
        keyframe: KeyframeId,
        now_nanos: u64,
        resend_after_nanos: u64,
    ) -> bool {
        match self.last_sent_nanos.get(&(peer, keyframe)) {
            None => {
                self.counts.sent += 1;
            }
            Some(&sent_nanos) if now_nanos.saturating_sub(sent_nanos) >= resend_after_nanos => {
                self.counts.resent += 1;
            }
            Some(_) => {
                self.counts.repeats_ignored += 1;
                return false;
            }
        }
        self.last_sent_nanos.insert((peer, keyframe), now_nanos);
        true
    }

    pub(crate) fn counts(&self) -> CloudServing {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cloud_is_sent_once_per_peer_until_the_first_copy_must_have_been_lost() {
        let mut served = ServedClouds::default();
        let keyframe = KeyframeId {
            robot: RobotId(0),
            index: 4,
        };
        assert!(served.should_send(RobotId(1), keyframe, 0, 100));
        // The same peer asks again while the reply is still on the link: nothing is sent.
        assert!(!served.should_send(RobotId(1), keyframe, 60, 100));
        // Another peer gets its own copy.
        assert!(served.should_send(RobotId(2), keyframe, 60, 100));
        // Past the resend time the first copy is taken as lost.
        assert!(served.should_send(RobotId(1), keyframe, 100, 100));
        assert_eq!(
            served.counts(),
            CloudServing {
                sent: 2,
                resent: 1,
                repeats_ignored: 1
            }
        );
    }
}
