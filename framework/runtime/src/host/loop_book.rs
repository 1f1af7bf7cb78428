//! The book of a robot's loops: every loop it registered and submitted to its verifier (with where each
//! stands now and why a refused one was refused), the loops its peers accepted with it, which keyframe
//! pairs were tried, and the counters of what became of every candidate.

use std::collections::{BTreeMap, BTreeSet};

use skid_core::slots::{LoopClosure, RejectionKind};
use skid_core::{Information, KeyframeId, LoopId, Pose};

/// What became of this robot's loop candidates. Every candidate ends in exactly one outcome, so the
/// candidates add up: `candidates_intra + candidates_inter` equals `repeated_pair + cloud_missing +
/// queued + expired + awaiting_cloud + coarse_invalid + coarse_ambiguous + fine_not_converged +
/// accepted_intra + accepted_inter + rejected + undecided` ([`LoopStats::outcomes`]). The accepted, rejected and undecided counts are the state at the
/// time of reading (a loop PCM retracts counts as rejected); the last three fields count events.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct LoopStats {
    pub candidates_intra: usize,
    pub candidates_inter: usize,
    /// The same keyframe pair had been registered before.
    pub repeated_pair: usize,
    /// A keyframe's cloud was not held (a peer keyframe whose cloud never came).
    pub cloud_missing: usize,
    /// Inter-robot candidates still queued for the budget (`loops.inter_robot_budget`).
    pub queued: usize,
    /// Inter-robot candidates that waited too long (queued, or for their cloud) or were pushed out of a
    /// full queue.
    pub expired: usize,
    /// Inter-robot candidates still waiting for the peer's cloud.
    pub awaiting_cloud: usize,
    /// The coarse registration found no valid alignment.
    pub coarse_invalid: usize,
    /// The coarse registration found a rival alignment nearly as strong as its best
    /// (`loops.ambiguous_rival_ratio`): a symmetric or repetitive place.
    pub coarse_ambiguous: usize,
    /// The fine registration did not converge.
    pub fine_not_converged: usize,
    /// In this robot's graph, found by this robot.
    pub accepted_intra: usize,
    pub accepted_inter: usize,
    /// Refused by the verifier (truncated MSE, free space or consistency), or accepted and later
    /// retracted.
    pub rejected: usize,
    /// `rejected` by the verifier's reason ([`RejectionKind`]), as the loops stand now.
    pub rejected_by: BTreeMap<&'static str, usize>,
    /// Submitted to the verifier, which has not decided yet (PCM waits for enough loops of a pair).
    pub undecided: usize,
    /// Events: inter-robot candidates the budget admitted to registration, coarse alignments judged
    /// invalid but refined anyway (`loops.refine_invalid_coarse`), loops retracted, and accepted loops
    /// received from peers.
    pub inter_admitted: usize,
    pub coarse_invalid_refined: usize,
    pub retracted: usize,
    pub received_from_peers: usize,
    /// Loops peers accepted with this robot that its own verifier has not let into its graph (yet, or
    /// ever): they are undecided, refused, or retracted here.
    pub peer_loops_held_back: usize,
    /// Of `candidates_inter`, those found when a peer's descriptor arrived (against own keyframes the
    /// peer had not seen when it looked for candidates), not by querying a new own keyframe.
    pub inter_on_arrival: usize,
    /// Loops peers found that do not join this robot, held under `loops.fleet_loops`, and of them those
    /// in its graph (both robots placed in it).
    pub fleet_loops_held: usize,
    pub fleet_loops_in_graph: usize,
}

impl LoopStats {
    /// The sum of the outcome counts, which equals the number of candidates.
    pub fn outcomes(&self) -> usize {
        self.repeated_pair
            + self.cloud_missing
            + self.queued
            + self.expired
            + self.awaiting_cloud
            + self.coarse_invalid
            + self.coarse_ambiguous
            + self.fine_not_converged
            + self.accepted_intra
            + self.accepted_inter
            + self.rejected
            + self.undecided
    }

