//! Registration slots: coarse (global, no initial guess) and fine (local refinement) alignment.

use std::any::Any;
use std::sync::Arc;

use crate::{Cloud, CloudView, Information, PluginResult, Pose};

/// Result of a coarse (global) registration.
#[derive(Clone, Debug)]
pub struct CoarseAlignment {
    pub target_from_source: Pose,
    /// Correspondences that survived outlier pruning and agree with the estimate.
    pub inlier_count: usize,
    /// Correspondences before pruning.
    pub correspondence_count: usize,
    /// Inliers of the strongest alignment distinct from this one, found among the correspondences this
    /// one leaves out; 0 when the plugin does not look. A symmetric or repetitive place admits several
    /// alignments, and a rival nearly as strong as the estimate marks the result as ambiguous.
    pub rival_inlier_count: usize,
    /// True when the plugin trusts the estimate (for example at least 5 final inliers).
    pub valid: bool,
}

/// Aligns two clouds without an initial guess.
pub trait CoarseRegistration: Send {
    /// Estimates `target_from_source`; `prior`, when given (a yaw hint from place recognition, say), may
    /// be used or ignored.
    fn align(
        &mut self,
        target: CloudView<'_>,
        source: CloudView<'_>,
        prior: Option<&Pose>,
    ) -> PluginResult<CoarseAlignment>;
}

/// A cloud with whatever the fine registration precomputed for it (downsampled points, kd-tree,
/// covariances), cached per keyframe so repeated alignments against it pay once.
#[derive(Clone)]
pub struct PreparedCloud {
    /// The cloud as the plugin uses it (for example downsampled).
    pub cloud: Arc<Cloud>,
    /// Plugin-private precomputation; only the plugin that prepared it can read it.
    pub cache: Arc<dyn Any + Send + Sync>,
}

impl std::fmt::Debug for PreparedCloud {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PreparedCloud")
            .field("points", &self.cloud.len())
            .finish_non_exhaustive()
    }
}

/// Result of a fine registration.
#[derive(Clone, Debug)]
pub struct FineAlignment {
    pub target_from_source: Pose,
    /// 6x6 information (the Gauss-Newton Hessian at the optimum), translation first.
    pub information: Information,
    pub converged: bool,
    pub iterations: usize,
    pub inlier_count: usize,
    /// Inliers over source points.
    pub inlier_ratio: f64,
    /// Final value of the plugin's cost.
    pub error: f64,
    /// Why the alignment did not converge (for example "not converged after 20 iterations", a singular
    /// Hessian, too few correspondences), as a sentence for logs and reports; `None` when `converged`.
    pub failure: Option<String>,
}

/// Refines an alignment from an initial guess.
pub trait FineRegistration: Send {
    /// Precomputes what `refine` needs for one cloud.
    fn prepare(&mut self, cloud: CloudView<'_>) -> PluginResult<PreparedCloud>;

    /// Refines `target_from_source` starting from `guess`.
    fn refine(
        &mut self,
        target: &PreparedCloud,
        source: &PreparedCloud,
        guess: &Pose,
    ) -> PluginResult<FineAlignment>;
}
