//! Replaying a problem through a verifier and a back-end, the plugins `skid run` uses, in one of two
//! modes:
//!
//! - **batch**: one verifier and one back-end hold the whole problem (every robot's keyframes, odometry
//!   and priors); the loops are submitted in stamp order, and the back-end optimises once at the end.
//! - **incremental** (distributed): each robot has its own verifier and back-end and learns its own
//!   measurements in stamp order. A loop goes through the verifier of the robot whose list holds it (the
//!   one that found it); an accepted inter-robot loop reaches the other robot's back-end at once, with
//!   the finder's odometry chain when it is the first loop between them, and a retracted one leaves both,
//!   as `skid run` shares them. With `fleet_loops`, as `skid run` under `loops.fleet_loops`, every
//!   accepted loop (intra-robot ones too) also reaches every other robot, whose second verifier (the
//!   fleet's loops, pooled by robot pair) judges it on its pose before it enters that robot's back-end;
//!   a loop its finder retracts leaves every graph. Every robot's odometry is known to every verifier
//!   as it arrives (robots
//!   broadcast their chains). After each event the back-ends it changed optimise; the time of the event,
//!   verifier and back-ends together, is one update.
//!
//! The verifier judges a loop on its pose alone: a recorded problem has no clouds, so the candidates
//! carry none and cloud checks (PCM's truncated MSE) are skipped.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Instant;

use skid_core::slots::{
    Backend, LoopCandidate, LoopClosure, OdometryMeasurement, OptimizeBudget, Verdict, Verifier,
};
use skid_core::{CloudView, Information, KeyframeId, LoopId, PluginError, PluginResult, Pose, RobotId};
use skid_geometry::OdometryChains;

use crate::ReplayError;
use crate::problem::{Item, ReplayProblem};

/// How the problem is replayed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplayMode {
    Batch,
    Incremental,
}

/// Builds the plugin instances of one robot (batch mode asks once, for robot 0).
pub trait PluginFactory {
    fn verifier(&self, robot: RobotId) -> PluginResult<Box<dyn Verifier>>;
    fn backend(&self, robot: RobotId) -> PluginResult<Box<dyn Backend>>;
    /// Whether an accepted loop reaches every robot's back-end, not only those of the robots it joins
    /// (`loops.fleet_loops`).
    fn fleet_loops(&self) -> bool {
        false
    }
}

/// What became of one loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoopFate {
    /// The verifier accepted it (it was not submitted when the file marks it a known inlier).
    pub accepted: bool,
    /// The verifier had not decided at the end.
    pub undecided: bool,
    /// Graphs that hold it at the end, and of those, graphs whose robust solve gives it weight.
    pub held_in: u32,
    pub weighed_in: u32,
}

impl LoopFate {
    /// The loop moves some robot's estimate.
    pub fn kept(&self) -> bool {
        self.weighed_in > 0
    }
}

/// A robot's graph at the end: its keyframes at their optimised poses, the odometry and the loops it
/// holds (for writing it out).
#[derive(Clone, Debug, Default)]
pub struct RobotGraph {
    pub poses: BTreeMap<KeyframeId, Pose>,
    pub odometry: Vec<OdometryMeasurement>,
    pub loops: Vec<LoopClosure>,
}

/// The outcome of a replay.
#[derive(Clone, Debug)]
pub struct ReplayOutcome {
    pub mode: ReplayMode,
    /// Each robot's estimate of its own keyframes, by index (batch: from the one graph).
    pub estimates: Vec<BTreeMap<u32, Pose>>,
    /// Each graph at the end: one per robot, or the one graph in batch mode.
    pub graphs: Vec<RobotGraph>,
    pub loops: BTreeMap<LoopId, LoopFate>,
    /// Milliseconds of each update (batch: one, the whole solve): every robot's work for one event.
    pub update_ms: Vec<f64>,
    /// Milliseconds of each robot's own share of each update it took part in (its verifiers and its
    /// back-end; incremental mode): what one robot spends, as each runs on its own computer.
    pub robot_update_ms: Vec<f64>,
    /// Seconds in the plugins, all updates together.
    pub total_s: f64,
}

/// Replays `problem` in `mode` with plugins from `factory`, each optimisation within `budget`.
pub fn replay(
    problem: &ReplayProblem,
    mode: ReplayMode,
    factory: &dyn PluginFactory,
    budget: OptimizeBudget,
) -> Result<ReplayOutcome, ReplayError> {
    match mode {
        ReplayMode::Batch => batch(problem, factory, budget),
        ReplayMode::Incremental => incremental(problem, factory, budget),
    }
}