    pub fn candidates(&self) -> usize {
        self.candidates_intra + self.candidates_inter
    }
}

/// The inter-robot candidates the budget holds, admitted or dropped, as they stand.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct BudgetFigures {
    pub queued: usize,
    pub expired: usize,
    pub admitted: usize,
    pub awaiting_cloud: usize,
}

/// Where one of this robot's own loops stands with the verifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopStanding {
    Accepted,
    Rejected,
    Undecided,
}

/// A candidate's end before the verifier, or an event, counted in [`LoopStats`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LoopEvent {
    IntraCandidate,
    InterCandidate,
    InterOnArrival,
    RepeatedPair,
    CloudMissing,
    CoarseInvalid,
    CoarseAmbiguous,
    CoarseInvalidRefined,
    FineNotConverged,
}

/// One of this robot's submitted loops as it stands, for the loop lines of the outputs.
pub struct StandingLoop<'a> {
    pub closure: &'a LoopClosure,
    pub standing: LoopStanding,
    /// Why the verifier refused or retracted it, when it stands rejected.
    pub reason: Option<&'a str>,
}

/// Every loop of one robot, with its standing.
#[derive(Debug, Default)]
pub(crate) struct LoopBook {
    /// The accepted loops: the ones in the back-end.
    accepted: BTreeMap<LoopId, LoopClosure>,
    /// Loops identified across robots by their keyframe pair.
    by_pair: BTreeMap<(KeyframeId, KeyframeId), LoopId>,
    next_id: u64,
    /// Submitted loops that are not (or no longer) accepted, kept because PCM may accept them later.
    unaccepted: BTreeMap<LoopId, LoopClosure>,
    /// Each loop this robot registered and submitted, with whether it is inter-robot.
    standing: BTreeMap<LoopId, (bool, LoopStanding)>,
    /// Why the verifier refused (or retracted) each loop that stands rejected.
    rejection_reasons: BTreeMap<LoopId, String>,
    /// The loops peers found and sent, judged by this robot's verifier like its own.
    from_peers: BTreeSet<LoopId>,
    /// Loops (peers' and its own against a peer's keyframe) waiting for the odometry that places their
    /// keyframes before they can be judged.
    awaiting_poses: BTreeSet<LoopId>,
    /// Event counters; [`LoopBook::stats`] completes them with the loops' current standing.
    counters: LoopStats,
}

impl LoopBook {
    pub(crate) fn count(&mut self, event: LoopEvent) {
        let counter = match event {
            LoopEvent::IntraCandidate => &mut self.counters.candidates_intra,
            LoopEvent::InterCandidate => &mut self.counters.candidates_inter,
            LoopEvent::InterOnArrival => &mut self.counters.inter_on_arrival,
            LoopEvent::RepeatedPair => &mut self.counters.repeated_pair,
            LoopEvent::CloudMissing => &mut self.counters.cloud_missing,
            LoopEvent::CoarseInvalid => &mut self.counters.coarse_invalid,
            LoopEvent::CoarseAmbiguous => &mut self.counters.coarse_ambiguous,
            LoopEvent::CoarseInvalidRefined => &mut self.counters.coarse_invalid_refined,
            LoopEvent::FineNotConverged => &mut self.counters.fine_not_converged,
        };
        *counter += 1;
    }

    /// Whether the keyframe pair (target, source) was registered before, here or by the peer.
    pub(crate) fn knows_pair(&self, pair: (KeyframeId, KeyframeId)) -> bool {
        self.by_pair.contains_key(&pair)
    }

    /// A new loop between the pair, with a fresh id; the pair counts as registered from now on.
    pub(crate) fn new_loop(
        &mut self,
        (target, source): (KeyframeId, KeyframeId),
        target_from_source: Pose,
        information: Information,
    ) -> LoopClosure {
        let id = LoopId(self.next_id);
        self.next_id += 1;
        self.by_pair.insert((target, source), id);
        LoopClosure {
            id,
            target,
            source,
            target_from_source,
            information,
        }
    }

