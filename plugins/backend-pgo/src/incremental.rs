//! What keeps the `pgo` back-end's cost per keyframe flat as a mission grows (issue #18): what the last
//! optimisation left behind, so that the next one does only the work that is new.
//!
//! - **Variables for what loops touch.** The subgraph holds of the own robot only the keyframes loops
//!   touch and the ends of its odometry segments, the chain between them composed into one factor
//!   ([`crate::own_chain`]), as it holds of the peers; so a solve costs in proportion to the loops, not
//!   to the keyframes of the mission.
//! - **Nothing new, nothing solved.** A keyframe of the robot's own enters the graph as a leaf, placed by
//!   its odometry from the optimised pose before it (the host's guess), where its one factor has zero
//!   residual: the optimum of the grown graph is the old optimum plus the new leaves. Until a loop is
//!   added or removed, or peer odometry changes inside a stretch the subgraph composes, the next
//!   optimisation only re-places the peers' keyframes (after a solve that converged).
//! - **Warm GNC.** New loops graduate from the last solution while the earlier loops keep their labels,
//!   with only the poses of their region free ([`crate::region`], `warm_region_hops`) and the whole graph
//!   refined once afterwards; then every loop is re-labelled at the nominal threshold
//!   ([`crate::gnc_warm::gnc_tls_warm`]); a loop the verifier retracted simply leaves the warm solve. A full GNC run (from the odometry, with the
//!   variance factor re-estimated) happens once the loops added and removed since the last full run
//!   number as many as the loops that run had, so its cost, which grows with the graph, is amortised
//!   to a constant per loop change however the verifier's verdicts come (additions only, or a set that
//!   turns over at a constant size); and, with `full_run_on_rejected_new_loop`, as soon as a warm run
//!   rejects a loop new since the last run, which the warm start's settled labels may be wrong about.

use std::collections::BTreeMap;

use skid_core::slots::OptimizeReport;
use skid_core::{LoopId, RobotId};

/// Fewer loops than this always get a full GNC run: a warm start needs an established consensus.
const MIN_LOOPS_FOR_WARM_START: usize = 8;

/// What the last optimisation left behind.
#[derive(Debug)]
pub struct Memory {
    /// Something the last solution does not account for: a loop added or removed, peer odometry inside
    /// a composed stretch, or a solve that did not converge.
    pub changed: bool,
    /// Each loop's label after the last GNC run (1 inlier, 0 outlier).
    pub labels: BTreeMap<LoopId, f64>,
    /// The threshold the last full GNC run graduated at (its variance factor applied).
    threshold_squared: Option<f64>,
    /// The number of loops at the last full GNC run.
    loops_at_full_run: usize,
    /// Loops added or removed since the last full GNC run.
    loop_changes_since_full_run: usize,
    /// The highest keyframe index of each peer that a loop touches: peer odometry up to there is
    /// composed into the subgraph.
    pub touched_up_to: BTreeMap<RobotId, u32>,
    /// The report of the last solve, returned again when nothing changed.
    pub last_report: OptimizeReport,
    /// The last keyframe of each peer placed from the subgraph: without a solve only later ones move.
    pub placed_through: BTreeMap<RobotId, u32>,
}

impl Default for Memory {
    fn default() -> Self {
        Self {
            changed: true,
            labels: BTreeMap::new(),
            threshold_squared: None,
            loops_at_full_run: 0,
            loop_changes_since_full_run: 0,
            touched_up_to: BTreeMap::new(),
            last_report: OptimizeReport::default(),
            placed_through: BTreeMap::new(),
        }
    }
}

impl Memory {
    /// The threshold a warm GNC start graduates at, or `None` when the next run must be a full one.
    pub fn warm_start_threshold(&self) -> Option<f64> {
        self.threshold_squared.filter(|_| {
            self.loops_at_full_run >= MIN_LOOPS_FOR_WARM_START
                && self.loop_changes_since_full_run < self.loops_at_full_run
        })
    }

    /// Records that a loop joined or left the graph.
    pub fn loop_changed(&mut self) {
        self.changed = true;
        self.loop_changes_since_full_run += 1;
    }

    /// Records a full GNC run over `loops` loops that graduated at `threshold_squared`.
    pub fn full_run(&mut self, loops: usize, threshold_squared: f64) {
        self.threshold_squared = Some(threshold_squared);
        self.loops_at_full_run = loops;
        self.loop_changes_since_full_run = 0;
    }

    /// The earlier label of each factor's loop (`None` for odometry and for loops new since).
    pub fn earlier_labels(&self, factor_loops: &[Option<LoopId>]) -> Vec<Option<f64>> {
        factor_loops
            .iter()
            .map(|id| id.and_then(|id| self.labels.get(&id).copied()))
            .collect()
    }

    /// Keeps the labels GNC gave each factor's loop.
    pub fn keep_labels(&mut self, factor_loops: &[Option<LoopId>], weights: &[f64]) {
        self.labels = factor_loops
            .iter()
            .zip(weights)
            .filter_map(|(id, weight)| id.map(|id| (id, *weight)))
            .collect();
    }

    /// Records that a loop touching `robot`'s keyframe `index` (a peer's) joined the graph.
    pub fn loop_touches_peer(&mut self, robot: RobotId, index: u32) {
        let up_to = self.touched_up_to.entry(robot).or_insert(index);
        *up_to = (*up_to).max(index);
    }

    /// Whether peer odometry into `robot`'s keyframe `index` falls inside a stretch the subgraph composes.
    pub fn inside_composed_stretch(&self, robot: RobotId, index: u32) -> bool {
        self.touched_up_to
            .get(&robot)
            .is_some_and(|up_to| index <= *up_to)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warm_starts_until_the_loops_changed_as_many_times_as_the_full_run_had_loops() {
        let mut memory = Memory::default();
        assert_eq!(memory.warm_start_threshold(), None, "no full run yet");
        memory.full_run(10, 16.8);
        for _ in 0..9 {
            memory.loop_changed();
        }
        assert_eq!(
            memory.warm_start_threshold(),
            Some(16.8),
            "9 changes after a run over 10 loops"
        );
        memory.loop_changed();
        assert_eq!(
            memory.warm_start_threshold(),
            None,
            "10 changes: additions and removals both count"
        );
        memory.full_run(12, 12.5);
        assert_eq!(
            memory.warm_start_threshold(),
            Some(12.5),
            "the new run's threshold"
        );
        memory.full_run(MIN_LOOPS_FOR_WARM_START - 1, 16.8);
        assert_eq!(
            memory.warm_start_threshold(),
            None,
            "too few loops for a consensus"
        );
    }

    #[test]
    fn peer_odometry_counts_only_inside_touched_stretches() {
        let mut memory = Memory::default();
        memory.loop_touches_peer(RobotId(1), 5);
        memory.loop_touches_peer(RobotId(1), 3);
        assert!(memory.inside_composed_stretch(RobotId(1), 5));
        assert!(!memory.inside_composed_stretch(RobotId(1), 6));
        assert!(!memory.inside_composed_stretch(RobotId(2), 0));
    }
}
