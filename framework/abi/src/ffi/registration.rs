//! The registration slots' function tables and the values they exchange: borrowed point clouds, rigid
//! transforms as row-major 4×4 matrices, and results written into host-owned structs.
//!
//! Coarse registration is one call, `align`. Fine registration splits as the `FineRegistration` trait
//! does: `prepare` turns a cloud into a plugin-owned *prepared cloud* (downsampled points, a search
//! structure, covariances; an opaque handle the host keeps per keyframe and may share between threads),
//! `prepared_points` shows the host the points the plugin kept, `refine` aligns two prepared clouds from
//! a guess, and `destroy_prepared` frees one. A prepared cloud is never mutated after `prepare`, so the
//! host may call `refine` on several instances at once with the same prepared clouds.

use skid_msgs::Point;

use super::{CreateFn, DestroyFn, ErrorBuf, Handle, Status};

/// A borrowed point cloud: `count` points at `points`, valid for the duration of one call (or, from
/// `prepared_points`, for the prepared cloud's life). The host does not filter the points it passes: a
/// keyframe's cloud is what the odometry kept, so a plugin must tolerate (skip) non-finite coordinates.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiCloud {
    pub points: *const Point,
    pub count: usize,
}

/// A rigid transform as a row-major 4×4 matrix: rotation in the upper-left 3×3 block, translation in
/// metres in the last column, and `0 0 0 1` in the last row.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AbiTransform {
    pub matrix: [f64; 16],
}

impl AbiTransform {
    /// The identity transform.
    pub const IDENTITY: AbiTransform = AbiTransform {
        matrix: [
            1.0, 0.0, 0.0, 0.0, //
            0.0, 1.0, 0.0, 0.0, //
            0.0, 0.0, 1.0, 0.0, //
            0.0, 0.0, 0.0, 1.0,
        ],
    };
}

/// A host-owned text buffer the plugin may fill: it writes at most `capacity` bytes of UTF-8 and stores
/// the length written in `len` (0 for no text).
#[repr(C)]
#[derive(Debug)]
pub struct TextBuf {
    pub ptr: *mut u8,
    pub capacity: usize,
    pub len: usize,
}

/// What a coarse `align` writes (skid-core's `CoarseAlignment`). Booleans are `u32`, non-zero for true.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct CoarseResult {
    pub target_from_source: AbiTransform,
    /// Correspondences that survived pruning and agree with the estimate.
    pub inlier_count: u64,
    /// Correspondences before pruning.
    pub correspondence_count: u64,
    /// Inliers of the strongest alignment distinct from this one (a symmetric or repetitive place gives
    /// a rival nearly as strong); 0 when the plugin does not look.
    pub rival_inlier_count: u64,
    /// Non-zero when the plugin trusts the estimate.
    pub valid: u32,
    /// Explicit padding.
    pub reserved: u32,
}

/// What a fine `refine` writes (skid-core's `FineAlignment`).
#[repr(C)]
#[derive(Debug)]
pub struct FineResult {
    pub target_from_source: AbiTransform,
    /// The 6×6 information matrix, row-major, of the estimate over a right perturbation
    /// `target_from_source · Exp(δ)`, δ = (translation x, y, z in metres, rotation x, y, z in radians)
    /// expressed in the source frame.
    pub information: [f64; 36],
    /// Non-zero when the optimisation converged.
    pub converged: u32,
    /// Explicit padding.
    pub reserved: u32,
    pub iterations: u64,
    pub inlier_count: u64,
    /// Inliers over source points, in `[0, 1]`.
    pub inlier_ratio: f64,
    /// Final value of the plugin's cost.
    pub error: f64,
    /// Why the alignment did not converge, as a sentence; empty when it converged. The host points it
    /// at a buffer of its own (`ptr`, `capacity`) before `refine`; the plugin writes at most `capacity`
    /// bytes and sets `len`.
    pub failure: TextBuf,
}

/// Estimates `target_from_source` of two clouds without a guess; `prior` is null or a hint the plugin
/// may use or ignore.
pub type AlignFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        target: AbiCloud,
        source: AbiCloud,
        prior: *const AbiTransform,
        out: *mut CoarseResult,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// Precomputes what `refine` needs for one cloud; stores a new prepared-cloud handle in `out_prepared`.
pub type PrepareFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        cloud: AbiCloud,
        out_prepared: *mut Handle,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The points a prepared cloud kept (for example after downsampling), borrowed for its life.
pub type PreparedPointsFn =
    Option<unsafe extern "C" fn(prepared: Handle, out_cloud: *mut AbiCloud, error: *mut ErrorBuf) -> Status>;

/// Refines `target_from_source` of two prepared clouds from `guess`.
pub type RefineFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        target: Handle,
        source: Handle,
        guess: *const AbiTransform,
        out: *mut FineResult,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// Frees a prepared cloud; the handle is invalid afterwards whatever the status.
pub type DestroyPreparedFn = Option<unsafe extern "C" fn(prepared: Handle, error: *mut ErrorBuf) -> Status>;

/// The coarse registration slot's function table ([`SlotKind::COARSE`](super::SlotKind::COARSE)).
#[repr(C)]
#[derive(Debug)]
pub struct CoarseVTable {
    pub create: CreateFn,
    pub align: AlignFn,
    pub destroy: DestroyFn,
}

/// The fine registration slot's function table ([`SlotKind::FINE`](super::SlotKind::FINE)).
#[repr(C)]
#[derive(Debug)]
pub struct FineVTable {
    pub create: CreateFn,
    pub prepare: PrepareFn,
    pub prepared_points: PreparedPointsFn,
    pub refine: RefineFn,
    pub destroy_prepared: DestroyPreparedFn,
    pub destroy: DestroyFn,
}
