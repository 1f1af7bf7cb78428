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

use crate::clique::{Graph, extend_greedily, heuristic_clique, max_clique, max_clique_within};
use crate::consistency::{PcmLoop, squared_mahalanobis};
use crate::dense::consistent_core;
use crate::earned::{GrantRule, Withheld, agrees_with_cycle, judge};
use crate::lie::chi2_quantile;

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
    /// An inter-robot group whose frame is already known through a third robot decides once it holds
    /// this many loops, instead of `min_loops_before_decision`, when every one of them agrees with that
    /// frame (the cycle test above): the cycle is the evidence the extra loops would give. The pairwise
    /// test and the grant rules are unchanged. 0 turns it off.
    pub min_loops_with_cycle: usize,
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
            min_loops_with_cycle: 2,
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
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ParamError::at(
                    key,
                    format!("must be 0 (off) or positive, got {value}"),
                ));
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
            core_fraction: self.min_consistent_fraction,
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
}

impl Group {
    /// The loops this group accepts: its leading set, unless that is withheld.
    fn granted(&self) -> &[usize] {
        match self.withheld {
            Some(_) => &[],
            None => &self.clique,
        }
    }
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
    /// frames through third robots, say): returns the loops granted and withdrawn.
    pub fn reconsider(&mut self, graph: &dyn GraphView) -> (Vec<LoopId>, Vec<LoopId>) {
        let rule = self.params.grant_rule();
        let (mut accepted, mut retracted) = (Vec::new(), Vec::new());
        for (&(a, b), group) in &mut self.groups {
            if a == b || !group.decided {
                continue;
            }
            let before: BTreeSet<usize> = group.granted().iter().copied().collect();
            group.withheld = judge(&rule, &group.loops, &group.graph, &group.clique, graph);
            let after: BTreeSet<usize> = group.granted().iter().copied().collect();
            accepted.extend(after.difference(&before).map(|&k| group.loops[k].id));
            retracted.extend(before.difference(&after).map(|&k| group.loops[k].id));
        }
        (accepted, retracted)
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
            if squared_mahalanobis(&group.loops[u], &pcm_loop, graph).is_some_and(|d2| d2 <= self.threshold) {
                group.graph.add_edge(u, v);
            }
        }
        group.loops.push(pcm_loop);
        let before: BTreeSet<usize> = group.granted().iter().copied().collect();
        // The cycle is only asked about while the group would otherwise still wait.
        let waits = group.loops.len() < self.params.min_loops_before_decision.max(1);
        let early = || {
            let members: Vec<usize> = (0..group.loops.len()).collect();
            !intra
                && self.params.min_loops_with_cycle > 0
                && group.loops.len() >= self.params.min_loops_with_cycle
                && agrees_with_cycle(&self.params.grant_rule(), &group.loops, &members, graph)
        };
        if waits && !early() {
            return Ok(PcmUpdate {
                pending: true,
                group_size: group.loops.len(),
                exact: true,
                ..PcmUpdate::default()
            });
        }
        let budget = self.params.clique_search_budget;
        if self.params.min_consistent_fraction < 1.0 {
            group.clique = consistent_core(&group.graph, self.params.min_consistent_fraction);
            group.decided = true;
            group.exact = true;
        } else if group.decided {
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
        } else {
            match max_clique(&group.graph, budget) {
                Ok(found) => {
                    group.clique = found;
                    group.exact = true;
                }
                Err(_) => {
                    group.clique = heuristic_clique(&group.graph);
                    group.exact = false;
                }
            }
            group.decided = true;
        }
        group.withheld = match intra {
            true => None,
            false => judge(
                &self.params.grant_rule(),
                &group.loops,
                &group.graph,
                &group.clique,
                graph,
            ),
        };
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
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use skid_core::slots::{LoopClosure, RelativePose};
    use skid_core::{Information, KeyframeId, Pose, RobotId};

    /// Two robots on gentle curves with exact odometry of small covariance.
    struct Curves;

    fn truth(id: KeyframeId) -> Pose {
        let k = f64::from(id.index);
        Pose::new(
            Vector3::new(2.0 * k, 5.0 * f64::from(id.robot.0), 0.0),
            Vector3::new(0.0, 0.0, 0.03 * k),
        )
    }

