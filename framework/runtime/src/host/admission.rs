//! The host's side of the loop-closure budget: inter-robot candidates are ranked with what the host
//! knows (which robots are in its frame, which peer clouds it holds or asked for, which peers it heard
//! from lately), admitted within the period's budget, and either registered at once (the cloud is here)
//! or parked until the cloud comes; on every step the waits that ran out expire and unanswered requests
//! are asked again.

use std::collections::BTreeSet;

use skid_config::ResolvedConfig;
use skid_core::{KeyframeId, RobotId};
use skid_protocol::Message;

use super::RobotHost;
use super::candidate_queue::{Budget, CandidateRanking};
use super::peer_clouds::PeerClouds;
use crate::clock::nanos_from_s;
use crate::error::RuntimeError;
use crate::messages::cloud_request;

/// The budget `[loops]` sets.
pub(crate) fn budget(config: &ResolvedConfig) -> Budget {
    let loops = &config.loops;
    Budget {
        per_period: loops.inter_robot_budget,
        period_nanos: nanos_from_s(loops.budget_period_s),
        expiry_nanos: nanos_from_s(loops.candidate_expiry_s),
        capacity: loops.candidate_queue,
    }
}

/// A peer heard from within this long (by the host's clock) counts as reachable: a few of its
/// keyframes' descriptors and odometry, or its heartbeats, at any speed the missions drive.
const REACHABLE_NANOS: u64 = 10_000_000_000;

/// What ranks candidates: the robots in this robot's frame (itself included), the peer clouds, and the
/// peers heard from lately.
pub(crate) struct HostRanking<'a> {
    in_frame: BTreeSet<RobotId>,
    clouds: &'a PeerClouds,
    reachable: BTreeSet<RobotId>,
}

impl CandidateRanking for HostRanking<'_> {
    fn in_frame(&self, robot: RobotId) -> bool {
        self.in_frame.contains(&robot)
    }

    fn cloud_known(&self, keyframe: KeyframeId) -> bool {
        self.clouds.knows(keyframe)
    }

    fn reachable(&self, robot: RobotId) -> bool {
        self.reachable.contains(&robot)
    }
}

impl RobotHost {
    /// The robots in this robot's frame (itself included) and the peers heard from within
    /// [`REACHABLE_NANOS`] of `now_nanos`.
    fn frame_and_reachable(&self, now_nanos: u64) -> (BTreeSet<RobotId>, BTreeSet<RobotId>) {
        let mut in_frame: BTreeSet<RobotId> = self.frames.joined(self.robot).into_keys().collect();
        in_frame.insert(self.robot);
        let reachable = self
            .heard_nanos
            .iter()
            .filter(|&(_, &heard)| now_nanos.saturating_sub(heard) <= REACHABLE_NANOS)
            .map(|(&robot, _)| robot)
            .collect();
        (in_frame, reachable)
    }

    /// Queues an inter-robot candidate for the budget.
    pub(crate) fn queue_candidate(
        &mut self,
        config: &ResolvedConfig,
        queued: super::candidate_queue::QueuedCandidate,
    ) {
        let budget = budget(config);
        let (in_frame, reachable) = self.frame_and_reachable(self.now_nanos());
        let ranking = HostRanking {
            in_frame,
            reachable,
            clouds: &self.peer_clouds,
        };
        self.candidates.push(queued, &budget, &ranking);
    }

    /// Admits what the budget allows: candidates whose cloud is here are registered now, the others
    /// wait for it (and the cloud is asked for once).
    pub(crate) fn admit_candidates(
        &mut self,
        config: &ResolvedConfig,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        if self.candidates.len() == 0 {
            return Ok(());
        }
        let now_nanos = self.now_nanos();
        let budget = budget(config);
        let waiting = self.peer_clouds.waiting();
        let (in_frame, reachable) = self.frame_and_reachable(now_nanos);
        let ranking = HostRanking {
            in_frame,
            reachable,
            clouds: &self.peer_clouds,
        };
        let admitted = self.candidates.admit(now_nanos, waiting, &budget, &ranking);
        for pending in admitted {
            if self.peer_clouds.holds(pending.target) {
                self.process_candidate(config, pending, outbox)?;
            } else if self.peer_clouds.wait_for(pending, now_nanos) {
                outbox.push(cloud_request(self.robot, pending.target));
            }
        }
        Ok(())
    }

    /// The budget's upkeep, on every step and while the executor drains the links: waits that ran out
    /// expire, the budget admits what it allows, and cloud requests unanswered for `retry_nanos` by this
    /// robot's clock are sent again (the request or the reply was lost, or the peer was away). Each
    /// retry doubles the wait (up to 16 periods), so replies queued on a slow link are not answered by
    /// ever more copies. Deterministic in scan time, so the executors still agree.
    pub fn loop_upkeep(
        &mut self,
        config: &ResolvedConfig,
        retry_nanos: u64,
    ) -> Result<Vec<Message>, RuntimeError> {
        let now_nanos = self.now_nanos();
        let expiry_nanos = budget(config).expiry_nanos;
        let expired = self.peer_clouds.expire(now_nanos, expiry_nanos);
        self.candidates.count_expired(expired);
        let mut outbox = Vec::new();
        self.admit_candidates(config, &mut outbox)?;
        let robot = self.robot;
        let due = self.peer_clouds.due(now_nanos, retry_nanos);
        outbox.extend(due.into_iter().map(|id| cloud_request(robot, id)));
        outbox.extend(self.restatements(now_nanos));
        Ok(outbox)
    }
}
