//! The odometry slot on the plugin side: the safe trait, the scan it is lent, the update it returns, and
//! the `extern "C"` functions of its table.
//!
//! The keyframe cloud of the last update lives in the instance's wrapper, so the host can read it by
//! pointer until its next call, without the plugin allocating on the host's behalf.

use skid_msgs::{ImuSample, Point, RawPoint};

use super::glue::{Failure, create_with, destroy, guard, instance, lent};
use super::{ConfigError, InstanceContext};
use crate::ffi::{
    AbiScan, AbiStr, AbiTransform, ErrorBuf, Handle, HostContext, OdometryResult, OdometryVTable, Status,
};

/// One scan as the plugin sees it, borrowed for the call.
#[derive(Clone, Copy, Debug)]
pub struct ScanView<'a> {
    pub robot: u32,
    /// Per-robot scan counter, from 0.
    pub sequence: u32,
    /// Start of the sweep; point time offsets are relative to it.
    pub stamp_nanos: u64,
    pub points: &'a [RawPoint],
    /// IMU samples since the previous scan.
    pub imu: &'a [ImuSample],
    pub ground_truth_world_from_sensor: Option<AbiTransform>,
    pub imu_from_sensor: Option<AbiTransform>,
}

/// What registering a scan found.
#[derive(Clone, Debug, PartialEq)]
pub struct OdometryOutcome {
    pub stamp_nanos: u64,
    /// Pose of the sensor at the scan stamp in the robot's odometry world frame.
    pub world_from_sensor: AbiTransform,
    /// Motion since the previous scan.
    pub previous_from_current: AbiTransform,
    /// The keyframe's cloud (deskewed, downsampled, sensor frame) when the keyframe policy fired.
    pub keyframe: Option<Vec<Point>>,
}

/// A LiDAR (or LiDAR-inertial) odometry implemented in safe Rust, exported with
/// [`export_plugins!`](crate::export_plugins).
pub trait OdometryPlugin: Sized + Send + 'static {
    /// The registry name.
    const NAME: &'static str;
    /// One line for `skid plugins`.
    const SUMMARY: &'static str;
    /// The default parameters as TOML text; [`from_config`](Self::from_config) must accept it.
    const DEFAULT_CONFIG: &'static str;

    /// Builds an instance from TOML config text.
    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError>;

    /// Registers one scan; an error must leave the estimator's state as it was.
    fn register(&mut self, scan: &ScanView<'_>) -> Result<OdometryOutcome, String>;
}

/// An odometry instance and the keyframe cloud it last lent the host.
struct Lending<T> {
    plugin: T,
    keyframe: Vec<Point>,
}

/// The odometry function table of plugin type `T`.
pub const fn odometry_vtable<T: OdometryPlugin>() -> OdometryVTable {
    OdometryVTable {
        create: Some(create::<T>),
        register: Some(register::<T>),
        destroy: Some(destroy::<Lending<T>>),
    }
}

fn lending<T: OdometryPlugin>(config: &str, context: &InstanceContext) -> Result<Lending<T>, ConfigError> {
    Ok(Lending {
        plugin: T::from_config(config, context)?,
        keyframe: Vec::new(),
    })
}

unsafe extern "C" fn create<T: OdometryPlugin>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    // SAFETY: the host's pointers, passed on unchanged.
    unsafe { create_with(config, context, out_handle, error, lending::<T>) }
}

unsafe extern "C" fn register<T: OdometryPlugin>(
    handle: Handle,
    scan: *const AbiScan,
    out: *mut OdometryResult,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or a scan valid for this call.
        let scan = unsafe { scan.as_ref() }
            .ok_or_else(|| Failure::InvalidArgument("register: null scan".to_owned()))?;
        // SAFETY: the host passes null or a result struct it owns for this call.
        let out = unsafe { out.as_mut() }
            .ok_or_else(|| Failure::InvalidArgument("register: null output".to_owned()))?;
        let view = ScanView {
            robot: scan.robot,
            sequence: scan.sequence,
            stamp_nanos: scan.stamp_nanos,
            // SAFETY: the scan's buffers are valid for this call.
            points: unsafe { lent(scan.points, scan.point_count, "points") }?,
            // SAFETY: as above.
            imu: unsafe { lent(scan.imu, scan.imu_count, "IMU samples") }?,
            ground_truth_world_from_sensor: (scan.has_ground_truth != 0)
                .then_some(scan.ground_truth_world_from_sensor),
            imu_from_sensor: (scan.has_imu_from_sensor != 0).then_some(scan.imu_from_sensor),
        };
        let outcome = lending.plugin.register(&view).map_err(Failure::Failed)?;
        let is_keyframe = outcome.keyframe.is_some();
        lending.keyframe = outcome.keyframe.unwrap_or_default();
        *out = OdometryResult {
            stamp_nanos: outcome.stamp_nanos,
            is_keyframe: u32::from(is_keyframe),
            reserved: 0,
            world_from_sensor: outcome.world_from_sensor,
            previous_from_current: outcome.previous_from_current,
            keyframe_points: lending.keyframe.as_ptr(),
            keyframe_count: lending.keyframe.len(),
        };
        Ok(())
    })
}
