//! The verifier slot's function table and the values it exchanges: a loop candidate with its two clouds,
//! read access to the host's pose graph (callbacks for poses and odometry, snapshots of keyframes and
//! loops), and the verdict, whose lists the plugin lends to the host until its next call.
//!
//! A verifier such as PCM is stateful: one submission can accept, retract or reject loops submitted
//! earlier, so a verdict cannot be asked for twice; that is why it is lent rather than written into host
//! buffers that might be too small.

use std::ffi::c_void;

use super::{AbiCloud, AbiStr, AbiTransform, CreateFn, DestroyFn, ErrorBuf, Handle, Status};

/// A keyframe: the robot and its per-robot index.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AbiKeyframeId {
    pub robot: u32,
    pub index: u32,
}

/// A loop closure between two keyframes.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiLoop {
    pub id: u64,
    pub target: AbiKeyframeId,
    pub source: AbiKeyframeId,
    pub target_from_source: AbiTransform,
    /// The 6×6 information matrix, row-major, of the measurement over a right perturbation
    /// `target_from_source · Exp(δ)`, δ = (translation x, y, z in metres, rotation x, y, z in radians)
    /// expressed in the source frame.
    pub information: [f64; 36],
}

/// A relative pose with its 6×6 covariance (row-major, translation first).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiRelativePose {
    pub target_from_source: AbiTransform,
    pub covariance: [f64; 36],
}

/// The current estimate of a keyframe's pose; returns non-zero and fills `out` when the keyframe is known.
pub type GraphPoseFn =
    Option<unsafe extern "C" fn(context: *const c_void, id: AbiKeyframeId, out: *mut AbiTransform) -> u32>;

/// The odometry-only relative pose between two keyframes of one robot; returns non-zero and fills `out`
/// when both are known and belong to the same robot.
pub type GraphOdometryFn = Option<
    unsafe extern "C" fn(
        context: *const c_void,
        target: AbiKeyframeId,
        source: AbiKeyframeId,
        out: *mut AbiRelativePose,
    ) -> u32,
>;

/// Read access to the host's pose graph, valid for the duration of one `submit` call.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiGraph {
    /// Passed back to the callbacks; opaque to the plugin.
    pub context: *const c_void,
    pub pose: GraphPoseFn,
    pub odometry_between: GraphOdometryFn,
    /// Every keyframe in the graph.
    pub keyframes: *const AbiKeyframeId,
    pub keyframe_count: usize,
    /// Every loop closure currently in the graph.
    pub loops: *const AbiLoop,
    pub loop_count: usize,
}

/// A rejected loop and why.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiRejection {
    pub id: u64,
    pub reason: AbiStr,
}

/// A verdict, lent by the plugin until its next call on the instance.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiVerdict {
    pub accepted: *const u64,
    pub accepted_count: usize,
    pub retracted: *const u64,
    pub retracted_count: usize,
    pub rejected: *const AbiRejection,
    pub rejected_count: usize,
}

/// Submits a loop candidate (with its target and source clouds in their sensor frames) for verification.
pub type SubmitFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        candidate: *const AbiLoop,
        target_cloud: AbiCloud,
        source_cloud: AbiCloud,
        graph: *const AbiGraph,
        out: *mut AbiVerdict,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The verifier slot's function table ([`SlotKind::VERIFIER`](super::SlotKind::VERIFIER)).
#[repr(C)]
#[derive(Debug)]
pub struct VerifierVTable {
    pub create: CreateFn,
    pub submit: SubmitFn,
    pub destroy: DestroyFn,
}
