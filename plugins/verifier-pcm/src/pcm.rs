//! Pairwise consistency maximisation (PCM; Mangelson et al., ICRA 2018), incremental: loops are grouped
//! by robot pair (intra-robot loops form the group of their robot); each new loop is tested against every
//! loop of its group ([`crate::consistency`]), becoming a vertex of the group's consistency graph, and the
//! accepted set is a maximum clique of that graph ([`crate::clique`]).
//!
//! The accepted set is the maximum clique with `min_consistent_fraction = 1`; below 1 (the default) it is
//! the consistent core that peeling keeps ([`crate::dense`]), recomputed at each new loop. An inter-robot
//! group's set is accepted only once it is earned ([`crate::earned`]): spread over space and clearly
//! stronger than any rival frame hypothesis; until then its loops wait, and a set that stops dominating
//! is retracted.
//!
//! Incremental update of the clique: adding one vertex `v` raises the maximum clique size by at most one, so when the
//! current clique is exact it suffices to look for a clique of the current size inside `v`'s
//! neighbourhood; if there is one, it and `v` replace the current clique (and the loops it leaves out are
//! retracted), otherwise the current clique stays. Two cheap cases come first: `v` consistent with the
//! whole clique, or the clique's members consistent with `v` plus `v` extended greedily, reaching the
//! current size plus one. When the exact search exceeds its budget the clique is no longer guaranteed
//! maximum (reported as heuristic); later loops still grow it by the cheap cases.

use std::collections::{BTreeMap, BTreeSet};

use serde::{Deserialize, Serialize};
use skid_core::slots::GraphView;
use skid_core::{LoopId, ParamError, RobotId};

use crate::clique::{Graph, extend_greedily, heuristic_clique, induced, max_clique, max_clique_within};
use crate::consistency::{PcmLoop, squared_mahalanobis};
use crate::dense::consistent_core;
use crate::earned::{GrantRule, Judged, Unseen, Withheld, agrees_with_cycle, judge};
use crate::lie::chi2_quantile;
use crate::predicted::OverlapRule;
use crate::repeated::Repeats;

