//! The `pgo` back-end plugin: keeps the keyframes, odometry and accepted loops it is given, and optimises
//! the robot's distributed pose graph ([`crate::distributed`]) by Levenberg-Marquardt ([`crate::lm`]) or
//! GNC-TLS ([`crate::gnc`]), reusing the symbolic factorisation while the topology stays the same.
//!
//! Conventions: odometry and loop information matrices weigh the residual `Log(Z⁻¹ T_t⁻¹ T_s)`
//! (translation first). [`GraphView::odometry_between`] reports the covariance of `target_from_source`
//! perturbed on the left, in the target keyframe's frame (as `skid_testkit::backend::ChainGraph`).

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use skid_core::slots::{
    Backend, GraphView, LoopClosure, OdometryMeasurement, OptimizeBudget, OptimizeReport, RelativePose,
};
use skid_core::{KeyframeId, LoopId, PluginContext, PluginError, PluginResult, Pose, RobotId};

use crate::chain::{Chains, Step};
use crate::distributed::{Prior, Scope, align_peers, build, write_back};
use crate::error::PgoError;
use crate::g2o_file::{Initialization, RobustMode};
use crate::gnc::{GncSettings, gnc_tls, strict_threshold};
use crate::gnc_warm::{WarmRegion, gnc_tls_warm};
use crate::group::PoseGroup;
use crate::incremental::Memory;
use crate::lm::{LmSettings, SystemCache, optimize};
use crate::problem::check_information;
use crate::robust::{Kernel, RobustLoss, chi2_quantile};

/// Parameters of the `pgo` back-end (`[backend.pgo]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PgoConfig {
    /// Robust loss on loop closures: none, huber, cauchy, tls or gnc (GNC-TLS).
    pub robust: RobustMode,
    /// Kernel width on the Mahalanobis norm; 0 = `√χ²₆` quantile at `inlier_probability`.
    pub robust_width: f64,
    pub inlier_probability: f64,
    /// Optimise only this robot's keyframes and the peer keyframes its loops touch (the paper's
    /// distributed form); off = every keyframe, odometry edge and loop (centralised).
    pub distributed: bool,
    /// `chordal`: start every optimisation from the chordal relaxation instead of the current estimate.
    pub init: Initialization,
    /// Stop when a step lowers the cost by less than this fraction.
    pub relative_tolerance: f64,
    /// With `robust = "gnc"`: a warm GNC run graduates new loops with only the poses within this many
    /// factors of their ends free, then refines the whole graph once ([`crate::region`]); 0 = graduate
    /// over the whole graph.
    pub warm_region_hops: usize,
    /// With `robust = "gnc"`: when a warm GNC run rejects a loop new since the last run, the labels are
    /// settled again by a full run. A new loop that disagrees with the last consensus is where that
    /// consensus may be wrong (on COSMO-Bench's real problems, the loops closing a route's start long
    /// after it drifted); off, the warm labels stand until the next scheduled full run.
    pub full_run_on_rejected_new_loop: bool,
}

impl Default for PgoConfig {
    fn default() -> Self {
        Self {
            robust: RobustMode::None,
            robust_width: 0.0,
            inlier_probability: 0.99,
            distributed: true,
            init: Initialization::File,
            relative_tolerance: 1e-6,
            warm_region_hops: 4,
            full_run_on_rejected_new_loop: true,
        }
    }
}

/// The plugin state.
pub struct PgoBackend {
    config: PgoConfig,
    own: RobotId,
    poses: BTreeMap<KeyframeId, Pose>,
    chains: Chains,
    loops: BTreeMap<LoopId, LoopClosure>,
    priors: BTreeMap<KeyframeId, Prior>,
    aligned: BTreeSet<RobotId>,
    cache: SystemCache<6>,
    kernel: Kernel,
    memory: Memory,
}

fn invalid(message: impl Into<String>) -> PluginError {
    PluginError::InvalidInput(message.into())
}

fn finite_pose(pose: &Pose) -> bool {
    <Pose as PoseGroup<6>>::is_finite(pose)
}

