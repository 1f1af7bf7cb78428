//! The back-end slot's function table: building a pose graph (keyframes, odometry edges, priors, loops
//! added and removed), optimising it within a budget, and answering the host's graph queries (poses,
//! odometry between keyframes, the keyframe and loop lists, and the loops its robust solve rejects, which
//! the plugin lends until its next call).

use super::{
    AbiKeyframeId, AbiLoop, AbiRelativePose, AbiTransform, CreateFn, DestroyFn, ErrorBuf, Handle, Status,
};

/// What one optimisation call did.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct AbiOptimizeReport {
    pub iterations: u64,
    pub initial_cost: f64,
    pub final_cost: f64,
    /// Non-zero when the optimisation converged.
    pub converged: u32,
    /// Explicit padding.
    pub reserved: u32,
}

/// Adds a keyframe with an initial pose guess; adding a known keyframe is an error.
pub type AddKeyframeFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        id: AbiKeyframeId,
        world_from_sensor: *const AbiTransform,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// Adds an edge between two known keyframes: odometry (`is_loop` zero, the loop id unused) or an
/// accepted loop closure.
pub type AddEdgeFn = Option<
    unsafe extern "C" fn(handle: Handle, edge: *const AbiLoop, is_loop: u32, error: *mut ErrorBuf) -> Status,
>;

/// A prior on one keyframe: its pose in the world frame and the 6×6 information (row-major, translation
/// first) of the residual `Log(Z⁻¹ T)`, GTSAM's `PriorFactor`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiPrior {
    pub id: AbiKeyframeId,
    pub world_from_sensor: AbiTransform,
    pub information: [f64; 36],
}

/// Adds a prior on a known keyframe.
pub type AddPriorFn =
    Option<unsafe extern "C" fn(handle: Handle, prior: *const AbiPrior, error: *mut ErrorBuf) -> Status>;

/// Removes a loop closure that was retracted; an unknown id is an error.
pub type RemoveLoopFn = Option<unsafe extern "C" fn(handle: Handle, id: u64, error: *mut ErrorBuf) -> Status>;

/// Optimises within `max_iterations` and `max_duration_s` seconds.
pub type OptimizeFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        max_iterations: u64,
        max_duration_s: f64,
        out: *mut AbiOptimizeReport,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The current estimate of a keyframe's pose; `out_found` says whether the graph has it.
pub type BackendPoseFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        id: AbiKeyframeId,
        out: *mut AbiTransform,
        out_found: *mut u32,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The odometry-only relative pose between two keyframes of one robot; `out_found` says whether both are
/// known and belong to the same robot.
pub type BackendOdometryFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        target: AbiKeyframeId,
        source: AbiKeyframeId,
        out: *mut AbiRelativePose,
        out_found: *mut u32,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// Every keyframe and every loop in the graph, lent until the next call on the instance.
pub type BackendListsFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        out_keyframes: *mut *const AbiKeyframeId,
        out_keyframe_count: *mut usize,
        out_loops: *mut *const AbiLoop,
        out_loop_count: *mut usize,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The ids of the loops in the graph that the last robust solve gave no weight (its outliers), lent
/// until the next call on the instance; none for a back-end that does not judge loops.
pub type RejectedLoopsFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        out_ids: *mut *const u64,
        out_count: *mut usize,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The back-end slot's function table ([`SlotKind::BACKEND`](super::SlotKind::BACKEND)).
#[repr(C)]
#[derive(Debug)]
pub struct BackendVTable {
    pub create: CreateFn,
    pub add_keyframe: AddKeyframeFn,
    pub add_edge: AddEdgeFn,
    pub add_prior: AddPriorFn,
    pub remove_loop: RemoveLoopFn,
    pub optimize: OptimizeFn,
    pub pose: BackendPoseFn,
    pub odometry_between: BackendOdometryFn,
    pub lists: BackendListsFn,
    pub rejected_loops: RejectedLoopsFn,
    pub destroy: DestroyFn,
}