/// Parameters of PCM.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PcmParams {
    /// Two loops are consistent when the squared Mahalanobis norm of their cycle is below the χ²
    /// (6 degrees of freedom) quantile at this probability (0.99 gives 16.81).
    pub consistency_probability: f64,
    /// A group decides only once it holds this many loops (earlier loops wait, neither accepted nor
    /// rejected).
    pub min_loops_before_decision: usize,
    /// Search nodes the exact clique solver may visit per update before the heuristic takes over.
    pub clique_search_budget: u64,
    /// Verify intra-robot loops with PCM too (otherwise they are accepted after the fitness check).
    pub check_intra_robot: bool,
    /// Each accepted loop must be consistent with at least this fraction of the group's other accepted
    /// loops: 1 is the classic rule (a maximum clique, searched exactly within the budget); below 1 the
    /// set is peeled ([`crate::dense`]), so a true loop that fails the test with a few others by chance
    /// stays (real covariances give heavy-tailed test statistics). The default 0.8 is the largest that
    /// drops no more true loops than GNC-TLS alone on COSMO-Bench's real problems (0.9 drops 2–57 more).
    pub min_consistent_fraction: f64,
    /// An inter-robot set is granted (its loops accepted, the robots merged) only when, on each robot, the
    /// keyframes its loops join span at least this many metres ([`crate::earned`]). 0 turns it off.
    pub min_spread_m: f64,
    /// An inter-robot set is granted only when it holds at least this many times as many loops as the
    /// strongest rival frame hypothesis (the consistent core of the loops that disagree with it); a
    /// granted set that stops dominating is retracted. 0 turns it off.
    pub dominance_ratio: f64,
    /// Where a third robot has merged with both robots of an inter-robot set, the frame through it must
    /// agree with most of the set's loops within this distance (at each loop's place) and angle, or the
    /// set is not granted ([`crate::earned`]).
    pub cycle_tolerance_m: f64,
    pub cycle_tolerance_deg: f64,
    /// The cycle refutes a loop only beyond `cycle_tolerance_m` plus this fraction of the route from the
    /// loop's keyframes to each robot's nearest keyframe that an inter-robot loop in the graph ties
    /// (the frame through the third robot is fixed there; the odometry drifts away from it). The default
    /// 0.01 is the top of real LiDAR(-inertial) odometry's drift, 0.3–1 % of the path. The same allowance
    /// holds where the cycle vouches for a set (`min_loops_with_cycle`). 0 turns it off.
    pub cycle_drift_fraction: f64,
    /// An inter-robot set is not granted when two or more of its loops join keyframes recorded within
    /// `together_within_s` seconds of each other and measured within `together_within_m` metres: the
    /// robots would have stood in one place at one time ([`crate::earned`]). Either 0 turns it off; it is
    /// off by default because the simulator's missions drive robots through each other where they meet
    /// (its rendezvous and crossings put two robots in one place at one time, which the rule refuses).
    /// The aliasing benchmark turns it on at 1 s and 2 m.
    pub together_within_s: f64,
    pub together_within_m: f64,
    /// An inter-robot group whose frame is already known through a third robot decides once it holds
    /// this many loops, instead of `min_loops_before_decision`, when every one of them agrees with that
    /// frame (the cycle test above): the cycle is the evidence the extra loops would give. The pairwise
    /// test and the grant rules are unchanged. 0 turns it off.
    pub min_loops_with_cycle: usize,
    /// An inter-robot set is granted only while the keyframe pairs its frame puts within
    /// `predicted_overlap_m` of each other, farther than `predicted_beyond_m` from its loops' keyframes,
    /// look alike to the descriptor (within a candidate's distance) at least `min_alike_fraction` of the
    /// time, once there are `min_predicted_pairs` of them ([`crate::predicted`]): a look-alike stretch
    /// of two different places stops looking alike beyond it. `predicted_overlap_m = 0` turns it off.
    pub predicted_overlap_m: f64,
    pub predicted_beyond_m: f64,
    pub min_predicted_pairs: usize,
    pub min_alike_fraction: f64,
    /// A keyframe whose descriptor looks like one of its own robot's keyframes at least this many metres
    /// away (by odometry) shows a place that repeats ([`crate::repeated`]). An inter-robot set most of
    /// whose loops join such keyframes is granted only when at least `min_sightings` of its loops were
    /// sighted (each robot's body seen where the loop puts it, `[verifier.pcm.peer_seen]`), when its
    /// loops span `aliased_min_spread_m` on each robot, when every loop agrees with the frame through a
    /// third robot, or when its predictions (above) look alike at least `aliased_alike_fraction` of the
    /// time. 0 turns it off, the default: on the simulator's bland planetary terrain most keyframes look
    /// like another of their robot's keyframes at SOLiD's candidate distance, and with the rule on
    /// sixteen robots on the default mission joined robot 0's frame 8 of 15 instead of 15 of 15. The
    /// aliasing benchmark turns it on at 20 m.
    pub repeat_beyond_m: f64,
    pub aliased_min_spread_m: f64,
    pub min_sightings: usize,
    pub aliased_alike_fraction: f64,
    /// An inter-robot frame hypothesis is refuted for good when at least this many loops that the
    /// peer-visibility check refused (`[verifier.pcm.peer_seen]`: a scan shows the place empty where the
    /// loop puts the other robot) are each consistent with most of its loops: they imply its frame, so
    /// its frame puts the robot where the scans show nobody ([`crate::earned`]). 0 turns it off.
    pub min_unseen_loops: usize,
}

impl Default for PcmParams {
    fn default() -> Self {
        Self {
            consistency_probability: 0.99,
            min_loops_before_decision: 5,
            clique_search_budget: 2_000_000,
            check_intra_robot: true,
            min_consistent_fraction: 0.8,
            min_spread_m: 3.0,
            dominance_ratio: 2.0,
            cycle_tolerance_m: 5.0,
            cycle_tolerance_deg: 10.0,
            cycle_drift_fraction: 0.01,
            together_within_s: 0.0,
            together_within_m: 2.0,
            min_loops_with_cycle: 2,
            predicted_overlap_m: 3.0,
            predicted_beyond_m: 10.0,
            min_predicted_pairs: 10,
            min_alike_fraction: 0.3,
            repeat_beyond_m: 0.0,
            aliased_min_spread_m: 15.0,
            min_sightings: 1,
            aliased_alike_fraction: 0.6,
            min_unseen_loops: 2,
        }
    }
}