/// What every robot knows of every robot's odometry (chains are broadcast), for the verifiers.
#[derive(Default)]
struct Known {
    chains: OdometryChains,
    initial: BTreeMap<KeyframeId, Pose>,
    odometry: BTreeMap<KeyframeId, OdometryMeasurement>,
    priors: BTreeMap<KeyframeId, (Pose, Information)>,
}

impl Known {
    fn learn(&mut self, item: &Item) {
        match item {
            Item::Keyframe { id, initial } => {
                self.initial.insert(*id, *initial);
                self.chains.insert(*id, *initial, Information::zeros());
            }
            Item::Odometry {
                measurement,
                step_covariance,
            } => {
                let pose = self.initial.get(&measurement.source).copied().unwrap_or_else(|| {
                    self.chains
                        .pose(measurement.target)
                        .map_or(Pose::identity(), |pose| pose * measurement.target_from_source)
                });
                self.chains.insert(measurement.source, pose, **step_covariance);
                self.odometry.insert(measurement.source, (**measurement).clone());
            }
            Item::Prior {
                id,
                world_from_sensor,
                information,
            } => {
                self.priors.insert(*id, (*world_from_sensor, *information));
            }
            Item::Loop { .. } => {}
        }
    }
}

fn submit(verifier: &mut dyn Verifier, closure: &LoopClosure, known: &Known) -> PluginResult<Verdict> {
    let candidate = LoopCandidate {
        closure: closure.clone(),
        target_cloud: CloudView::default(),
        source_cloud: CloudView::default(),
    };
    // The verifiers see the odometry chains known so far.
    verifier.submit(&candidate, &known.chains)
}

/// One back-end and what it holds.
struct Graph {
    backend: Box<dyn Backend>,
    /// Robots whose keyframes it holds (its own robot from the start).
    robots: BTreeSet<RobotId>,
    in_backend: BTreeSet<KeyframeId>,
    loops: BTreeMap<LoopId, LoopClosure>,
    /// Loops waiting for a keyframe the back-end does not hold yet.
    deferred: BTreeMap<LoopId, LoopClosure>,
    changed: bool,
}

impl Graph {
    fn new(backend: Box<dyn Backend>, robots: impl IntoIterator<Item = RobotId>) -> Self {
        Self {
            backend,
            robots: robots.into_iter().collect(),
            in_backend: BTreeSet::new(),
            loops: BTreeMap::new(),
            deferred: BTreeMap::new(),
            changed: false,
        }
    }

    /// Adds a keyframe (placed after its predecessor by its odometry when the back-end holds both) and
    /// its odometry and prior, when known.
    fn add_keyframe(&mut self, id: KeyframeId, known: &Known) -> PluginResult<()> {
        if self.in_backend.contains(&id) || !self.robots.contains(&id.robot) {
            return Ok(());
        }
        let odometry = known.odometry.get(&id);
        if let Some(measurement) = odometry
            && !self.in_backend.contains(&measurement.target)
            && !known.odometry.contains_key(&measurement.target)
        {
            // The first keyframe of a chain that no prior introduced.
            self.add_keyframe(measurement.target, known)?;
        }
        let after = odometry.and_then(|measurement| {
            let previous = self.backend.graph().pose(measurement.target)?;
            Some(previous * measurement.target_from_source)
        });
        let Some(guess) = after.or_else(|| known.initial.get(&id).copied()) else {
            return Ok(());
        };
        self.backend.add_keyframe(id, guess)?;
        self.in_backend.insert(id);
        if let Some(measurement) = odometry
            && self.in_backend.contains(&measurement.target)
        {
            self.backend.add_odometry(measurement.clone())?;
        }
        if let Some((pose, information)) = known.priors.get(&id) {
            self.backend.add_prior(id, *pose, *information)?;
        }
        self.changed = true;
        Ok(())
    }

    /// Adds every keyframe of `robot` known so far, in order, the first time the graph meets it.
    fn add_robot(&mut self, robot: RobotId, known: &Known) -> PluginResult<()> {
        if !self.robots.insert(robot) {
            return Ok(());
        }
        for (index, _) in known.chains.chain(robot) {
            self.add_keyframe(KeyframeId { robot, index }, known)?;
        }
        Ok(())
    }

    /// Adds a loop, bringing in the robots it joins; it waits while a keyframe is missing.
    fn add_loop(&mut self, closure: &LoopClosure, known: &Known) -> PluginResult<()> {
        for end in [closure.target, closure.source] {
            self.add_robot(end.robot, known)?;
        }
        if [closure.target, closure.source]
            .iter()
            .all(|id| self.in_backend.contains(id))
        {
            self.backend.add_loop(closure.clone())?;
            self.loops.insert(closure.id, closure.clone());
            self.changed = true;
        } else {
            self.deferred.insert(closure.id, closure.clone());
        }
        Ok(())
    }

