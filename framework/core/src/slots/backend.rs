//! Back-end slots: loop verification (the verifier) and pose-graph optimisation (the back-end).

use std::time::Duration;

use crate::{CloudView, Information, KeyframeId, LoopId, PluginResult, Pose, RobotId};

/// A relative pose with its uncertainty.
#[derive(Clone, Debug)]
pub struct RelativePose {
    pub target_from_source: Pose,
    /// 6x6 covariance, translation first.
    pub covariance: Information,
}

/// Odometry between two keyframes of one robot.
#[derive(Clone, Debug)]
pub struct OdometryMeasurement {
    /// The earlier keyframe.
    pub target: KeyframeId,
    /// The later keyframe.
    pub source: KeyframeId,
    pub target_from_source: Pose,
    pub information: Information,
}

/// A loop closure between two keyframes (same robot: intra-robot; different robots: inter-robot).
#[derive(Clone, Debug)]
pub struct LoopClosure {
    pub id: LoopId,
    pub target: KeyframeId,
    pub source: KeyframeId,
    pub target_from_source: Pose,
    pub information: Information,
}

impl LoopClosure {
    /// True when the two keyframes belong to different robots.
    pub fn is_inter_robot(&self) -> bool {
        self.target.robot != self.source.robot
    }
}

/// A loop closure submitted for verification, with the two clouds it aligns (sensor frames). Both clouds
/// are empty when the candidate comes from a recorded pose graph (`skid replay`): a verifier then judges
/// it on its pose alone and skips the checks that need clouds.
#[derive(Clone, Debug)]
pub struct LoopCandidate<'a> {
    pub closure: LoopClosure,
    pub target_cloud: CloudView<'a>,
    pub source_cloud: CloudView<'a>,
}

/// The verifier's decision after one submission. PCM may retract loops it accepted earlier when the
/// maximum consistent set changes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Verdict {
    pub accepted: Vec<LoopId>,
    pub retracted: Vec<LoopId>,
    /// Rejected loops with the reason, for logs and evaluation.
    pub rejected: Vec<(LoopId, String)>,
}

/// Read-only access to the pose graph, for verifiers and the runtime.
pub trait GraphView {
    /// The current estimate of a keyframe's pose in the optimiser's world frame.
    fn pose(&self, id: KeyframeId) -> Option<Pose>;

    /// The odometry-only relative pose between two keyframes of one robot, composed along the chain,
    /// with its covariance; `None` if either keyframe is unknown or they belong to different robots.
    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose>;

    /// Every keyframe in the graph.
    fn keyframes(&self) -> Vec<KeyframeId>;

    /// Every loop closure currently in the graph.
    fn loops(&self) -> Vec<LoopClosure>;

    /// When a keyframe was recorded (its scan's stamp, nanoseconds on the fleet's clock), for the
    /// robot's own keyframes and the peers' whose descriptors arrived; `None` when unknown (the default).
    fn keyframe_stamp_nanos(&self, id: KeyframeId) -> Option<u64> {
        let _ = id;
        None
    }

    /// Whether the place recognition takes two keyframes (of any robots) for one place: their
    /// descriptors are as close as a loop candidate's must be. `None` when either descriptor is not
    /// held or the descriptor cannot compare stored keyframes (the default). A verifier checks what a
    /// frame hypothesis predicts with it: keyframes the hypothesis puts in one place should look alike.
    fn looks_alike(&self, a: KeyframeId, b: KeyframeId) -> Option<bool> {
        let _ = (a, b);
        None
    }

    /// Where robot `b`'s first keyframe sits in the frame of robot `a`'s first keyframe, as robots other
    /// than `a` and `b` know it (composed through each such robot `via` that has merged with both):
    /// one `(via, a_first_from_b_first)` per robot. Empty when no third robot has (the default). A
    /// verifier checks a direct frame hypothesis between `a` and `b` against these, closing the cycle.
    fn frames_through_others(&self, a: RobotId, b: RobotId) -> Vec<(RobotId, Pose)> {
        let _ = (a, b);
        Vec::new()
    }
}

/// Decides which loop closures to trust.
pub trait Verifier: Send {
    fn submit(&mut self, candidate: &LoopCandidate<'_>, graph: &dyn GraphView) -> PluginResult<Verdict>;

    /// Re-judges the loops submitted so far after something outside them changed (another robot's
    /// frame estimates arrived, see [`GraphView::frames_through_others`]); returns the loops that enter
    /// or leave the accepted set. The default changes nothing.
    fn reconsider(&mut self, graph: &dyn GraphView) -> PluginResult<Verdict> {
        let _ = graph;
        Ok(Verdict::default())
    }
}

/// Limits on one optimisation call.
#[derive(Clone, Copy, Debug)]
pub struct OptimizeBudget {
    pub max_iterations: usize,
    pub max_duration: Duration,
}

impl Default for OptimizeBudget {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            max_duration: Duration::from_secs(10),
        }
    }
}

/// What one optimisation call did.
#[derive(Clone, Debug, Default)]
pub struct OptimizeReport {
    pub iterations: usize,
    pub initial_cost: f64,
    pub final_cost: f64,
    pub converged: bool,
}

/// Pose-graph optimisation over a robot's keyframes and the peer keyframes its loops link to.
pub trait Backend: Send {
    /// Adds a keyframe with an initial pose guess; adding a known keyframe is an error.
    fn add_keyframe(&mut self, id: KeyframeId, world_from_sensor: Pose) -> PluginResult<()>;

    /// Adds an odometry edge between two known keyframes of one robot.
    fn add_odometry(&mut self, measurement: OdometryMeasurement) -> PluginResult<()>;

    /// Adds a prior on a known keyframe: its pose in the world frame, measured with `information`
    /// (weighing the residual `Log(Z⁻¹ T)`, translation first, as GTSAM's `PriorFactor`). A pose graph
    /// whose robots start at known poses (a recorded problem's, or a prior map's) is anchored by them.
    fn add_prior(
        &mut self,
        id: KeyframeId,
        world_from_sensor: Pose,
        information: Information,
    ) -> PluginResult<()>;

    /// Adds an accepted loop closure.
    fn add_loop(&mut self, closure: LoopClosure) -> PluginResult<()>;

    /// Removes a loop closure that was retracted; unknown ids are an error.
    fn remove_loop(&mut self, id: LoopId) -> PluginResult<()>;

    /// Optimises within the budget.
    fn optimize(&mut self, budget: OptimizeBudget) -> PluginResult<OptimizeReport>;

    /// Read-only view of the graph.
    fn graph(&self) -> &dyn GraphView;

    /// The loops in the graph that the last robust solve gave no weight (GNC's outliers): they stay in
    /// the graph but do not move it. Empty for a back-end that does not judge loops.
    fn rejected_loops(&self) -> Vec<LoopId> {
        Vec::new()
    }
}