impl PcmParams {
    /// Checks that every value is usable; the error is at the offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        if !(self.consistency_probability > 0.0 && self.consistency_probability < 1.0) {
            return Err(ParamError::at(
                "consistency_probability",
                format!("must lie in (0, 1), got {}", self.consistency_probability),
            ));
        }
        if !(self.min_consistent_fraction > 0.0 && self.min_consistent_fraction <= 1.0) {
            return Err(ParamError::at(
                "min_consistent_fraction",
                format!("must lie in (0, 1], got {}", self.min_consistent_fraction),
            ));
        }
        for (value, key) in [
            (self.min_spread_m, "min_spread_m"),
            (self.dominance_ratio, "dominance_ratio"),
            (self.cycle_tolerance_m, "cycle_tolerance_m"),
            (self.cycle_tolerance_deg, "cycle_tolerance_deg"),
            (self.cycle_drift_fraction, "cycle_drift_fraction"),
            (self.together_within_s, "together_within_s"),
            (self.together_within_m, "together_within_m"),
            (self.predicted_overlap_m, "predicted_overlap_m"),
            (self.predicted_beyond_m, "predicted_beyond_m"),
            (self.repeat_beyond_m, "repeat_beyond_m"),
            (self.aliased_min_spread_m, "aliased_min_spread_m"),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ParamError::at(
                    key,
                    format!("must be 0 (off) or positive, got {value}"),
                ));
            }
        }
        for (value, key) in [
            (self.min_alike_fraction, "min_alike_fraction"),
            (self.aliased_alike_fraction, "aliased_alike_fraction"),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(ParamError::at(key, format!("must lie in [0, 1], got {value}")));
            }
        }
        Ok(())
    }

    fn grant_rule(&self) -> GrantRule {
        GrantRule {
            min_spread_m: self.min_spread_m,
            dominance_ratio: self.dominance_ratio,
            cycle_tolerance_m: self.cycle_tolerance_m,
            cycle_tolerance_rad: self.cycle_tolerance_deg.to_radians(),
            cycle_drift_fraction: self.cycle_drift_fraction,
            together_within_s: self.together_within_s,
            together_within_m: self.together_within_m,
            core_fraction: self.min_consistent_fraction,
            overlaps: OverlapRule {
                radius_m: self.predicted_overlap_m,
                beyond_m: self.predicted_beyond_m,
                min_pairs: self.min_predicted_pairs,
                min_alike_fraction: self.min_alike_fraction,
            },
            repeat_beyond_m: self.repeat_beyond_m,
            aliased_min_spread_m: self.aliased_min_spread_m,
            min_sightings: self.min_sightings,
            aliased_alike_fraction: self.aliased_alike_fraction,
            min_unseen_loops: self.min_unseen_loops,
        }
    }
}

/// The change one new loop caused.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PcmUpdate {
    /// Loops that entered the accepted set (the new loop among them when accepted).
    pub accepted: Vec<LoopId>,
    /// Loops that left it.
    pub retracted: Vec<LoopId>,
    /// True when the group has not decided yet.
    pub pending: bool,
    /// Size of the group's accepted clique and of the group.
    pub clique_size: usize,
    pub group_size: usize,
    /// False when the clique came from the heuristic.
    pub exact: bool,
    /// Why the group's leading inter-robot set is not granted ([`crate::earned`]), when it is not.
    pub withheld: Option<String>,
    /// True when the new loop belongs to the group's leading set (granted or not).
    pub in_leading_set: bool,
}