    fn remove_loop(&mut self, id: LoopId) -> PluginResult<()> {
        if self.deferred.remove(&id).is_none() && self.loops.remove(&id).is_some() {
            self.backend.remove_loop(id)?;
            self.changed = true;
        }
        Ok(())
    }

    /// Adds the deferred loops whose keyframes have arrived.
    fn retry_deferred(&mut self, known: &Known) -> PluginResult<()> {
        let ready: Vec<LoopClosure> = self
            .deferred
            .values()
            .filter(|closure| {
                [closure.target, closure.source]
                    .iter()
                    .all(|id| self.in_backend.contains(id))
            })
            .cloned()
            .collect();
        for closure in ready {
            self.deferred.remove(&closure.id);
            self.add_loop(&closure, known)?;
        }
        Ok(())
    }

    /// Optimises when the graph changed since the last time; returns whether it did.
    fn optimize_if_changed(&mut self, budget: OptimizeBudget) -> PluginResult<bool> {
        let changed = std::mem::take(&mut self.changed);
        if changed {
            self.backend.optimize(budget)?;
        }
        Ok(changed)
    }

    fn snapshot(&self, known: &Known) -> RobotGraph {
        let view = self.backend.graph();
        let poses: BTreeMap<KeyframeId, Pose> = self
            .in_backend
            .iter()
            .filter_map(|id| view.pose(*id).map(|pose| (*id, pose)))
            .collect();
        RobotGraph {
            odometry: poses
                .keys()
                .filter_map(|id| known.odometry.get(id))
                .filter(|measurement| poses.contains_key(&measurement.target))
                .cloned()
                .collect(),
            poses,
            loops: self.loops.values().cloned().collect(),
        }
    }
}

fn plugin_error(robot: RobotId, error: PluginError) -> ReplayError {
    ReplayError::Plugin { robot, source: error }
}

fn batch(
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
                    let verdict = submit(verifier.as_mut(), closure, &known).map_err(fail)?;
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
        robot_update_ms: vec![total_s * 1e3],
        total_s,
    })
}

fn incremental(
    problem: &ReplayProblem,
    factory: &dyn PluginFactory,
    budget: OptimizeBudget,
) -> Result<ReplayOutcome, ReplayError> {
    let mut graphs = Vec::new();
    let mut verifiers = Vec::new();
    let mut fleet_verifiers = Vec::new();
    let fleet = factory.fleet_loops();
    for robot in (0..problem.robots.len() as u32).map(RobotId) {
        let fail = |error| plugin_error(robot, error);
        graphs.push(Graph::new(factory.backend(robot).map_err(fail)?, [robot]));
        verifiers.push(factory.verifier(robot).map_err(fail)?);
        if fleet {
            fleet_verifiers.push(FleetVerifier {
                verifier: factory.verifier(robot).map_err(fail)?,
                submitted: BTreeSet::new(),
                accepted: BTreeSet::new(),
            });
        }
    }
    let mut known = Known::default();
    let mut fates: BTreeMap<LoopId, LoopFate> = BTreeMap::new();
    let mut closures: BTreeMap<LoopId, LoopClosure> = BTreeMap::new();
    let mut update_ms = Vec::with_capacity(problem.events.len());
    let mut robot_update_ms = Vec::with_capacity(problem.events.len());
    for event in &problem.events {
        let robot = event.robot;
        let fail = |error| plugin_error(robot, error);
        let started = Instant::now();
        // Each robot's own work in this event, in milliseconds (`None`: it did nothing).
        let mut robot_ms: Vec<Option<f64>> = vec![None; graphs.len()];
        for item in &event.items {
            known.learn(item);
            match item {
                Item::Keyframe { .. } => {}
                Item::Odometry { measurement, .. } => {
                    for graph in &mut graphs {
                        graph.add_keyframe(measurement.source, &known).map_err(fail)?;
                    }
                }
                Item::Prior { id, .. } => {
                    for graph in &mut graphs {
                        graph.add_keyframe(*id, &known).map_err(fail)?;
                    }
                }
                Item::Loop { closure, label } => {
                    closures.insert(closure.id, closure.clone());
                    let fate = fates.entry(closure.id).or_default();
                    let entering = if label.potential_outlier {
                        fate.undecided = true;
                        let verifier = &mut verifiers[robot.0 as usize];
                        let judged = Instant::now();
                        let verdict = submit(verifier.as_mut(), closure, &known).map_err(fail)?;
                        add_ms(&mut robot_ms, robot, judged);
                        apply_to_fates(&mut fates, &verdict);
                        for id in &verdict.retracted {
                            for graph in graphs.iter_mut() {
                                graph.remove_loop(*id).map_err(fail)?;
                            }
                        }
                        verdict.accepted
                    } else {
                        // A known inlier is not submitted.
                        fate.accepted = true;
                        vec![closure.id]
                    };
                    for id in &entering {
                        if let Some(closure) = closures.get(id) {
                            share_accepted(
                                &mut graphs,
                                &mut fleet_verifiers,
                                closure,
                                &closures,
                                &known,
                                &mut robot_ms,
                            )
                            .map_err(fail)?;
                        }
                    }
                }
            }
        }
        for (index, graph) in graphs.iter_mut().enumerate() {
            let optimised = Instant::now();
            graph.retry_deferred(&known).map_err(fail)?;
            if graph.optimize_if_changed(budget).map_err(fail)? {
                add_ms(&mut robot_ms, RobotId(index as u32), optimised);
            }
        }
        update_ms.push(started.elapsed().as_secs_f64() * 1e3);
        robot_update_ms.extend(robot_ms.into_iter().flatten());
    }
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
        robot_update_ms,
    })
}

