//! Pairwise consistency maximisation (PCM; Mangelson et al., ICRA 2018), incremental: loops are grouped
//! by robot pair (intra-robot loops form the group of their robot); each new loop is tested against every
//! loop of its group ([`crate::consistency`]), becoming a vertex of the group's consistency graph, and the
//! accepted set is a maximum clique of that graph ([`crate::clique`]).
//!
//! Incremental update: adding one vertex `v` raises the maximum clique size by at most one, so when the
//! current clique is exact it suffices to look for a clique of the current size inside `v`'s
//! neighbourhood; if there is one, it and `v` replace the current clique (and the loops it leaves out are
//! retracted), otherwise the current clique stays. When the exact search exceeds its budget the greedy
//! heuristic is used (and the next update searches the whole graph again).

use std::collections::{BTreeMap, BTreeSet};

use serde::{Deserialize, Serialize};
use skid_core::slots::GraphView;
use skid_core::{LoopId, RobotId};

use crate::clique::{Graph, heuristic_clique, max_clique, max_clique_within};
use crate::consistency::{PcmLoop, squared_mahalanobis};
use crate::lie::chi2_quantile;

/// Parameters of PCM.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
}

impl Default for PcmParams {
    fn default() -> Self {
        Self {
            consistency_probability: 0.99,
            min_loops_before_decision: 5,
            clique_search_budget: 2_000_000,
            check_intra_robot: true,
        }
    }
}

impl PcmParams {
    /// Checks that every value is usable.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.consistency_probability > 0.0 && self.consistency_probability < 1.0) {
            return Err(format!(
                "consistency_probability must lie in (0, 1), got {}",
                self.consistency_probability
            ));
        }
        Ok(())
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
}

/// One robot pair's loops and consistency graph.
#[derive(Default)]
struct Group {
    loops: Vec<PcmLoop>,
    graph: Graph,
    clique: Vec<usize>,
    decided: bool,
    exact: bool,
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
        params.validate()?;
        let threshold = chi2_quantile(6, params.consistency_probability);
        Ok(Self {
            params,
            threshold,
            groups: BTreeMap::new(),
            known: BTreeSet::new(),
        })
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
            .flat_map(|g| g.clique.iter().map(|&k| g.loops[k].id))
            .collect();
        ids.sort_unstable();
        ids
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
        let before: BTreeSet<usize> = group.clique.iter().copied().collect();
        if group.loops.len() < self.params.min_loops_before_decision.max(1) {
            return Ok(PcmUpdate {
                pending: true,
                group_size: group.loops.len(),
                exact: true,
                ..PcmUpdate::default()
            });
        }
        let budget = self.params.clique_search_budget;
        if group.decided && group.exact {
            let at_least = group.clique.len().saturating_sub(1);
            match max_clique_within(&group.graph, group.graph.neighbours(v), at_least, budget) {
                Ok(Some(mut found)) => {
                    found.push(v);
                    found.sort_unstable();
                    group.clique = found;
                }
                Ok(None) => {}
                Err(_) => {
                    let heuristic = heuristic_clique(&group.graph);
                    if heuristic.len() > group.clique.len() {
                        group.clique = heuristic;
                    }
                    group.exact = false;
                }
            }
        } else {
            match max_clique(&group.graph, budget) {
                Ok(found) => {
                    group.clique = found;
                    group.exact = true;
                }
                Err(_) => {
                    let heuristic = heuristic_clique(&group.graph);
                    if heuristic.len() > group.clique.len() || !group.decided {
                        group.clique = heuristic;
                    }
                    group.exact = false;
                }
            }
            group.decided = true;
        }
        let after: BTreeSet<usize> = group.clique.iter().copied().collect();
        Ok(PcmUpdate {
            accepted: after.difference(&before).map(|&k| group.loops[k].id).collect(),
            retracted: before.difference(&after).map(|&k| group.loops[k].id).collect(),
            pending: false,
            clique_size: group.clique.len(),
            group_size: group.loops.len(),
            exact: group.exact,
        })
    }
}
