//! Incremental (distributed) mode: each robot has its own verifier and back-end and learns its own
//! measurements in stamp order; accepted loops are shared as `skid run` shares them, and each robot's
//! frames of the robots it merged with reach the others as `Frames` messages would (again only once
//! they moved), whereupon every verifier re-judges its loops against the frames through third robots.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Instant;

use skid_core::slots::{GraphView, LoopClosure, OptimizeBudget, Verdict, Verifier};
use skid_core::{LoopId, PluginResult, RobotId};

use super::{
    Graph, Known, LoopFate, PluginFactory, ReplayMode, ReplayOutcome, RobotGraph, apply_to_fates,
    own_estimate, plugin_error, submit, weigh,
};
use crate::ReplayError;
use crate::frames::{FrameTables, VerifierView, worth_reporting};
use crate::problem::{Item, ReplayProblem};

pub(super) fn incremental(
    problem: &ReplayProblem,
    factory: &dyn PluginFactory,
    budget: OptimizeBudget,
) -> Result<ReplayOutcome, ReplayError> {
    let mut robots = Robots::new(problem.robots.len(), factory)?;
    let mut known = Known::default();
    let mut fates: BTreeMap<LoopId, LoopFate> = BTreeMap::new();
    let mut closures: BTreeMap<LoopId, LoopClosure> = BTreeMap::new();
    let mut update_ms = Vec::with_capacity(problem.events.len());
    let mut slowest_robot_update_ms = Vec::with_capacity(problem.events.len());
    for event in &problem.events {
        let robot = event.robot;
        let fail = |error| plugin_error(robot, error);
        let started = Instant::now();
        // Each robot's own work in this event, in milliseconds (`None`: it did nothing).
        let mut robot_ms: Vec<Option<f64>> = vec![None; robots.graphs.len()];
        for item in &event.items {
            known.learn(item);
            match item {
                Item::Keyframe { .. } => {}
                Item::Odometry { measurement, .. } => {
                    for graph in &mut robots.graphs {
                        graph.add_keyframe(measurement.source, &known).map_err(fail)?;
                    }
                }
                Item::Prior { id, .. } => {
                    for graph in &mut robots.graphs {
                        graph.add_keyframe(*id, &known).map_err(fail)?;
                    }
                }
                Item::Loop { closure, label } => {
                    closures.insert(closure.id, closure.clone());
                    let fate = fates.entry(closure.id).or_default();
                    if !label.potential_outlier {
                        // A known inlier is not submitted.
                        fate.accepted = true;
                        let mut sharing = robots.sharing(&closures, &known, &mut robot_ms);
                        sharing.share_accepted(closure).map_err(fail)?;
                        continue;
                    }
                    fate.undecided = true;
                    let judged = Instant::now();
                    let verdict = robots
                        .ask(robot, &known, |verifier, view| submit(verifier, closure, view))
                        .map_err(fail)?;
                    add_ms(&mut robot_ms, robot, judged);
                    apply_to_fates(&mut fates, &verdict);
                    let mut sharing = robots.sharing(&closures, &known, &mut robot_ms);
                    sharing.apply(&verdict).map_err(fail)?;
                }
            }
        }
        optimize_changed(&mut robots.graphs, &known, budget, &mut robot_ms).map_err(fail)?;
        // Frames that moved reach the other robots, whose verifiers re-judge their loops against the
        // cycles through third robots; what that changes is solved at once.
        if robots.report_moved_frames() {
            for me in (0..robots.graphs.len() as u32).map(RobotId) {
                let fail = |error| plugin_error(me, error);
                let judged = Instant::now();
                let verdict = robots
                    .ask(me, &known, |verifier, view| verifier.reconsider(view))
                    .map_err(fail)?;
                add_ms(&mut robot_ms, me, judged);
                apply_to_fates(&mut fates, &verdict);
                let mut sharing = robots.sharing(&closures, &known, &mut robot_ms);
                sharing.apply(&verdict).map_err(fail)?;
            }
            optimize_changed(&mut robots.graphs, &known, budget, &mut robot_ms).map_err(fail)?;
        }
        update_ms.push(started.elapsed().as_secs_f64() * 1e3);
        // The robots work on their own computers at once: the update is done when the slowest is.
        slowest_robot_update_ms.push(robot_ms.into_iter().flatten().fold(0.0, f64::max));
    }
    let graphs = robots.graphs;
    weigh(&mut fates, &graphs);
    let snapshots: Vec<RobotGraph> = graphs.iter().map(|graph| graph.snapshot(&known)).collect();
    let estimates = snapshots
        .iter()
        .enumerate()
        .map(|(robot, snapshot)| own_estimate(snapshot, RobotId(robot as u32)))
        .collect();
    Ok(ReplayOutcome {
        mode: ReplayMode::Incremental,
        estimates,
        graphs: snapshots,
        loops: fates,
        total_s: update_ms.iter().sum::<f64>() * 1e-3,
        update_ms,
        slowest_robot_update_ms,
    })
}