impl PgoBackend {
    pub fn new(config: PgoConfig, context: &PluginContext) -> PluginResult<Self> {
        if !(config.inlier_probability > 0.0 && config.inlier_probability < 1.0) {
            return Err(PluginError::failed(
                "pgo",
                "inlier_probability must lie in (0, 1)",
            ));
        }
        if !(config.relative_tolerance.is_finite() && config.relative_tolerance >= 0.0) {
            return Err(PluginError::failed(
                "pgo",
                "relative_tolerance must be finite and not negative",
            ));
        }
        let width = if config.robust_width > 0.0 {
            config.robust_width
        } else {
            chi2_quantile(6, config.inlier_probability).sqrt()
        };
        let loss = match config.robust {
            RobustMode::None => RobustLoss::None,
            RobustMode::Huber => RobustLoss::Huber,
            RobustMode::Cauchy => RobustLoss::Cauchy,
            RobustMode::Tls | RobustMode::Gnc => RobustLoss::Tls,
        };
        let kernel = Kernel::new(loss, width).map_err(|e| PluginError::failed("pgo", e))?;
        Ok(Self {
            config,
            own: context.robot,
            poses: BTreeMap::new(),
            chains: Chains::default(),
            loops: BTreeMap::new(),
            priors: BTreeMap::new(),
            aligned: BTreeSet::from([context.robot]),
            cache: SystemCache::default(),
            kernel,
            memory: Memory::default(),
        })
    }

    /// Checks a measurement between two known keyframes; returns its information, symmetrised.
    fn check_measurement(
        &self,
        what: &str,
        target: KeyframeId,
        source: KeyframeId,
        pose: &Pose,
        information: &skid_core::Information,
    ) -> PluginResult<skid_core::Information> {
        for id in [target, source] {
            if !self.poses.contains_key(&id) {
                return Err(invalid(format!(
                    "{what} {target} -> {source}: keyframe {id} is unknown"
                )));
            }
        }
        if target == source {
            return Err(invalid(format!(
                "{what} {target} -> {source} links a keyframe to itself"
            )));
        }
        if !finite_pose(pose) {
            return Err(invalid(format!(
                "{what} {target} -> {source}: the measured pose is not finite"
            )));
        }
        check_information(information)
            .map_err(|reason| invalid(format!("{what} {target} -> {source}: {reason}")))
    }

    fn scope(&self) -> Scope {
        if self.config.distributed {
            Scope::Distributed { own: self.own }
        } else {
            Scope::Full
        }
    }
}

impl Backend for PgoBackend {
    fn add_keyframe(&mut self, id: KeyframeId, world_from_sensor: Pose) -> PluginResult<()> {
        if self.poses.contains_key(&id) {
            return Err(invalid(format!("keyframe {id} was added before")));
        }
        if !finite_pose(&world_from_sensor) {
            return Err(invalid(format!("keyframe {id}: the pose is not finite")));
        }
        self.poses.insert(id, world_from_sensor);
        self.chains
            .robots
            .entry(id.robot)
            .or_default()
            .add_keyframe(id.index);
        Ok(())
    }

    fn add_odometry(&mut self, measurement: OdometryMeasurement) -> PluginResult<()> {
        let (target, source) = (measurement.target, measurement.source);
        let information = self.check_measurement(
            "odometry",
            target,
            source,
            &measurement.target_from_source,
            &measurement.information,
        )?;
        if target.robot != source.robot || target.index >= source.index {
            return Err(invalid(format!(
                "odometry {target} -> {source} must go forwards within one robot"
            )));
        }
        if source.robot != self.own && self.memory.inside_composed_stretch(source.robot, source.index) {
            self.memory.changed = true;
        }
        let chain = self.chains.robots.entry(source.robot).or_default();
        if chain.step(source.index).is_some() {
            return Err(invalid(format!("odometry into {source} was added before")));
        }
        if chain.indices().any(|k| k > target.index && k < source.index) {
            return Err(invalid(format!(
                "odometry {target} -> {source} skips keyframes in between"
            )));
        }
        let covariance = information
            .try_inverse()
            .ok_or_else(|| invalid(format!("odometry {target} -> {source}: singular information")))?;
        chain.add_step(
            source.index,
            Step {
                from: target.index,
                from_from_to: measurement.target_from_source,
                covariance,
            },
        );
        Ok(())
    }

    fn add_prior(
        &mut self,
        id: KeyframeId,
        world_from_sensor: Pose,
        information: skid_core::Information,
    ) -> PluginResult<()> {
        if !self.poses.contains_key(&id) {
            return Err(invalid(format!("prior on {id}: the keyframe is unknown")));
        }
        if self.priors.contains_key(&id) {
            return Err(invalid(format!("prior on {id} was added before")));
        }
        if !finite_pose(&world_from_sensor) {
            return Err(invalid(format!("prior on {id}: the pose is not finite")));
        }
        let information =
            check_information(&information).map_err(|reason| invalid(format!("prior on {id}: {reason}")))?;
        if id.robot != self.own {
            self.memory.loop_touches_peer(id.robot, id.index);
        }
        self.memory.changed = true;
        self.priors.insert(
            id,
            Prior {
                world_from_sensor,
                information,
            },
        );
        Ok(())
    }

