//! The loop-closure budget of one robot: inter-robot candidates wait here until the period's budget
//! admits them, best first, and leave when they wait too long. Swarm-SLAM (Lajoie et al., 2024) verifies
//! a fixed budget of candidates per period, first those that would connect a robot not yet connected;
//! the same order is kept here, then candidates whose peer cloud is already held or asked for (they
//! cost no new cloud on the link), then the closest descriptors. A candidate whose cloud must come from a
//! peer not heard from lately (out of range, or gone) stays queued rather than hold one of the few places
//! for candidates waiting on a cloud, which it would hold until it expired. Nothing here grows without
//! bound: the queue holds at most `capacity` candidates and pushes out its worst when full.

use skid_core::{KeyframeId, RobotId};

use super::peer_clouds::PendingCandidate;

/// An inter-robot candidate waiting for the budget.
#[derive(Clone, Copy, Debug)]
pub(crate) struct QueuedCandidate {
    pub candidate: PendingCandidate,
    /// The descriptor distance that raised it (smaller is closer).
    pub distance: f64,
    /// When it was raised, in the host's clock.
    pub raised_nanos: u64,
}

/// What the host knows when it ranks candidates.
pub(crate) trait CandidateRanking {
    /// Whether `robot` is already in this robot's frame (merged with, or joined through others).
    fn in_frame(&self, robot: RobotId) -> bool;
    /// Whether the cloud of `keyframe` is held or already asked for.
    fn cloud_known(&self, keyframe: KeyframeId) -> bool;
    /// Whether a message from `robot` arrived lately: a cloud asked of it now is likely to come.
    fn reachable(&self, robot: RobotId) -> bool;
}

/// The budget's settings, in the host's clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Budget {
    /// Candidates admitted per period, and the most that may wait for a peer's cloud at once.
    pub per_period: usize,
    pub period_nanos: u64,
    /// A candidate still queued, or still waiting for its cloud, this long after it was raised expires.
    pub expiry_nanos: u64,
    /// Most candidates queued.
    pub capacity: usize,
}

/// The queue and the period's remaining budget.
#[derive(Debug, Default)]
pub(crate) struct CandidateQueue {
    queued: Vec<QueuedCandidate>,
    period_start_nanos: Option<u64>,
    admitted_this_period: usize,
    admitted: usize,
    expired: usize,
}

impl CandidateQueue {
    /// Queues a candidate; when the queue is full, the worst queued candidate (this one included) is
    /// pushed out and counted as expired.
    pub(crate) fn push(
        &mut self,
        candidate: QueuedCandidate,
        budget: &Budget,
        ranking: &dyn CandidateRanking,
    ) {
        self.queued.push(candidate);
        if self.queued.len() > budget.capacity.max(1) {
            self.sort(ranking);
            self.queued.pop();
            self.expired += 1;
        }
    }

    /// Candidates queued now.
    pub(crate) fn len(&self) -> usize {
        self.queued.len()
    }

    /// Candidates admitted so far.
    pub(crate) fn admitted(&self) -> usize {
        self.admitted
    }

    /// Candidates that expired (in the queue or while waiting for a cloud) or were pushed out of a
    /// full queue.
    pub(crate) fn expired(&self) -> usize {
        self.expired
    }

    /// Counts candidates that expired elsewhere (waiting for their cloud).
    pub(crate) fn count_expired(&mut self, count: usize) {
        self.expired += count;
    }

    /// Drops queued candidates past their expiry, then admits the best ones the period's budget allows,
    /// with `waiting_for_clouds` candidates already holding a place.
    pub(crate) fn admit(
        &mut self,
        now_nanos: u64,
        waiting_for_clouds: usize,
        budget: &Budget,
        ranking: &dyn CandidateRanking,
    ) -> Vec<PendingCandidate> {
        let period_nanos = budget.period_nanos.max(1);
        let start = *self.period_start_nanos.get_or_insert(now_nanos);
        if now_nanos >= start + period_nanos {
            // Periods are aligned to the first one, so the budget does not drift with when steps come.
            let periods = (now_nanos - start) / period_nanos;
            self.period_start_nanos = Some(start + periods * period_nanos);
            self.admitted_this_period = 0;
        }
        let before = self.queued.len();
        self.queued
            .retain(|queued| now_nanos.saturating_sub(queued.raised_nanos) < budget.expiry_nanos);
        self.expired += before - self.queued.len();
        let free = budget
            .per_period
            .saturating_sub(self.admitted_this_period)
            .min(budget.per_period.saturating_sub(waiting_for_clouds));
        if free == 0 || self.queued.is_empty() {
            return Vec::new();
        }
        self.sort(ranking);
        // The best candidates that can be served now: their cloud is known, or its robot is reachable.
        let mut taken = Vec::new();
        self.queued.retain(|queued| {
            let target = queued.candidate.target;
            let servable = ranking.cloud_known(target) || ranking.reachable(target.robot);
            if taken.len() < free && servable {
                taken.push(queued.candidate);
                false
            } else {
                true
            }
        });
        self.admitted_this_period += taken.len();
        self.admitted += taken.len();
        taken
    }