/// One robot pair's loops and consistency graph.
#[derive(Default)]
struct Group {
    loops: Vec<PcmLoop>,
    graph: Graph,
    clique: Vec<usize>,
    decided: bool,
    exact: bool,
    /// Why the leading set (`clique`) of an inter-robot group is not granted; `None` when it is.
    withheld: Option<Withheld>,
    /// Loops of frame hypotheses whose predictions failed ([`crate::predicted`]): left out of the
    /// leading set and of its rivals from then on.
    refuted: BTreeSet<usize>,
    /// Which of its loops' keyframes show places that repeat in their robot's map.
    repeats: Repeats,
    /// Loops the peer-visibility check refused, each with the loops of `loops` it is consistent with.
    unseen: Vec<Unseen>,
}

impl Group {
    /// The loops this group accepts: its leading set, unless that is withheld.
    fn granted(&self) -> &[usize] {
        match self.withheld {
            Some(_) => &[],
            None => &self.clique,
        }
    }

    /// The leading set among the loops not refuted, and whether it is exact.
    fn leading_without_refuted(&self, params: &PcmParams) -> (Vec<usize>, bool) {
        if self.refuted.is_empty() {
            return leading_set(&self.graph, params);
        }
        let kept: Vec<usize> = (0..self.loops.len())
            .filter(|k| !self.refuted.contains(k))
            .collect();
        let (local, exact) = leading_set(&induced(&self.graph, &kept), params);
        (local.into_iter().map(|i| kept[i]).collect(), exact)
    }

    /// Whether a group that holds fewer loops than `min_loops_before_decision` decides now: an
    /// inter-robot group with at least `min_loops_with_cycle` loops, every one of which agrees with the
    /// frame known through a third robot.
    fn decides_early(&self, params: &PcmParams, intra: bool, graph: &dyn GraphView) -> bool {
        let members: Vec<usize> = (0..self.loops.len()).collect();
        !intra
            && params.min_loops_with_cycle > 0
            && self.loops.len() >= params.min_loops_with_cycle
            && agrees_with_cycle(&params.grant_rule(), &self.loops, &members, graph)
    }

    /// Judges an inter-robot group's leading set; a set whose predictions fail, or whose frame puts a
    /// robot where scans show nobody, is refuted for good and
    /// the leading set of the loops left is judged in its place, so a wrong frame that outnumbers the
    /// right one does not hold it back.
    fn settle(&mut self, params: &PcmParams, graph: &dyn GraphView) {
        let rule = params.grant_rule();
        loop {
            let group = Judged {
                consistency: &self.graph,
                refuted: &self.refuted,
                repeats: &mut self.repeats,
                unseen: &self.unseen,
            };
            self.withheld = judge(&rule, &self.loops, &self.clique, group, graph);
            let Some(reason @ (Withheld::Unconfirmed { .. } | Withheld::Unseen { .. })) = &self.withheld
            else {
                return;
            };
            if self.clique.is_empty() {
                return;
            }
            tracing::debug!(
                loops = self.clique.len(),
                "PCM: a frame hypothesis is refuted for good: {reason}"
            );
            self.refuted.extend(self.clique.iter().copied());
            (self.clique, self.exact) = self.leading_without_refuted(params);
        }
    }
}

/// The leading set of a whole consistency graph, solved from scratch: the consistent core below a
/// `min_consistent_fraction` of 1, else the maximum clique (the heuristic's past the search budget, then
/// not exact).
fn leading_set(graph: &Graph, params: &PcmParams) -> (Vec<usize>, bool) {
    if params.min_consistent_fraction < 1.0 {
        return (consistent_core(graph, params.min_consistent_fraction), true);
    }
    match max_clique(graph, params.clique_search_budget) {
        Ok(found) => (found, true),
        Err(_) => (heuristic_clique(graph), false),
    }
}

/// PCM's pairwise test: the cycle of loops `a` and `b` is within the squared-Mahalanobis `threshold`.
fn consistent(a: &PcmLoop, b: &PcmLoop, graph: &dyn GraphView, threshold: f64) -> bool {
    squared_mahalanobis(a, b, graph).is_some_and(|d2| d2 <= threshold)
}

/// The incremental PCM state.
pub struct Pcm {
    params: PcmParams,
    threshold: f64,
    groups: BTreeMap<(RobotId, RobotId), Group>,
    known: BTreeSet<LoopId>,
}

