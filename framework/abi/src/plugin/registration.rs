//! The registration slots on the plugin side: the safe traits a coarse or fine registration implements,
//! the results they return, and the `extern "C"` functions of their tables.
//!
//! A fine registration's prepared cloud is the plugin's own type, boxed behind a handle the host keeps;
//! it must be `Sync` because the host may refine with it on several threads at once.

use skid_msgs::Point;

use super::glue::{Failure, create_with, destroy, guard, instance, lent, write_text};
use super::{ConfigError, InstanceContext};
use crate::ffi::{
    AbiCloud, AbiStr, AbiTransform, CoarseResult, CoarseVTable, ErrorBuf, FineResult, FineVTable, Handle,
    HostContext, Status,
};

/// What a coarse registration found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoarseOutcome {
    pub target_from_source: AbiTransform,
    /// Correspondences that survived pruning and agree with the estimate.
    pub inlier_count: u64,
    /// Correspondences before pruning.
    pub correspondence_count: u64,
    /// Inliers of the strongest alignment distinct from this one; 0 when the plugin does not look.
    pub rival_inlier_count: u64,
    /// True when the plugin trusts the estimate.
    pub valid: bool,
}

/// What a fine registration found.
#[derive(Clone, Debug, PartialEq)]
pub struct FineOutcome {
    pub target_from_source: AbiTransform,
    /// The 6×6 information matrix, row-major, translation first.
    pub information: [f64; 36],
    pub converged: bool,
    pub iterations: u64,
    pub inlier_count: u64,
    /// Inliers over source points.
    pub inlier_ratio: f64,
    /// Final value of the plugin's cost.
    pub error: f64,
    /// Why the alignment did not converge; `None` when it converged.
    pub failure: Option<String>,
}

/// A global (coarse) registration implemented in safe Rust, exported with
/// [`export_plugins!`](crate::export_plugins).
pub trait CoarsePlugin: Sized + Send + 'static {
    /// The registry name.
    const NAME: &'static str;
    /// One line for `skid plugins`.
    const SUMMARY: &'static str;
    /// The default parameters as TOML text; [`from_config`](Self::from_config) must accept it.
    const DEFAULT_CONFIG: &'static str;

    /// Builds an instance from TOML config text.
    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError>;

    /// Estimates `target_from_source` without a guess; `prior` is a hint that may be ignored.
    fn align(
        &mut self,
        target: &[Point],
        source: &[Point],
        prior: Option<&AbiTransform>,
    ) -> Result<CoarseOutcome, String>;
}

/// A local (fine) registration implemented in safe Rust, exported with
/// [`export_plugins!`](crate::export_plugins).
pub trait FinePlugin: Sized + Send + 'static {
    /// The registry name.
    const NAME: &'static str;
    /// One line for `skid plugins`.
    const SUMMARY: &'static str;
    /// The default parameters as TOML text; [`from_config`](Self::from_config) must accept it.
    const DEFAULT_CONFIG: &'static str;
    /// What [`prepare`](Self::prepare) precomputes for one cloud; never changed afterwards.
    type Prepared: Send + Sync + 'static;

    /// Builds an instance from TOML config text.
    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError>;

    /// Precomputes what `refine` needs for one cloud.
    fn prepare(&mut self, points: &[Point]) -> Result<Self::Prepared, String>;

    /// The points a prepared cloud kept.
    fn prepared_points(prepared: &Self::Prepared) -> &[Point];

    /// Refines `target_from_source` from `guess`.
    fn refine(
        &mut self,
        target: &Self::Prepared,
        source: &Self::Prepared,
        guess: &AbiTransform,
    ) -> Result<FineOutcome, String>;
}

/// The coarse function table of plugin type `T`.
pub const fn coarse_vtable<T: CoarsePlugin>() -> CoarseVTable {
    CoarseVTable {
        create: Some(create_coarse::<T>),
        align: Some(align::<T>),
        destroy: Some(destroy::<T>),
    }
}

/// The fine function table of plugin type `T`.
pub const fn fine_vtable<T: FinePlugin>() -> FineVTable {
    FineVTable {
        create: Some(create_fine::<T>),
        prepare: Some(prepare::<T>),
        prepared_points: Some(prepared_points::<T>),
        refine: Some(refine::<T>),
        destroy_prepared: Some(destroy::<T::Prepared>),
        destroy: Some(destroy::<T>),
    }
}

unsafe extern "C" fn create_coarse<T: CoarsePlugin>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    // SAFETY: the host's pointers, passed on unchanged.
    unsafe { create_with(config, context, out_handle, error, T::from_config) }
}