    /// Best first: a robot not yet in this robot's frame, then a cloud already held or asked for, then
    /// the closer descriptor, then the older candidate.
    fn sort(&mut self, ranking: &dyn CandidateRanking) {
        self.queued.sort_by(|a, b| {
            let key = |q: &QueuedCandidate| {
                (
                    ranking.in_frame(q.candidate.target.robot),
                    !ranking.cloud_known(q.candidate.target),
                )
            };
            key(a)
                .cmp(&key(b))
                .then(a.distance.total_cmp(&b.distance))
                .then(a.raised_nanos.cmp(&b.raised_nanos))
        });
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use super::*;

    struct Known {
        in_frame: BTreeSet<u32>,
        clouds: BTreeSet<(u32, u32)>,
        unreachable: BTreeSet<u32>,
    }

    impl CandidateRanking for Known {
        fn in_frame(&self, robot: RobotId) -> bool {
            self.in_frame.contains(&robot.0)
        }
        fn cloud_known(&self, keyframe: KeyframeId) -> bool {
            self.clouds.contains(&(keyframe.robot.0, keyframe.index))
        }
        fn reachable(&self, robot: RobotId) -> bool {
            !self.unreachable.contains(&robot.0)
        }
    }

    fn queued(robot: u32, index: u32, distance: f64, raised_nanos: u64) -> QueuedCandidate {
        QueuedCandidate {
            candidate: PendingCandidate {
                target: KeyframeId {
                    robot: RobotId(robot),
                    index,
                },
                source: KeyframeId {
                    robot: RobotId(0),
                    index: 100,
                },
                yaw_hint_rad: None,
            },
            distance,
            raised_nanos,
        }
    }

    const SECOND: u64 = 1_000_000_000;

    fn budget() -> Budget {
        Budget {
            per_period: 2,
            period_nanos: SECOND,
            expiry_nanos: 10 * SECOND,
            capacity: 4,
        }
    }

    #[test]
    fn a_robot_not_yet_in_the_frame_comes_first_then_known_clouds_then_closer_descriptors() {
        let known = Known {
            in_frame: BTreeSet::from([1]),
            clouds: BTreeSet::from([(1, 5)]),
            unreachable: BTreeSet::new(),
        };
        let mut queue = CandidateQueue::default();
        // Robot 1 is in the frame; robot 2 is not.
        queue.push(queued(1, 9, 0.01, 0), &budget(), &known);
        queue.push(queued(1, 5, 0.04, 0), &budget(), &known);
        queue.push(queued(2, 3, 0.045, 0), &budget(), &known);
        let first = queue.admit(0, 0, &budget(), &known);
        let targets: Vec<_> = first.iter().map(|c| (c.target.robot.0, c.target.index)).collect();
        assert_eq!(targets, vec![(2, 3), (1, 5)]);
        // The period's budget is spent: nothing more until the next period.
        assert!(queue.admit(SECOND / 2, 0, &budget(), &known).is_empty());
        let next = queue.admit(SECOND, 0, &budget(), &known);
        assert_eq!(next.len(), 1);
        assert_eq!(next[0].target.index, 9);
        assert_eq!(queue.admitted(), 3);
    }

    #[test]
    fn candidates_waiting_for_clouds_hold_places_of_the_budget() {
        let known = Known {
            in_frame: BTreeSet::new(),
            clouds: BTreeSet::new(),
            unreachable: BTreeSet::new(),
        };
        let mut queue = CandidateQueue::default();
        for index in 0..3 {
            queue.push(queued(1, index, 0.01, 0), &budget(), &known);
        }
        assert_eq!(queue.admit(0, 1, &budget(), &known).len(), 1);
        assert!(queue.admit(5 * SECOND, 2, &budget(), &known).is_empty());
        assert_eq!(queue.admit(6 * SECOND, 0, &budget(), &known).len(), 2);
    }

    #[test]
    fn a_full_queue_pushes_out_its_worst_and_old_candidates_expire() {
        let known = Known {
            in_frame: BTreeSet::new(),
            clouds: BTreeSet::new(),
            unreachable: BTreeSet::new(),
        };
        let mut queue = CandidateQueue::default();
        for (index, distance) in [0.05, 0.01, 0.03, 0.02, 0.04].into_iter().enumerate() {
            queue.push(
                queued(1, index as u32, distance, index as u64 * SECOND),
                &budget(),
                &known,
            );
        }
        assert_eq!(queue.len(), 4);
        assert_eq!(queue.expired(), 1);
        // At 11.5 s the candidate raised at 1 s has waited too long (the one raised at 0 s was pushed
        // out); the ones raised at 2, 3 and 4 s are still queued.
        let admitted = queue.admit(11 * SECOND + SECOND / 2, 0, &budget(), &known);
        assert_eq!(queue.expired(), 2);
        let distances: Vec<_> = admitted.iter().map(|c| c.target.index).collect();
        assert_eq!(distances, vec![3, 2]);
        assert_eq!(queue.len(), 1);
    }

    #[test]
    fn a_candidate_of_an_unreachable_robot_waits_in_the_queue_unless_its_cloud_is_known() {
        let known = Known {
            in_frame: BTreeSet::new(),
            clouds: BTreeSet::from([(3, 7)]),
            unreachable: BTreeSet::from([3]),
        };
        let mut queue = CandidateQueue::default();
        queue.push(queued(3, 1, 0.01, 0), &budget(), &known);
        queue.push(queued(3, 7, 0.03, 0), &budget(), &known);
        queue.push(queued(1, 2, 0.04, 0), &budget(), &known);
        let admitted = queue.admit(0, 0, &budget(), &known);
        let targets: Vec<_> = admitted
            .iter()
            .map(|c| (c.target.robot.0, c.target.index))
            .collect();
        // Robot 3's first candidate is the closest, but its cloud would not come: it stays queued.
        assert_eq!(targets, vec![(3, 7), (1, 2)]);
        assert_eq!(queue.len(), 1);
    }
}
