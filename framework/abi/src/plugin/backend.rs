//! The back-end slot on the plugin side: the safe trait and the `extern "C"` functions of its table. The
//! keyframe and loop lists live in the instance's wrapper, so the host can read them by pointer until
//! its next call.

use super::glue::{Failure, create_with, destroy, guard, instance};
use super::{ConfigError, InstanceContext};
use crate::ffi::{
    AbiKeyframeId, AbiLoop, AbiOptimizeReport, AbiPrior, AbiRelativePose, AbiStr, AbiTransform,
    BackendVTable, ErrorBuf, Handle, HostContext, Status,
};

/// A pose-graph back-end implemented in safe Rust, exported with [`export_plugins!`](crate::export_plugins).
pub trait BackendPlugin: Sized + Send + 'static {
    /// The registry name.
    const NAME: &'static str;
    /// One line for `skid plugins`.
    const SUMMARY: &'static str;
    /// The default parameters as TOML text; [`from_config`](Self::from_config) must accept it.
    const DEFAULT_CONFIG: &'static str;

    /// Builds an instance from TOML config text.
    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError>;

    /// Adds a keyframe with an initial pose guess; a known keyframe is an error.
    fn add_keyframe(&mut self, id: AbiKeyframeId, world_from_sensor: &AbiTransform) -> Result<(), String>;

    /// Adds an odometry edge between two known keyframes of one robot (the edge's id is unused).
    fn add_odometry(&mut self, edge: &AbiLoop) -> Result<(), String>;

    /// Adds a prior on a known keyframe (refuse it with a reason if the back-end takes none).
    fn add_prior(&mut self, prior: &AbiPrior) -> Result<(), String>;

    /// Adds an accepted loop closure.
    fn add_loop(&mut self, closure: &AbiLoop) -> Result<(), String>;

    /// Removes a retracted loop closure; an unknown id is an error.
    fn remove_loop(&mut self, id: u64) -> Result<(), String>;

    /// Optimises within the budget.
    fn optimize(&mut self, max_iterations: u64, max_duration_s: f64) -> Result<AbiOptimizeReport, String>;

    /// The current estimate of a keyframe's pose.
    fn pose(&self, id: AbiKeyframeId) -> Option<AbiTransform>;

    /// The odometry-only relative pose between two keyframes of one robot, with its covariance.
    fn odometry_between(&self, target: AbiKeyframeId, source: AbiKeyframeId) -> Option<AbiRelativePose>;

    /// Every keyframe in the graph.
    fn keyframes(&self) -> Vec<AbiKeyframeId>;

    /// Every loop closure in the graph.
    fn loops(&self) -> Vec<AbiLoop>;

    /// The ids of the loops the last robust solve gave no weight; none for a back-end that does not
    /// judge loops.
    fn rejected_loops(&self) -> Vec<u64> {
        Vec::new()
    }
}

/// A back-end instance and the lists it last lent the host.
struct Lending<T> {
    plugin: T,
    keyframes: Vec<AbiKeyframeId>,
    loops: Vec<AbiLoop>,
    rejected: Vec<u64>,
}

/// The back-end function table of plugin type `T`.
pub const fn backend_vtable<T: BackendPlugin>() -> BackendVTable {
    BackendVTable {
        create: Some(create::<T>),
        add_keyframe: Some(add_keyframe::<T>),
        add_edge: Some(add_edge::<T>),
        add_prior: Some(add_prior::<T>),
        remove_loop: Some(remove_loop::<T>),
        optimize: Some(optimize::<T>),
        pose: Some(pose::<T>),
        odometry_between: Some(odometry_between::<T>),
        lists: Some(lists::<T>),
        rejected_loops: Some(rejected_loops::<T>),
        destroy: Some(destroy::<Lending<T>>),
    }
}

fn lending<T: BackendPlugin>(config: &str, context: &InstanceContext) -> Result<Lending<T>, ConfigError> {
    Ok(Lending {
        plugin: T::from_config(config, context)?,
        keyframes: Vec::new(),
        loops: Vec::new(),
        rejected: Vec::new(),
    })
}

unsafe extern "C" fn create<T: BackendPlugin>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    // SAFETY: the host's pointers, passed on unchanged.
    unsafe { create_with(config, context, out_handle, error, lending::<T>) }
}

/// The value behind a pointer the host passes, or an invalid-argument failure naming `what`.
///
/// # Safety
///
/// `pointer` must be null or valid for writes (and reads) during the call.
unsafe fn argument<'a, V>(pointer: *mut V, what: &str) -> Result<&'a mut V, Failure> {
    // SAFETY: the caller's guarantee.
    unsafe { pointer.as_mut() }.ok_or_else(|| Failure::InvalidArgument(format!("null {what}")))
}