/// Every robot's back-end and verifiers, and the frames each last reported.
struct Robots {
    graphs: Vec<Graph>,
    verifiers: Vec<Box<dyn Verifier>>,
    /// Empty without `fleet_loops`.
    fleet_verifiers: Vec<FleetVerifier>,
    reported: FrameTables,
}

impl Robots {
    fn new(count: usize, factory: &dyn PluginFactory) -> Result<Self, ReplayError> {
        let mut robots = Self {
            graphs: Vec::new(),
            verifiers: Vec::new(),
            fleet_verifiers: Vec::new(),
            reported: FrameTables::new(),
        };
        for robot in (0..count as u32).map(RobotId) {
            let fail = |error| plugin_error(robot, error);
            robots
                .graphs
                .push(Graph::new(factory.backend(robot).map_err(fail)?, [robot]));
            robots.verifiers.push(factory.verifier(robot).map_err(fail)?);
            if factory.fleet_loops() {
                robots.fleet_verifiers.push(FleetVerifier {
                    verifier: factory.verifier(robot).map_err(fail)?,
                    submitted: BTreeSet::new(),
                    accepted: BTreeSet::new(),
                });
            }
        }
        Ok(robots)
    }

    /// Asks `robot`'s own verifier through the view its host would give it: the chains, its back-end's
    /// poses and the frames reported so far.
    fn ask(
        &mut self,
        robot: RobotId,
        known: &Known,
        ask: impl FnOnce(&mut dyn Verifier, &dyn GraphView) -> PluginResult<Verdict>,
    ) -> PluginResult<Verdict> {
        let index = robot.0 as usize;
        let view = VerifierView {
            chains: &known.chains,
            backend: Some(self.graphs[index].backend.graph()),
            tables: &self.reported,
            me: Some(robot),
        };
        ask(self.verifiers[index].as_mut(), &view)
    }

    /// What sharing a verdict touches.
    fn sharing<'a>(
        &'a mut self,
        closures: &'a BTreeMap<LoopId, LoopClosure>,
        known: &'a Known,
        robot_ms: &'a mut [Option<f64>],
    ) -> Sharing<'a> {
        Sharing {
            graphs: &mut self.graphs,
            fleet_verifiers: &mut self.fleet_verifiers,
            closures,
            known,
            robot_ms,
        }
    }

    /// Updates each robot's reported frames where they moved enough to be sent again; returns whether
    /// any did.
    fn report_moved_frames(&mut self) -> bool {
        let mut moved = false;
        for (index, graph) in self.graphs.iter().enumerate() {
            let robot = RobotId(index as u32);
            let now = graph.merged_frames(robot);
            if worth_reporting(self.reported.get(&robot), &now) {
                self.reported.insert(robot, now);
                moved = true;
            }
        }
        moved
    }
}

/// Every graph that changed adds the deferred loops whose keyframes arrived and optimises.
fn optimize_changed(
    graphs: &mut [Graph],
    known: &Known,
    budget: OptimizeBudget,
    robot_ms: &mut [Option<f64>],
) -> PluginResult<()> {
    for (index, graph) in graphs.iter_mut().enumerate() {
        let optimised = Instant::now();
        graph.retry_deferred(known)?;
        if graph.optimize_if_changed(budget)? {
            add_ms(robot_ms, RobotId(index as u32), optimised);
        }
    }
    Ok(())
}