    /// Records a loop of this robot's own as submitted to the verifier, not yet decided.
    pub(crate) fn submitted(&mut self, closure: LoopClosure) {
        self.standing
            .insert(closure.id, (closure.is_inter_robot(), LoopStanding::Undecided));
        self.unaccepted.insert(closure.id, closure);
    }

    fn set_standing(&mut self, id: LoopId, standing: LoopStanding) {
        if let Some((_, current)) = self.standing.get_mut(&id) {
            *current = standing;
        }
    }

    /// Records the verifier's refusal.
    pub(crate) fn rejected(&mut self, id: LoopId, reason: String) {
        self.set_standing(id, LoopStanding::Rejected);
        self.rejection_reasons.insert(id, reason);
    }

    /// Takes an accepted loop out of the graph's set; the verifier may accept it again later.
    pub(crate) fn retract(&mut self, id: LoopId) -> Option<LoopClosure> {
        let closure = self.accepted.remove(&id)?;
        self.counters.retracted += 1;
        self.rejected(id, "retracted: no longer consistent with the others".to_owned());
        self.unaccepted.insert(id, closure.clone());
        Some(closure)
    }

    /// A submitted loop the verifier accepted, to add to the graph; `None` when it is unknown or
    /// already accepted. [`LoopBook::accept`] records it once it is in.
    pub(crate) fn take_for_acceptance(&mut self, id: LoopId) -> Option<LoopClosure> {
        let closure = self.unaccepted.remove(&id)?;
        (!self.accepted.contains_key(&id)).then_some(closure)
    }

    /// Records a loop of this robot's own as accepted and in the graph.
    pub(crate) fn accept(&mut self, closure: LoopClosure) {
        self.set_standing(closure.id, LoopStanding::Accepted);
        self.rejection_reasons.remove(&closure.id);
        self.accepted.insert(closure.id, closure);
    }

    /// Records a loop a peer accepted with this robot, submitted to this robot's verifier: it enters
    /// the graph when the verifier accepts it, as this robot's own loops do.
    pub(crate) fn received(&mut self, closure: LoopClosure) {
        self.counters.received_from_peers += 1;
        self.from_peers.insert(closure.id);
        self.unaccepted.insert(closure.id, closure);
    }

    /// Holds a loop back until the odometry places both its keyframes.
    pub(crate) fn await_poses(&mut self, id: LoopId) {
        self.awaiting_poses.insert(id);
    }

    /// How many loops wait for odometry.
    pub(crate) fn awaiting_poses_count(&self) -> usize {
        self.awaiting_poses.len()
    }

    /// The loops that waited for odometry, to judge again (those that still cannot be wait again).
    pub(crate) fn take_awaiting_poses(&mut self) -> Vec<LoopClosure> {
        std::mem::take(&mut self.awaiting_poses)
            .into_iter()
            .filter_map(|id| self.unaccepted.get(&id).cloned())
            .collect()
    }

    /// Whether the loop is one a peer found.
    pub(crate) fn is_from_peer(&self, id: LoopId) -> bool {
        self.from_peers.contains(&id)
    }

    /// Forgets a loop the peer that found it retracted; its id when it was in the graph. A pair this
    /// robot found itself is not the peer's to retract.
    pub(crate) fn retract_from_peer(&mut self, pair: (KeyframeId, KeyframeId)) -> Option<LoopId> {
        let id = self.by_pair.get(&pair).copied()?;
        if !self.from_peers.contains(&id) {
            return None;
        }
        self.unaccepted.remove(&id);
        self.awaiting_poses.remove(&id);
        self.accepted.remove(&id)?;
        self.counters.retracted += 1;
        Some(id)
    }