unsafe extern "C" fn add_keyframe<T: BackendPlugin>(
    handle: Handle,
    id: AbiKeyframeId,
    world_from_sensor: *const AbiTransform,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or a transform valid for this call (only read).
        let pose = unsafe { argument(world_from_sensor.cast_mut(), "pose") }?;
        lending.plugin.add_keyframe(id, pose).map_err(Failure::Failed)
    })
}

unsafe extern "C" fn add_edge<T: BackendPlugin>(
    handle: Handle,
    edge: *const AbiLoop,
    is_loop: u32,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or an edge valid for this call (only read).
        let edge = unsafe { argument(edge.cast_mut(), "edge") }?;
        let added = if is_loop != 0 {
            lending.plugin.add_loop(edge)
        } else {
            lending.plugin.add_odometry(edge)
        };
        added.map_err(Failure::Failed)
    })
}

unsafe extern "C" fn add_prior<T: BackendPlugin>(
    handle: Handle,
    prior: *const AbiPrior,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or a prior valid for this call (only read).
        let prior = unsafe { argument(prior.cast_mut(), "prior") }?;
        lending.plugin.add_prior(prior).map_err(Failure::Failed)
    })
}

unsafe extern "C" fn remove_loop<T: BackendPlugin>(handle: Handle, id: u64, error: *mut ErrorBuf) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        lending.plugin.remove_loop(id).map_err(Failure::Failed)
    })
}

unsafe extern "C" fn optimize<T: BackendPlugin>(
    handle: Handle,
    max_iterations: u64,
    max_duration_s: f64,
    out: *mut AbiOptimizeReport,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or a struct it owns for this call.
        let out = unsafe { argument(out, "report") }?;
        *out = lending
            .plugin
            .optimize(max_iterations, max_duration_s)
            .map_err(Failure::Failed)?;
        Ok(())
    })
}

unsafe extern "C" fn pose<T: BackendPlugin>(
    handle: Handle,
    id: AbiKeyframeId,
    out: *mut AbiTransform,
    out_found: *mut u32,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or values it owns for this call.
        let (out, out_found) = unsafe { (argument(out, "pose")?, argument(out_found, "flag")?) };
        let found = lending.plugin.pose(id);
        *out_found = u32::from(found.is_some());
        *out = found.unwrap_or(AbiTransform::IDENTITY);
        Ok(())
    })
}

unsafe extern "C" fn odometry_between<T: BackendPlugin>(
    handle: Handle,
    target: AbiKeyframeId,
    source: AbiKeyframeId,
    out: *mut AbiRelativePose,
    out_found: *mut u32,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or values it owns for this call.
        let (out, out_found) = unsafe { (argument(out, "relative pose")?, argument(out_found, "flag")?) };
        let found = lending.plugin.odometry_between(target, source);
        *out_found = u32::from(found.is_some());
        if let Some(found) = found {
            *out = found;
        }
        Ok(())
    })
}

unsafe extern "C" fn lists<T: BackendPlugin>(
    handle: Handle,
    out_keyframes: *mut *const AbiKeyframeId,
    out_keyframe_count: *mut usize,
    out_loops: *mut *const AbiLoop,
    out_loop_count: *mut usize,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or values it owns for this call.
        let outputs = unsafe {
            (
                argument(out_keyframes, "keyframe list")?,
                argument(out_keyframe_count, "keyframe count")?,
                argument(out_loops, "loop list")?,
                argument(out_loop_count, "loop count")?,
            )
        };
        lending.keyframes = lending.plugin.keyframes();
        lending.loops = lending.plugin.loops();
        *outputs.0 = lending.keyframes.as_ptr();
        *outputs.1 = lending.keyframes.len();
        *outputs.2 = lending.loops.as_ptr();
        *outputs.3 = lending.loops.len();
        Ok(())
    })
}

unsafe extern "C" fn rejected_loops<T: BackendPlugin>(
    handle: Handle,
    out_ids: *mut *const u64,
    out_count: *mut usize,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live handle from `create`, called from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or values it owns for this call.
        let (out_ids, out_count) = unsafe { (argument(out_ids, "id list")?, argument(out_count, "count")?) };
        lending.rejected = lending.plugin.rejected_loops();
        *out_ids = lending.rejected.as_ptr();
        *out_count = lending.rejected.len();
        Ok(())
    })
}
