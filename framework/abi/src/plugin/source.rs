//! The source slot on the plugin side: the safe trait, the scan it produces, and the `extern "C"`
//! functions of its table. The last scan lives in the instance's wrapper, so the host can read its
//! buffers by pointer until its next call.

use skid_msgs::{ImuSample, RawPoint};

use super::glue::{Failure, create_with, destroy, guard, instance};
use super::{ConfigError, InstanceContext};
use crate::ffi::{
    AbiScan, AbiStr, AbiTransform, ErrorBuf, Handle, HostContext, SourceInfo, SourceVTable, Status,
};

/// One scan a source produces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OwnedScan {
    pub robot: u32,
    /// Per-robot scan counter, from 0.
    pub sequence: u32,
    /// Start of the sweep; point time offsets are relative to it.
    pub stamp_nanos: u64,
    pub points: Vec<RawPoint>,
    /// IMU samples since the previous scan.
    pub imu: Vec<ImuSample>,
    pub ground_truth_world_from_sensor: Option<AbiTransform>,
    pub imu_from_sensor: Option<AbiTransform>,
}

/// A source of scans (files, a driver, a simulator) implemented in safe Rust, exported with
/// [`export_plugins!`](crate::export_plugins).
pub trait SourcePlugin: Sized + Send + 'static {
    /// The registry name.
    const NAME: &'static str;
    /// One line for `skid plugins`.
    const SUMMARY: &'static str;
    /// The default parameters as TOML text; [`from_config`](Self::from_config) must accept it.
    const DEFAULT_CONFIG: &'static str;

    /// Builds an instance from TOML config text; `context.robot` says whose scans to produce.
    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError>;

    /// The next scan, or `None` at the end of the sequence.
    fn next_scan(&mut self) -> Result<Option<OwnedScan>, String>;

    /// Whether the scans carry IMU samples.
    fn provides_imu(&self) -> bool {
        false
    }

    /// How many scans remain, when the source knows.
    fn remaining_hint(&self) -> Option<usize> {
        None
    }
}

/// A source instance and the scan it last lent the host.
struct Lending<T> {
    plugin: T,
    scan: OwnedScan,
}

/// The source function table of plugin type `T`.
pub const fn source_vtable<T: SourcePlugin>() -> SourceVTable {
    SourceVTable {
        create: Some(create::<T>),
        info: Some(info::<T>),
        next_scan: Some(next_scan::<T>),
        destroy: Some(destroy::<Lending<T>>),
    }
}

fn lending<T: SourcePlugin>(config: &str, context: &InstanceContext) -> Result<Lending<T>, ConfigError> {
    Ok(Lending {
        plugin: T::from_config(config, context)?,
        scan: OwnedScan::default(),
    })
}

unsafe extern "C" fn create<T: SourcePlugin>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    // SAFETY: the host's pointers, passed on unchanged.
    unsafe { create_with(config, context, out_handle, error, lending::<T>) }
}

unsafe extern "C" fn info<T: SourcePlugin>(
    handle: Handle,
    out: *mut SourceInfo,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or a struct it owns for this call.
        let out = unsafe { out.as_mut() }
            .ok_or_else(|| Failure::InvalidArgument("info: null output".to_owned()))?;
        let remaining = lending.plugin.remaining_hint();
        *out = SourceInfo {
            provides_imu: u32::from(lending.plugin.provides_imu()),
            knows_remaining: u32::from(remaining.is_some()),
            remaining_scans: remaining.map_or(0, |count| count as u64),
        };
        Ok(())
    })
}

unsafe extern "C" fn next_scan<T: SourcePlugin>(
    handle: Handle,
    out_scan: *mut AbiScan,
    out_has_scan: *mut u32,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or structs it owns for this call.
        let (Some(out_scan), Some(out_has_scan)) =
            (unsafe { out_scan.as_mut() }, unsafe { out_has_scan.as_mut() })
        else {
            return Err(Failure::InvalidArgument("next_scan: null output".to_owned()));
        };
        let Some(scan) = lending.plugin.next_scan().map_err(Failure::Failed)? else {
            *out_has_scan = 0;
            return Ok(());
        };
        lending.scan = scan;
        let scan = &lending.scan;
        *out_has_scan = 1;
        *out_scan = AbiScan {
            robot: scan.robot,
            sequence: scan.sequence,
            stamp_nanos: scan.stamp_nanos,
            points: scan.points.as_ptr(),
            point_count: scan.points.len(),
            imu: scan.imu.as_ptr(),
            imu_count: scan.imu.len(),
            has_ground_truth: u32::from(scan.ground_truth_world_from_sensor.is_some()),
            has_imu_from_sensor: u32::from(scan.imu_from_sensor.is_some()),
            ground_truth_world_from_sensor: scan
                .ground_truth_world_from_sensor
                .unwrap_or(AbiTransform::IDENTITY),
            imu_from_sensor: scan.imu_from_sensor.unwrap_or(AbiTransform::IDENTITY),
        };
        Ok(())
    })
}