impl Pcm {
    pub fn new(params: PcmParams) -> Result<Self, String> {
        params.validate().map_err(|error| error.to_string())?;
        Ok(Self::from_checked(params))
    }

    /// [`Pcm::new`] for parameters checked already (the registry checks them once, at load time).
    pub(crate) fn from_checked(params: PcmParams) -> Self {
        let threshold = chi2_quantile(6, params.consistency_probability);
        Self {
            params,
            threshold,
            groups: BTreeMap::new(),
            known: BTreeSet::new(),
        }
    }

    /// Whether a grant rule reads [`PcmLoop::sighted`] (the rule for places that repeat is on): the
    /// verifier marks sightings only then.
    pub fn reads_sightings(&self) -> bool {
        self.params.repeat_beyond_m > 0.0
    }

    /// The squared-Mahalanobis threshold in use.
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// Every loop currently accepted.
    pub fn accepted(&self) -> Vec<LoopId> {
        let mut ids: Vec<LoopId> = self
            .groups
            .values()
            .flat_map(|g| g.granted().iter().map(|&k| g.loops[k].id))
            .collect();
        ids.sort_unstable();
        ids
    }

    /// Re-judges every decided inter-robot group's leading set against the graph as it is now (new
    /// frames through third robots, say), and decides a waiting group whose loops all agree with a frame
    /// through a third robot that became known since its last loop (`min_loops_with_cycle`): returns
    /// the loops granted and withdrawn.
    pub fn reconsider(&mut self, graph: &dyn GraphView) -> (Vec<LoopId>, Vec<LoopId>) {
        let (mut accepted, mut retracted) = (Vec::new(), Vec::new());
        for (&(a, b), group) in &mut self.groups {
            if a == b {
                continue;
            }
            let before: BTreeSet<usize> = group.granted().iter().copied().collect();
            if !group.decided {
                if !group.decides_early(&self.params, false, graph) {
                    continue;
                }
                (group.clique, group.exact) = group.leading_without_refuted(&self.params);
                group.decided = true;
            }
            group.settle(&self.params, graph);
            let after: BTreeSet<usize> = group.granted().iter().copied().collect();
            let withdrawn: Vec<LoopId> = before.difference(&after).map(|&k| group.loops[k].id).collect();
            if let Some(reason) = group.withheld.as_ref().filter(|_| !withdrawn.is_empty()) {
                tracing::debug!(
                    robots = %format!("{a}-{b}"),
                    withdrawn = withdrawn.len(),
                    "PCM: a granted set is withdrawn on reconsideration: {reason}"
                );
            }
            accepted.extend(after.difference(&before).map(|&k| group.loops[k].id));
            retracted.extend(withdrawn);
        }
        (accepted, retracted)
    }

    /// Adds an inter-robot loop the peer-visibility check refused: it is never accepted, but it refutes
    /// the frame hypotheses it agrees with (`min_unseen_loops`). Returns the loops withdrawn when the
    /// group's granted set is refuted by it. The id of a loop [`Pcm::add`] took is an error; with the
    /// rule off, for an intra-robot loop, or for a loop kept already, nothing is kept.
    pub fn add_unseen(&mut self, pcm_loop: PcmLoop, graph: &dyn GraphView) -> Result<Vec<LoopId>, String> {
        if self.params.min_unseen_loops == 0 || pcm_loop.target.robot == pcm_loop.source.robot {
            return Ok(Vec::new());
        }
        if self.known.contains(&pcm_loop.id) {
            return Err(format!("{} was submitted before", pcm_loop.id));
        }
        let group = self.groups.entry(pcm_loop.group()).or_default();
        if group
            .unseen
            .iter()
            .any(|unseen| unseen.pcm_loop.id == pcm_loop.id)
        {
            return Ok(Vec::new());
        }
        let consistent_with = (0..group.loops.len())
            .filter(|&u| consistent(&group.loops[u], &pcm_loop, graph, self.threshold))
            .collect();
        group.unseen.push(Unseen {
            pcm_loop,
            consistent_with,
        });
        if !group.decided {
            return Ok(Vec::new());
        }
        let before: BTreeSet<usize> = group.granted().iter().copied().collect();
        group.settle(&self.params, graph);
        let after: BTreeSet<usize> = group.granted().iter().copied().collect();
        Ok(before.difference(&after).map(|&k| group.loops[k].id).collect())
    }