/// What sharing a robot's verdict with the fleet touches.
struct Sharing<'a> {
    graphs: &'a mut [Graph],
    fleet_verifiers: &'a mut [FleetVerifier],
    closures: &'a BTreeMap<LoopId, LoopClosure>,
    known: &'a Known,
    robot_ms: &'a mut [Option<f64>],
}

impl Sharing<'_> {
    /// A robot's own verdict: the loops it retracts leave every graph, those it accepts are shared.
    fn apply(&mut self, verdict: &Verdict) -> PluginResult<()> {
        for id in &verdict.retracted {
            for graph in self.graphs.iter_mut() {
                graph.remove_loop(*id)?;
            }
        }
        for id in &verdict.accepted {
            if let Some(closure) = self.closures.get(id) {
                self.share_accepted(closure)?;
            }
        }
        Ok(())
    }

    /// An accepted loop enters the graphs of the robots it joins (one for an intra-robot loop) and goes
    /// to every other robot (`fleet_loops`; none when `fleet_verifiers` is empty): each judges it with
    /// its fleet verifier, and the loops that verifier accepts (this one, or earlier ones it now
    /// decides) enter its graph, those it refuses or withdraws leave it.
    fn share_accepted(&mut self, closure: &LoopClosure) -> PluginResult<()> {
        let known = self.known;
        let ends: BTreeSet<RobotId> = [closure.target.robot, closure.source.robot].into();
        for end in ends {
            if let Some(graph) = self.graphs.get_mut(end.0 as usize)
                && !graph.loops.contains_key(&closure.id)
                && !graph.deferred.contains_key(&closure.id)
            {
                graph.add_loop(closure, known)?;
            }
        }
        for (robot, (graph, fleet)) in self
            .graphs
            .iter_mut()
            .zip(self.fleet_verifiers.iter_mut())
            .enumerate()
        {
            let robot = RobotId(robot as u32);
            if closure.target.robot == robot || closure.source.robot == robot {
                continue;
            }
            let mut entering = Vec::new();
            if fleet.submitted.insert(closure.id) {
                let judged = Instant::now();
                let view = VerifierView {
                    chains: &known.chains,
                    backend: Some(graph.backend.graph()),
                    tables: &FrameTables::new(),
                    me: Some(robot),
                };
                let verdict = submit(fleet.verifier.as_mut(), closure, &view)?;
                add_ms(self.robot_ms, robot, judged);
                let refused = verdict
                    .retracted
                    .iter()
                    .chain(verdict.rejected.iter().map(|(id, _)| id));
                for id in refused {
                    fleet.accepted.remove(id);
                    graph.remove_loop(*id)?;
                }
                fleet.accepted.extend(verdict.accepted.iter().copied());
                entering = verdict.accepted;
            } else if fleet.accepted.contains(&closure.id) {
                // Accepted again by its finder after a retraction: this robot's verdict on it stands.
                entering.push(closure.id);
            }
            for id in &entering {
                if let Some(accepted) = self.closures.get(id)
                    && !graph.loops.contains_key(id)
                    && !graph.deferred.contains_key(id)
                {
                    graph.add_loop(accepted, known)?;
                }
            }
        }
        Ok(())
    }
}

/// Adds the time since `since` to `robot`'s work in this event.
fn add_ms(robot_ms: &mut [Option<f64>], robot: RobotId, since: Instant) {
    if let Some(ms) = robot_ms.get_mut(robot.0 as usize) {
        *ms = Some(ms.unwrap_or(0.0) + since.elapsed().as_secs_f64() * 1e3);
    }
}

/// A robot's verifier of the loops other robots found (`fleet_loops`), and what it was given and
/// accepted.
struct FleetVerifier {
    verifier: Box<dyn Verifier>,
    submitted: BTreeSet<LoopId>,
    accepted: BTreeSet<LoopId>,
}