    /// The loops in the graph.
    pub(crate) fn accepted(&self) -> &BTreeMap<LoopId, LoopClosure> {
        &self.accepted
    }

    /// This robot's submitted loops, each with its standing.
    pub(crate) fn standings(&self) -> impl Iterator<Item = StandingLoop<'_>> {
        self.standing.iter().filter_map(|(id, &(_, standing))| {
            let closure = self.accepted.get(id).or_else(|| self.unaccepted.get(id))?;
            Some(StandingLoop {
                closure,
                standing,
                reason: self.rejection_reasons.get(id).map(String::as_str),
            })
        })
    }

    /// The counters with the accepted, rejected and undecided counts as they stand now, completed by
    /// the budget's figures (queued, expired, admitted) and the candidates still waiting for a cloud.
    pub(crate) fn stats(&self, budget: BudgetFigures) -> LoopStats {
        let mut stats = self.counters.clone();
        for (id, (inter, standing)) in &self.standing {
            match (standing, inter) {
                (LoopStanding::Accepted, true) => stats.accepted_inter += 1,
                (LoopStanding::Accepted, false) => stats.accepted_intra += 1,
                (LoopStanding::Rejected, _) => {
                    stats.rejected += 1;
                    let kind = self
                        .rejection_reasons
                        .get(id)
                        .map_or(RejectionKind::Other, |reason| RejectionKind::of(reason));
                    *stats.rejected_by.entry(kind.key()).or_default() += 1;
                }
                (LoopStanding::Undecided, _) => stats.undecided += 1,
            }
        }
        stats.peer_loops_held_back = self
            .from_peers
            .iter()
            .filter(|id| !self.accepted.contains_key(id))
            .count();
        stats.awaiting_cloud = budget.awaiting_cloud;
        stats.queued = budget.queued;
        stats.expired = budget.expired;
        stats.inter_admitted = budget.admitted;
        stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_are_counted_by_the_reason_the_verifier_gave() {
        let mut book = LoopBook::default();
        let k = KeyframeId::new;
        let reasons = [
            "truncated MSE 0.4 m² > 0.25 m² (overlap 0.80)",
            "free space: 3.10 % of the 5120 points both scans see stand where the other saw through (> 0.50 %)",
            "PCM: not in the maximum consistent set (12 of 14 loops)",
            "keyframe robot1/kf9 is not in the graph",
            "odometry: the loop moves its keyframes 98.0 m from where the odometry puts them over 98.0 m of route (at most 26.5 m)",
            "peer unseen: the loop puts robot robot1 2.5 m from robot0/kf4's sensor at that moment, but 30 of the 31 rays towards it passed through (> 80 %)",
        ];
        for (index, reason) in reasons.iter().enumerate() {
            let closure = book.new_loop(
                (k(0, index as u32), k(1, 0)),
                Pose::identity(),
                Information::identity(),
            );
            book.submitted(closure.clone());
            book.rejected(closure.id, (*reason).to_owned());
        }
        let accepted = book.new_loop((k(0, 9), k(1, 1)), Pose::identity(), Information::identity());
        book.submitted(accepted.clone());
        let taken = book.take_for_acceptance(accepted.id).unwrap();
        book.accept(taken);
        book.retract(accepted.id).unwrap();
        let stats = book.stats(BudgetFigures::default());
        assert_eq!(stats.rejected, 7);
        let expected: BTreeMap<&str, usize> = [
            ("truncated_mse", 1),
            ("free_space", 1),
            ("consistency", 1),
            ("other", 1),
            ("odometry", 1),
            ("peer_unseen", 1),
            ("retracted", 1),
        ]
        .into_iter()
        .collect();
        assert_eq!(stats.rejected_by, expected);
        assert!(RejectionKind::of(reasons[1]).is_alignment_check());
        assert!(!RejectionKind::of(reasons[2]).is_alignment_check());
    }
}