/// An accepted loop enters the graphs of the robots it joins (one for an intra-robot loop).
fn share(graphs: &mut [Graph], closure: &LoopClosure, known: &Known) -> PluginResult<()> {
    let ends: BTreeSet<RobotId> = [closure.target.robot, closure.source.robot].into();
    for end in ends {
        if let Some(graph) = graphs.get_mut(end.0 as usize)
            && !graph.loops.contains_key(&closure.id)
            && !graph.deferred.contains_key(&closure.id)
        {
            graph.add_loop(closure, known)?;
        }
    }
    Ok(())
}

/// An accepted loop enters the graphs of the robots it joins ([`share`]) and goes to every other robot
/// (`fleet_loops`; none when `fleet_verifiers` is empty): each judges it with its fleet verifier, and
/// the loops that verifier accepts (this one, or earlier ones it now decides) enter its graph, those it
/// refuses or withdraws leave it.
fn share_accepted(
    graphs: &mut [Graph],
    fleet_verifiers: &mut [FleetVerifier],
    closure: &LoopClosure,
    closures: &BTreeMap<LoopId, LoopClosure>,
    known: &Known,
    robot_ms: &mut [Option<f64>],
) -> PluginResult<()> {
    share(graphs, closure, known)?;
    for (robot, (graph, fleet)) in graphs.iter_mut().zip(fleet_verifiers.iter_mut()).enumerate() {
        let robot = RobotId(robot as u32);
        if closure.target.robot == robot || closure.source.robot == robot {
            continue;
        }
        let mut entering = Vec::new();
        if fleet.submitted.insert(closure.id) {
            let judged = Instant::now();
            let verdict = submit(fleet.verifier.as_mut(), closure, known)?;
            add_ms(robot_ms, robot, judged);
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
            if let Some(accepted) = closures.get(id)
                && !graph.loops.contains_key(id)
                && !graph.deferred.contains_key(id)
            {
                graph.add_loop(accepted, known)?;
            }
        }
    }
    Ok(())
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

fn apply_to_fates(fates: &mut BTreeMap<LoopId, LoopFate>, verdict: &Verdict) {
    for id in &verdict.accepted {
        let fate = fates.entry(*id).or_default();
        fate.accepted = true;
        fate.undecided = false;
    }
    for id in verdict
        .retracted
        .iter()
        .chain(verdict.rejected.iter().map(|(id, _)| id))
    {
        let fate = fates.entry(*id).or_default();
        fate.accepted = false;
        fate.undecided = false;
    }
}

/// Counts, for each loop, the graphs that hold it and those that give it weight.
fn weigh(fates: &mut BTreeMap<LoopId, LoopFate>, graphs: &[Graph]) {
    for graph in graphs {
        let rejected: BTreeSet<LoopId> = graph.backend.rejected_loops().into_iter().collect();
        for id in graph.loops.keys() {
            let fate = fates.entry(*id).or_default();
            fate.held_in += 1;
            if !rejected.contains(id) {
                fate.weighed_in += 1;
            }
        }
    }
}

fn own_estimate(graph: &RobotGraph, robot: RobotId) -> BTreeMap<u32, Pose> {
    graph
        .poses
        .iter()
        .filter(|(id, _)| id.robot == robot)
        .map(|(id, pose)| (id.index, *pose))
        .collect()
}