unsafe extern "C" fn create_fine<T: FinePlugin>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    // SAFETY: the host's pointers, passed on unchanged.
    unsafe { create_with(config, context, out_handle, error, T::from_config) }
}

unsafe extern "C" fn align<T: CoarsePlugin>(
    handle: Handle,
    target: AbiCloud,
    source: AbiCloud,
    prior: *const AbiTransform,
    out: *mut CoarseResult,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let plugin = unsafe { instance::<T>(handle) }?;
        // SAFETY: the host's clouds are valid for this call.
        let (target, source) = unsafe {
            (
                lent(target.points, target.count, "target points")?,
                lent(source.points, source.count, "source points")?,
            )
        };
        // SAFETY: the host passes null or a transform valid for this call.
        let prior = unsafe { prior.as_ref() };
        // SAFETY: the host passes null or a result struct it owns for this call.
        let out = unsafe { out.as_mut() }
            .ok_or_else(|| Failure::InvalidArgument("align: null output".to_owned()))?;
        let outcome = plugin.align(target, source, prior).map_err(Failure::Failed)?;
        *out = CoarseResult {
            target_from_source: outcome.target_from_source,
            inlier_count: outcome.inlier_count,
            correspondence_count: outcome.correspondence_count,
            rival_inlier_count: outcome.rival_inlier_count,
            valid: u32::from(outcome.valid),
            reserved: 0,
        };
        Ok(())
    })
}

unsafe extern "C" fn prepare<T: FinePlugin>(
    handle: Handle,
    cloud: AbiCloud,
    out_prepared: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let plugin = unsafe { instance::<T>(handle) }?;
        // SAFETY: the host's cloud is valid for this call.
        let cloud = unsafe { lent(cloud.points, cloud.count, "points") }?;
        if out_prepared.is_null() {
            return Err(Failure::InvalidArgument("prepare: null output handle".to_owned()));
        }
        let prepared = plugin.prepare(cloud).map_err(Failure::Failed)?;
        let prepared = Box::into_raw(Box::new(prepared)).cast::<std::ffi::c_void>();
        // SAFETY: `out_prepared` is non-null and points to a slot the host owns.
        unsafe { out_prepared.write(prepared) };
        Ok(())
    })
}

unsafe extern "C" fn prepared_points<T: FinePlugin>(
    prepared: Handle,
    out_cloud: *mut AbiCloud,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live prepared handle of this plugin type; prepared clouds are only read.
        let prepared = unsafe { prepared.cast::<T::Prepared>().as_ref() }
            .ok_or_else(|| Failure::InvalidArgument("prepared_points: null prepared cloud".to_owned()))?;
        // SAFETY: the host passes null or a struct it owns for this call.
        let out = unsafe { out_cloud.as_mut() }
            .ok_or_else(|| Failure::InvalidArgument("prepared_points: null output".to_owned()))?;
        let kept = T::prepared_points(prepared);
        *out = AbiCloud {
            points: kept.as_ptr(),
            count: kept.len(),
        };
        Ok(())
    })
}

unsafe extern "C" fn refine<T: FinePlugin>(
    handle: Handle,
    target: Handle,
    source: Handle,
    guess: *const AbiTransform,
    out: *mut FineResult,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let plugin = unsafe { instance::<T>(handle) }?;
        // SAFETY: live prepared handles of this plugin type, only read while the host holds them.
        let (target, source) = unsafe {
            (
                target.cast::<T::Prepared>().as_ref(),
                source.cast::<T::Prepared>().as_ref(),
            )
        };
        let (Some(target), Some(source)) = (target, source) else {
            return Err(Failure::InvalidArgument("refine: null prepared cloud".to_owned()));
        };
        // SAFETY: the host passes null or a transform valid for this call.
        let guess = unsafe { guess.as_ref() }
            .ok_or_else(|| Failure::InvalidArgument("refine: null guess".to_owned()))?;
        // SAFETY: the host passes null or a result struct it owns for this call.
        let out = unsafe { out.as_mut() }
            .ok_or_else(|| Failure::InvalidArgument("refine: null output".to_owned()))?;
        let outcome = plugin.refine(target, source, guess).map_err(Failure::Failed)?;
        out.target_from_source = outcome.target_from_source;
        out.information = outcome.information;
        out.converged = u32::from(outcome.converged);
        out.iterations = outcome.iterations;
        out.inlier_count = outcome.inlier_count;
        out.inlier_ratio = outcome.inlier_ratio;
        out.error = outcome.error;
        // SAFETY: the host's failure buffer is null or writable for its capacity.
        unsafe { write_text(&mut out.failure, outcome.failure.as_deref().unwrap_or("")) };
        Ok(())
    })
}
