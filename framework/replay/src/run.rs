//! Replaying a problem through a verifier and a back-end, the plugins `skid run` uses, in one of two
//! modes:
//!
//! - **batch** ([`batch`]): one verifier and one back-end hold the whole problem (every robot's
//!   keyframes, odometry and priors); the loops are submitted in stamp order, the back-end optimises
//!   once at the end, and the verifier then re-judges its loops against the frames the solved graph
//!   holds through third robots.
//! - **incremental** (distributed, [`incremental`]): each robot has its own verifier and back-end and
//!   learns its own measurements in stamp order. A loop goes through the verifier of the robot whose
//!   list holds it (the one that found it); an accepted inter-robot loop reaches the other robot's
//!   back-end at once, with the finder's odometry chain when it is the first loop between them, and a
//!   retracted one leaves both, as `skid run` shares them. With `fleet_loops`, as `skid run` under
//!   `loops.fleet_loops`, every accepted loop (intra-robot ones too) also reaches every other robot,
//!   whose second verifier (the fleet's loops, pooled by robot pair) judges it on its pose before it
//!   enters that robot's back-end; a loop its finder retracts leaves every graph. Every robot's odometry
//!   is known to every verifier as it arrives (robots broadcast their chains), and each robot's frames
//!   of the robots it merged with reach the others once they move ([`crate::frames`]). After each event
//!   the back-ends it changed optimise; the time of the event, verifiers and back-ends together, is one
//!   update.
//!
//! The verifier judges a loop on its pose alone: a recorded problem has no clouds, so the candidates
//! carry none and cloud checks (PCM's truncated MSE) are skipped.

use std::collections::{BTreeMap, BTreeSet};

use skid_core::slots::{
    Backend, GraphView, LoopCandidate, LoopClosure, OdometryMeasurement, OptimizeBudget, RejectionKind,
    Verdict, Verifier,
};
use skid_core::{CloudView, Information, KeyframeId, LoopId, PluginError, PluginResult, Pose, RobotId};
use skid_geometry::OdometryChains;

use crate::ReplayError;
use crate::problem::{Item, ReplayProblem};

mod batch;
mod incremental;

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
    /// Why the verifier last refused it (`retracted` when it took back an acceptance).
    pub rejected_by: Option<RejectionKind>,
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
    /// Milliseconds of each update in the robot that spent the most on it (its verifiers and its
    /// back-end; incremental mode): the update's latency, as each robot runs on its own computer.
    pub slowest_robot_update_ms: Vec<f64>,
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
        ReplayMode::Batch => batch::batch(problem, factory, budget),
        ReplayMode::Incremental => incremental::incremental(problem, factory, budget),
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

fn submit(
    verifier: &mut dyn Verifier,
    closure: &LoopClosure,
    graph: &dyn GraphView,
) -> PluginResult<Verdict> {
    let candidate = LoopCandidate {
        closure: closure.clone(),
        target_cloud: CloudView::default(),
        source_cloud: CloudView::default(),
    };
    // The verifiers see the odometry chains known so far.
    verifier.submit(&candidate, graph)
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

    /// This graph's frames of the robots `me` holds accepted loops with ([`crate::frames`]).
    fn merged_frames(&self, me: RobotId) -> BTreeMap<RobotId, Pose> {
        let view = self.backend.graph();
        let first_pose = |robot: RobotId| {
            let from = KeyframeId { robot, index: 0 };
            let to = KeyframeId {
                robot,
                index: u32::MAX,
            };
            view.pose(*self.in_backend.range(from..=to).next()?)
        };
        crate::frames::merged_frames(me, first_pose, self.loops.values())
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

fn apply_to_fates(fates: &mut BTreeMap<LoopId, LoopFate>, verdict: &Verdict) {
    for id in &verdict.accepted {
        let fate = fates.entry(*id).or_default();
        fate.accepted = true;
        fate.undecided = false;
        fate.rejected_by = None;
    }
    let refused = verdict
        .retracted
        .iter()
        .map(|id| (id, RejectionKind::Retracted))
        .chain(
            verdict
                .rejected
                .iter()
                .map(|(id, reason)| (id, RejectionKind::of(reason))),
        );
    for (id, kind) in refused {
        let fate = fates.entry(*id).or_default();
        fate.accepted = false;
        fate.undecided = false;
        fate.rejected_by = Some(kind);
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