    fn add_loop(&mut self, closure: LoopClosure) -> PluginResult<()> {
        if self.loops.contains_key(&closure.id) {
            return Err(invalid(format!("{} was added before", closure.id)));
        }
        let information = self.check_measurement(
            "loop",
            closure.target,
            closure.source,
            &closure.target_from_source,
            &closure.information,
        )?;
        for end in [closure.target, closure.source] {
            if end.robot != self.own {
                self.memory.loop_touches_peer(end.robot, end.index);
            }
        }
        self.memory.loop_changed();
        self.loops.insert(
            closure.id,
            LoopClosure {
                information,
                ..closure
            },
        );
        Ok(())
    }

    fn remove_loop(&mut self, id: LoopId) -> PluginResult<()> {
        self.loops
            .remove(&id)
            .ok_or_else(|| invalid(format!("{id} is not in the graph")))?;
        self.memory.loop_changed();
        Ok(())
    }

    fn optimize(&mut self, budget: OptimizeBudget) -> PluginResult<OptimizeReport> {
        let scope = self.scope();
        if self.poses.is_empty() {
            return Ok(OptimizeReport {
                converged: true,
                ..OptimizeReport::default()
            });
        }
        // Every loop the graph holds. A distributed graph holds those with an end on its own robot, and,
        // when the host shares the fleet's loops (`loops.fleet_loops`), loops between peers and a peer's
        // own loops, which touch the peer keyframes they join and place a peer no own loop reaches.
        let loops: Vec<&LoopClosure> = self.loops.values().collect();
        if scope == Scope::Full {
            // A centralised solve aligns every robot reachable from the first one.
            if let Some(first) = self.poses.keys().next() {
                self.aligned.insert(first.robot);
            }
        }
        // Robots with priors are in the priors' world already, and so is the frame of this robot's (or,
        // centralised, of any) robot with a prior: no loop moves them there.
        let in_prior_world = |robot: RobotId| scope == Scope::Full || robot == self.own;
        if self.priors.keys().any(|id| in_prior_world(id.robot)) {
            self.aligned.extend(self.priors.keys().map(|id| id.robot));
        }
        align_peers(&mut self.poses, &mut self.aligned, &loops);
        let robust = self.config.robust != RobustMode::None;
        let mut subgraph = match build(&self.poses, &self.chains, &loops, &self.priors, scope, robust) {
            Ok(subgraph) => subgraph,
            // A distributed graph that holds only peers' keyframes (the fleet's loops arrived before
            // this robot's first keyframe), none of them touched by a loop yet: nothing to solve.
            Err(PgoError::Empty(_)) if scope != Scope::Full => {
                return Ok(OptimizeReport {
                    converged: true,
                    ..OptimizeReport::default()
                });
            }
            Err(error) => return Err(error.into()),
        };
        // Nothing the last converged solution does not account for: it is still the optimum (see
        // `crate::incremental`); only the peers' keyframes are placed again below.
        let solved = self.memory.changed;
        let report = if solved {
            self.solve(&mut subgraph, budget, loops.len())?
        } else {
            OptimizeReport {
                iterations: 0,
                ..self.memory.last_report
            }
        };
        write_back(
            &mut self.poses,
            &self.chains,
            &subgraph,
            scope,
            solved,
            &mut self.memory.placed_through,
        );
        Ok(report)
    }

    fn graph(&self) -> &dyn GraphView {
        self
    }

    fn rejected_loops(&self) -> Vec<LoopId> {
        if self.config.robust != RobustMode::Gnc {
            return Vec::new();
        }
        self.loops
            .keys()
            .filter(|id| self.memory.labels.get(id).is_some_and(|&label| label < 0.5))
            .copied()
            .collect()
    }
}

impl PgoBackend {
    /// GNC from scratch over the whole subgraph (every label settled anew), remembered as the full run
    /// that warm starts build on.
    fn full_gnc_run(
        &mut self,
        subgraph: &mut crate::distributed::Subgraph,
        gnc: &GncSettings,
        loop_count: usize,
        nominal: f64,
    ) -> PluginResult<crate::gnc::GncOutcome> {
        let outcome = gnc_tls(&mut subgraph.problem, gnc, &mut self.cache)?;
        self.memory
            .full_run(loop_count, strict_threshold(&outcome, nominal));
        Ok(outcome)
    }