    /// Adds a loop and updates its group's clique. A loop id seen before is an error.
    pub fn add(&mut self, pcm_loop: PcmLoop, graph: &dyn GraphView) -> Result<PcmUpdate, String> {
        if !self.known.insert(pcm_loop.id) {
            return Err(format!("{} was submitted before", pcm_loop.id));
        }
        let intra = pcm_loop.target.robot == pcm_loop.source.robot;
        let group = self.groups.entry(pcm_loop.group()).or_default();
        if intra && !self.params.check_intra_robot {
            group.loops.push(pcm_loop);
            let v = group.graph.add_vertex();
            group.clique.push(v);
            group.decided = true;
            group.exact = true;
            let id = group.loops[v].id;
            return Ok(PcmUpdate {
                accepted: vec![id],
                clique_size: group.clique.len(),
                group_size: group.loops.len(),
                exact: true,
                ..PcmUpdate::default()
            });
        }
        let v = group.graph.add_vertex();
        for u in 0..v {
            if consistent(&group.loops[u], &pcm_loop, graph, self.threshold) {
                group.graph.add_edge(u, v);
            }
        }
        for unseen in &mut group.unseen {
            if consistent(&unseen.pcm_loop, &pcm_loop, graph, self.threshold) {
                unseen.consistent_with.insert(v);
            }
        }
        group.loops.push(pcm_loop);
        let before: BTreeSet<usize> = group.granted().iter().copied().collect();
        // The cycle is only asked about while the group would otherwise still wait.
        let waits = group.loops.len() < self.params.min_loops_before_decision.max(1);
        if waits && !group.decides_early(&self.params, intra, graph) {
            return Ok(PcmUpdate {
                pending: true,
                group_size: group.loops.len(),
                exact: true,
                ..PcmUpdate::default()
            });
        }
        let budget = self.params.clique_search_budget;
        let incremental =
            group.decided && group.refuted.is_empty() && self.params.min_consistent_fraction >= 1.0;
        if !incremental {
            (group.clique, group.exact) = group.leading_without_refuted(&self.params);
            group.decided = true;
        } else {
            // Adding `v` raises the maximum clique size by at most one, so a clique of the current size
            // plus one that contains `v` is a maximum clique.
            let target = group.clique.len() + 1;
            let kept: Vec<usize> = group
                .clique
                .iter()
                .copied()
                .filter(|&u| group.graph.neighbours(v).contains(u))
                .collect();
            let mut order: Vec<usize> = (0..group.graph.len()).collect();
            order.sort_by_key(|&u| (std::cmp::Reverse(group.graph.degree(u)), u));
            let mut seed = kept;
            seed.push(v);
            let greedy = if seed.len() == target {
                seed
            } else {
                extend_greedily(&group.graph, seed, &order)
            };
            if greedy.len() >= target {
                let mut found = greedy;
                found.sort_unstable();
                group.clique = found;
            } else if group.exact {
                let at_least = group.clique.len().saturating_sub(1);
                match max_clique_within(&group.graph, group.graph.neighbours(v), at_least, budget) {
                    Ok(Some(mut found)) => {
                        found.push(v);
                        found.sort_unstable();
                        group.clique = found;
                    }
                    Ok(None) => {}
                    Err(_) => group.exact = false,
                }
            }
        }
        match intra {
            true => group.withheld = None,
            false => group.settle(&self.params, graph),
        }
        let after: BTreeSet<usize> = group.granted().iter().copied().collect();
        Ok(PcmUpdate {
            withheld: group.withheld.as_ref().map(ToString::to_string),
            in_leading_set: group.clique.contains(&v),
            accepted: after.difference(&before).map(|&k| group.loops[k].id).collect(),
            retracted: before.difference(&after).map(|&k| group.loops[k].id).collect(),
            pending: false,
            clique_size: group.clique.len(),
            group_size: group.loops.len(),
            exact: group.exact,
        })
    }
}

#[cfg(test)]
mod tests;