    impl GraphView for Curves {
        fn pose(&self, id: KeyframeId) -> Option<Pose> {
            Some(truth(id))
        }
        fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
            (target.robot == source.robot).then(|| RelativePose {
                target_from_source: truth(target).inverse() * truth(source),
                covariance: Information::identity() * 1e-5 * f64::from(target.index.abs_diff(source.index)),
            })
        }
        fn keyframes(&self) -> Vec<KeyframeId> {
            Vec::new()
        }
        fn loops(&self) -> Vec<LoopClosure> {
            Vec::new()
        }
    }

    fn pcm_loop(id: u64, target: KeyframeId, source: KeyframeId, error: Pose) -> PcmLoop {
        aligned_loop(id, target, source, &Pose::identity(), error)
    }

    /// A loop measured as if robot 1's world were displaced by `world_error`, then perturbed by `error`.
    fn aligned_loop(
        id: u64,
        target: KeyframeId,
        source: KeyframeId,
        world_error: &Pose,
        error: Pose,
    ) -> PcmLoop {
        let closure = LoopClosure {
            id: LoopId(id),
            target,
            source,
            target_from_source: truth(target).inverse() * world_error * truth(source) * error,
            information: Information::identity() * 1e4,
        };
        PcmLoop::from_closure(&closure).unwrap()
    }

    #[test]
    fn a_consistent_wrong_pair_is_accepted_then_retracted() {
        // The classic rule: the largest set wins at once, however narrowly.
        let mut pcm = Pcm::new(PcmParams {
            min_loops_before_decision: 2,
            dominance_ratio: 0.0,
            ..PcmParams::default()
        })
        .unwrap();
        let k = KeyframeId::new;
        // Two wrong loops that agree with each other (both place robot 1 6 m too far along) come first.
        let offset = Pose::new(Vector3::new(6.0, 0.0, 0.0), Vector3::zeros());
        pcm.add(
            aligned_loop(1, k(0, 2), k(1, 2), &offset, Pose::identity()),
            &Curves,
        )
        .unwrap();
        let first = pcm
            .add(
                aligned_loop(2, k(0, 4), k(1, 4), &offset, Pose::identity()),
                &Curves,
            )
            .unwrap();
        assert_eq!(first.accepted, vec![LoopId(1), LoopId(2)]);
        // Three right loops outvote them: the clique changes and the wrong pair is retracted.
        let mut retracted = Vec::new();
        let mut accepted = BTreeSet::from([LoopId(1), LoopId(2)]);
        for (id, index) in [(3, 6), (4, 8), (5, 10)] {
            let update = pcm
                .add(pcm_loop(id, k(0, index), k(1, index), Pose::identity()), &Curves)
                .unwrap();
            assert!(update.exact);
            retracted.extend(update.retracted.iter().copied());
            accepted.extend(update.accepted.iter().copied());
            for r in &update.retracted {
                accepted.remove(r);
            }
        }
        assert_eq!(retracted, vec![LoopId(1), LoopId(2)]);
        assert_eq!(accepted, BTreeSet::from([LoopId(3), LoopId(4), LoopId(5)]));
        assert_eq!(pcm.accepted(), vec![LoopId(3), LoopId(4), LoopId(5)]);
        assert!(
            pcm.add(pcm_loop(5, k(0, 1), k(1, 1), Pose::identity()), &Curves)
                .is_err(),
            "duplicate id"
        );
    }

    /// Adds a loop and folds its update into `accepted`; returns the update.
    fn add_tracking(pcm: &mut Pcm, accepted: &mut BTreeSet<LoopId>, pcm_loop: PcmLoop) -> PcmUpdate {
        let update = pcm.add(pcm_loop, &Curves).unwrap();
        for id in &update.retracted {
            assert!(accepted.remove(id), "{id} retracted without being accepted");
        }
        accepted.extend(update.accepted.iter().copied());
        assert_eq!(pcm.accepted(), accepted.iter().copied().collect::<Vec<_>>());
        update
    }

    #[test]
    fn a_merge_waits_until_earned_is_withdrawn_when_contested_and_redone_in_the_stronger_frame() {
        let mut pcm = Pcm::new(PcmParams {
            min_loops_before_decision: 2,
            ..PcmParams::default()
        })
        .unwrap();
        let k = KeyframeId::new;
        let mut accepted = BTreeSet::new();
        // Four wrong loops that agree (robot 1 placed 6 m too far along), spread over 6 m on each robot.
        let offset = Pose::new(Vector3::new(6.0, 0.0, 0.0), Vector3::zeros());
        let wrong: Vec<LoopId> = (1..=4).map(LoopId).collect();
        for (id, index) in [(1, 2), (2, 4), (3, 6), (4, 5)] {
            add_tracking(
                &mut pcm,
                &mut accepted,
                aligned_loop(id, k(0, index), k(1, index), &offset, Pose::identity()),
            );
        }
        assert_eq!(
            accepted,
            wrong.iter().copied().collect(),
            "unrivalled and spread: granted"
        );
        // Right loops arrive further on. With three of them the wrong set no longer holds twice the
        // rival's loops: the merge is withdrawn.
        let mut withdrawn_at = None;
        let mut granted_at = None;
        for (n, index) in (10..=24).step_by(2).enumerate() {
            let id = 10 + n as u64;
            let update = add_tracking(
                &mut pcm,
                &mut accepted,
                pcm_loop(id, k(0, index), k(1, index), Pose::identity()),
            );
            if update.retracted == wrong && withdrawn_at.is_none() {
                withdrawn_at = Some(n + 1);
                assert!(update.withheld.is_some(), "{update:?}");
            }
            if !accepted.is_empty() && granted_at.is_none() && withdrawn_at.is_some() {
                granted_at = Some(n + 1);
            }
            assert!(
                accepted.iter().all(|id| id.0 >= 10) || accepted.iter().all(|id| id.0 < 10),
                "never two frames at once: {accepted:?}"
            );
        }
        assert_eq!(withdrawn_at, Some(3), "withdrawn once a rival holds three loops");
        assert_eq!(
            granted_at,
            Some(8),
            "redone once the right frame holds twice the wrong one's loops"
        );
        assert_eq!(accepted, (10..18).map(LoopId).collect());
    }

    /// [`Curves`] with a third robot that places robot 1 in robot 0's frame at `world_error`.
    struct CurvesWithThirdRobot(Pose);

    impl GraphView for CurvesWithThirdRobot {
        fn pose(&self, id: KeyframeId) -> Option<Pose> {
            Curves.pose(id)
        }
        fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
            Curves.odometry_between(target, source)
        }
        fn keyframes(&self) -> Vec<KeyframeId> {
            Vec::new()
        }
        fn loops(&self) -> Vec<LoopClosure> {
            Vec::new()
        }
        fn frames_through_others(&self, a: RobotId, b: RobotId) -> Vec<(RobotId, Pose)> {
            let first = |robot| truth(KeyframeId::new(robot, 0));
            assert_eq!((a, b), (RobotId(0), RobotId(1)));
            vec![(RobotId(2), first(0).inverse() * self.0 * first(1))]
        }
    }

    #[test]
    fn a_merge_that_disagrees_with_the_frame_through_a_third_robot_is_withdrawn() {
        let mut pcm = Pcm::new(PcmParams {
            min_loops_before_decision: 2,
            ..PcmParams::default()
        })
        .unwrap();
        let k = KeyframeId::new;
        // Wrong loops that agree (robot 1 placed 30 m off and turned 90°), spread and unrivalled.
        let wrong_world = Pose::new(Vector3::new(30.0, -4.0, 0.0), Vector3::z() * 1.5);
        for (id, index) in [(1, 2), (2, 6), (3, 10)] {
            pcm.add(
                aligned_loop(id, k(0, index), k(1, index), &wrong_world, Pose::identity()),
                &Curves,
            )
            .unwrap();
        }
        assert_eq!(pcm.accepted().len(), 3, "with no third robot the set is granted");
        // Robot 2 has merged with both and places robot 1 where it truly is: the set is withdrawn.
        let (accepted, retracted) = pcm.reconsider(&CurvesWithThirdRobot(Pose::identity()));
        assert!(accepted.is_empty());
        assert_eq!(retracted, vec![LoopId(1), LoopId(2), LoopId(3)]);
        assert!(pcm.accepted().is_empty());
        let update = pcm
            .add(
                aligned_loop(4, k(0, 14), k(1, 14), &wrong_world, Pose::identity()),
                &CurvesWithThirdRobot(Pose::identity()),
            )
            .unwrap();
        let reason = update.withheld.unwrap();
        assert!(reason.contains("through robot2"), "{reason}");
        // A third robot that agrees with the set (within tolerance) grants it again.
        let nearly = wrong_world * Pose::new(Vector3::new(1.0, 0.5, 0.0), Vector3::z() * 0.02);
        let (accepted, retracted) = pcm.reconsider(&CurvesWithThirdRobot(nearly));
        assert_eq!(accepted, vec![LoopId(1), LoopId(2), LoopId(3), LoopId(4)]);
        assert!(retracted.is_empty());
    }

    #[test]
    fn a_pair_whose_frame_a_third_robot_confirms_is_decided_with_fewer_loops() {
        let params = PcmParams {
            min_loops_before_decision: 5,
            ..PcmParams::default()
        };
        let k = KeyframeId::new;
        // Two true loops, 8 m apart on each robot, with robot 2 placing robot 1 where it truly is.
        let mut pcm = Pcm::new(params.clone()).unwrap();
        let confirmed = CurvesWithThirdRobot(Pose::identity());
        let first = pcm
            .add(pcm_loop(1, k(0, 2), k(1, 2), Pose::identity()), &confirmed)
            .unwrap();
        assert!(first.pending, "one loop never decides: {first:?}");
        pcm.add(pcm_loop(2, k(0, 10), k(1, 10), Pose::identity()), &confirmed)
            .unwrap();
        assert_eq!(pcm.accepted(), vec![LoopId(1), LoopId(2)]);
        // Without a third robot, or with one that places robot 1 elsewhere, the pair waits for five.
        for graph in [
            &Curves as &dyn GraphView,
            &CurvesWithThirdRobot(Pose::new(Vector3::new(30.0, 0.0, 0.0), Vector3::zeros())),
        ] {
            let mut pcm = Pcm::new(params.clone()).unwrap();
            for (id, index) in [(1, 2), (2, 10)] {
                let update = pcm
                    .add(pcm_loop(id, k(0, index), k(1, index), Pose::identity()), graph)
                    .unwrap();
                assert!(update.pending, "{update:?}");
            }
            assert!(pcm.accepted().is_empty());
        }
        // Off by default where it is asked to be.
        let mut pcm = Pcm::new(PcmParams {
            min_loops_with_cycle: 0,
            ..params
        })
        .unwrap();
        for (id, index) in [(1, 2), (2, 10)] {
            pcm.add(
                pcm_loop(id, k(0, index), k(1, index), Pose::identity()),
                &confirmed,
            )
            .unwrap();
        }
        assert!(pcm.accepted().is_empty());
    }

    #[test]
    fn loops_on_one_spot_do_not_merge_robots() {
        let mut pcm = Pcm::new(PcmParams {
            min_loops_before_decision: 2,
            ..PcmParams::default()
        })
        .unwrap();
        let k = KeyframeId::new;
        // Four consistent loops whose keyframes lie within 2 m on each robot.
        let mut last = None;
        for (id, (a, b)) in [(5, 5), (6, 5), (5, 6), (6, 6)].into_iter().enumerate() {
            last = Some(
                pcm.add(
                    pcm_loop(id as u64 + 1, k(0, a), k(1, b), Pose::identity()),
                    &Curves,
                )
                .unwrap(),
            );
        }
        let last = last.unwrap();
        assert!(pcm.accepted().is_empty());
        assert!(last.in_leading_set, "{last:?}");
        assert!(
            last.withheld
                .as_deref()
                .is_some_and(|reason| reason.contains("span only")),
            "{last:?}"
        );
        // A fifth loop 10 m away spreads the set: it is granted whole.
        let update = pcm
            .add(pcm_loop(9, k(0, 10), k(1, 10), Pose::identity()), &Curves)
            .unwrap();
        assert_eq!(update.withheld, None);
        assert_eq!(pcm.accepted().len(), 5);
    }

    #[test]
    fn intra_robot_loops_are_checked_in_their_own_group() {
        let mut pcm = Pcm::new(PcmParams {
            min_loops_before_decision: 3,
            ..PcmParams::default()
        })
        .unwrap();
        let k = KeyframeId::new;
        let wrong = Pose::new(Vector3::new(0.0, 3.0, 0.0), Vector3::new(0.0, 0.0, 0.5));
        let mut updates = Vec::new();
        for (id, a, b, error) in [
            (1, 0, 10, Pose::identity()),
            (2, 3, 12, wrong),
            (3, 5, 15, Pose::identity()),
            (4, 7, 18, Pose::identity()),
        ] {
            updates.push(pcm.add(pcm_loop(id, k(1, a), k(1, b), error), &Curves).unwrap());
        }
        assert!(updates[0].pending && updates[1].pending);
        assert_eq!(pcm.accepted(), vec![LoopId(1), LoopId(3), LoopId(4)]);
        // An inter-robot loop starts a separate group and waits for its own decision.
        let update = pcm
            .add(pcm_loop(5, k(0, 3), k(1, 3), Pose::identity()), &Curves)
            .unwrap();
        assert!(update.pending && update.group_size == 1);
    }

    #[test]
    fn the_incremental_clique_matches_a_full_solve() {
        // Random consistency outcomes: the incremental clique is always as large as a fresh exact one.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut group = Graph::new(0);
        let mut clique: Vec<usize> = Vec::new();
        for v in 0..40 {
            group.add_vertex();
            for u in 0..v {
                if next() % 100 < 70 {
                    group.add_edge(u, v);
                }
            }
            let kept: Vec<usize> = clique
                .iter()
                .copied()
                .filter(|&u| group.neighbours(v).contains(u))
                .collect();
            let mut seed = kept;
            seed.push(v);
            if seed.len() == clique.len() + 1 {
                clique = seed;
            } else if let Some(mut found) = max_clique_within(
                &group,
                group.neighbours(v),
                clique.len().saturating_sub(1),
                u64::MAX,
            )
            .unwrap()
            {
                found.push(v);
                clique = found;
            }
            assert!(group.is_clique(&clique));
            assert_eq!(
                clique.len(),
                max_clique(&group, u64::MAX).unwrap().len(),
                "after vertex {v}"
            );
        }
    }
}