    /// Solves `subgraph` (holding `loop_count` loops) from the current estimate, by GNC (warm when the
    /// memory allows) or by Levenberg-Marquardt with the configured kernel, and remembers the outcome.
    fn solve(
        &mut self,
        subgraph: &mut crate::distributed::Subgraph,
        budget: OptimizeBudget,
        loop_count: usize,
    ) -> PluginResult<OptimizeReport> {
        if self.config.init == Initialization::Chordal {
            crate::chordal::chordal_3d(&mut subgraph.problem)?;
        }
        let settings = LmSettings {
            max_iterations: budget.max_iterations,
            max_duration: budget.max_duration.max(Duration::from_millis(1)),
            relative_cost_tolerance: self.config.relative_tolerance,
            ..LmSettings::default()
        };
        let solve_began = std::time::Instant::now();
        let report = if self.config.robust == RobustMode::Gnc {
            let nominal = self.kernel.width * self.kernel.width;
            let gnc = GncSettings {
                threshold_squared: nominal,
                inner: settings,
                ..GncSettings::default()
            };
            let outcome = match self.memory.warm_start_threshold() {
                Some(threshold) => {
                    let earlier = self.memory.earlier_labels(&subgraph.factor_loops);
                    // When a rejected new loop is settled by a full run, a new loop the region
                    // rejects goes to that run straight away, without a warm run over the whole graph
                    // first (which costs three quarters of a full run and, when it rejects the loop
                    // too, is thrown away).
                    let region = (self.config.warm_region_hops > 0).then_some(WarmRegion {
                        hops: self.config.warm_region_hops,
                        whole_graph_on_rejection: !self.config.full_run_on_rejected_new_loop,
                    });
                    let warm = gnc_tls_warm(
                        &mut subgraph.problem,
                        &gnc,
                        threshold,
                        &earlier,
                        region,
                        &mut self.cache,
                    )?;
                    // A new loop the warm run rejects may be the one that overturns the consensus the
                    // warm start stands on (a long loop closing far from where the estimate has drifted
                    // to): the labels are then settled again by a full run.
                    let rejects_new_loop =
                        || {
                            earlier.iter().zip(&subgraph.factor_loops).zip(&warm.weights).any(
                                |((before, id), weight)| id.is_some() && before.is_none() && *weight < 0.5,
                            )
                        };
                    match self.config.full_run_on_rejected_new_loop && rejects_new_loop() {
                        true => self.full_gnc_run(subgraph, &gnc, loop_count, nominal)?,
                        false => warm,
                    }
                }
                None => self.full_gnc_run(subgraph, &gnc, loop_count, nominal)?,
            };
            self.memory.keep_labels(&subgraph.factor_loops, &outcome.weights);
            tracing::debug!(
                outer = outcome.outer_iterations,
                iterations = outcome.total_iterations,
                factorizations = outcome.factorizations,
                region_poses = ?outcome.region_poses,
                elapsed_ms = solve_began.elapsed().as_secs_f64() * 1e3,
                "GNC solve"
            );
            OptimizeReport {
                iterations: outcome.total_iterations,
                initial_cost: outcome.initial_cost,
                final_cost: outcome.last.final_cost,
                converged: outcome.last.converged(),
            }
        } else {
            let outcome = optimize(&mut subgraph.problem, &self.kernel, &settings, &mut self.cache)?;
            OptimizeReport {
                iterations: outcome.iterations,
                initial_cost: outcome.initial_cost,
                final_cost: outcome.final_cost,
                converged: outcome.converged(),
            }
        };
        self.memory.changed = !report.converged;
        self.memory.last_report = report.clone();
        Ok(report)
    }
}

impl GraphView for PgoBackend {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        self.poses.get(&id).copied()
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        self.chains.between(target, source)
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        self.poses.keys().copied().collect()
    }

    fn loops(&self) -> Vec<LoopClosure> {
        self.loops.values().cloned().collect()
    }
}

impl skid_core::PluginParams for PgoConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        use skid_core::registry::check::{non_negative, positive};
        non_negative("robust_width", self.robust_width)?;
        if !(self.inlier_probability > 0.0 && self.inlier_probability < 1.0) {
            return Err(skid_core::ParamError::at(
                "inlier_probability",
                format!("{} must lie strictly between 0 and 1", self.inlier_probability),
            ));
        }
        positive("relative_tolerance", self.relative_tolerance)
    }
}
