//! Batch mode: one verifier and one back-end hold the whole problem; the loops are submitted in stamp
//! order, the back-end optimises once at the end, and the verifier then re-judges its loops against the
//! frames the solved graph holds through third robots.

use std::collections::BTreeMap;
use std::time::Instant;

use skid_core::slots::{LoopClosure, OptimizeBudget};
use skid_core::{LoopId, RobotId};

use super::{
    Graph, Known, LoopFate, PluginFactory, ReplayMode, ReplayOutcome, apply_to_fates, own_estimate,
    plugin_error, submit, weigh,
};
use crate::ReplayError;
use crate::frames::{FrameTables, VerifierView};
use crate::problem::{Item, ReplayProblem};

/// Rounds of re-judging against the solved graph's frames in batch mode: each may add loops that move
/// the frames the next one sees.
const BATCH_RECONSIDER_ROUNDS: usize = 3;

pub(super) fn batch(
    problem: &ReplayProblem,
    factory: &dyn PluginFactory,
    budget: OptimizeBudget,
) -> Result<ReplayOutcome, ReplayError> {
    let first = RobotId(0);
    let fail = |error| plugin_error(first, error);
    let robots = (0..problem.robots.len() as u32).map(RobotId);
    let mut graph = Graph::new(factory.backend(first).map_err(fail)?, robots);
    let mut verifier = factory.verifier(first).map_err(fail)?;
    let mut known = Known::default();
    let mut fates: BTreeMap<LoopId, LoopFate> = BTreeMap::new();
    let mut closures: BTreeMap<LoopId, LoopClosure> = BTreeMap::new();
    let started = Instant::now();
    for event in &problem.events {
        for item in &event.items {
            known.learn(item);
            match item {
                Item::Keyframe { .. } => {}
                Item::Odometry { measurement, .. } => {
                    graph.add_keyframe(measurement.source, &known).map_err(fail)?;
                }
                Item::Prior { id, .. } => graph.add_keyframe(*id, &known).map_err(fail)?,
                Item::Loop { closure, label } => {
                    closures.insert(closure.id, closure.clone());
                    let fate = fates.entry(closure.id).or_default();
                    if !label.potential_outlier {
                        fate.accepted = true;
                        continue;
                    }
                    fate.undecided = true;
                    let verdict = submit(verifier.as_mut(), closure, &known.chains).map_err(fail)?;
                    apply_to_fates(&mut fates, &verdict);
                }
            }
        }
    }
    for (id, fate) in &fates {
        if fate.accepted
            && let Some(closure) = closures.get(id)
        {
            graph.add_loop(closure, &known).map_err(fail)?;
        }
    }
    graph.changed = true;
    graph.optimize_if_changed(budget).map_err(fail)?;
    // Once the graph is solved, frames through third robots are known: the verifier re-judges its loops
    // against them (a pair that waited for more loops decides when a third robot confirms its frame), as
    // `skid run`'s verifier does when frames arrive, and the graph is solved again with what changed.
    for _ in 0..BATCH_RECONSIDER_ROUNDS {
        let tables: FrameTables = (0..problem.robots.len() as u32)
            .map(RobotId)
            .map(|robot| (robot, graph.merged_frames(robot)))
            .collect();
        let view = VerifierView {
            chains: &known.chains,
            backend: Some(graph.backend.graph()),
            tables: &tables,
            me: None,
        };
        let verdict = verifier.reconsider(&view).map_err(fail)?;
        if verdict.accepted.is_empty() && verdict.retracted.is_empty() {
            break;
        }
        apply_to_fates(&mut fates, &verdict);
        for id in &verdict.retracted {
            graph.remove_loop(*id).map_err(fail)?;
        }
        for id in &verdict.accepted {
            if let Some(closure) = closures.get(id) {
                graph.add_loop(closure, &known).map_err(fail)?;
            }
        }
        graph.optimize_if_changed(budget).map_err(fail)?;
    }
    let total_s = started.elapsed().as_secs_f64();
    weigh(&mut fates, std::slice::from_ref(&graph));
    let snapshot = graph.snapshot(&known);
    let estimates = (0..problem.robots.len())
        .map(|robot| own_estimate(&snapshot, RobotId(robot as u32)))
        .collect();
    Ok(ReplayOutcome {
        mode: ReplayMode::Batch,
        estimates,
        graphs: vec![snapshot],
        loops: fates,
        update_ms: vec![total_s * 1e3],
        slowest_robot_update_ms: vec![total_s * 1e3],
        total_s,
    })
}
