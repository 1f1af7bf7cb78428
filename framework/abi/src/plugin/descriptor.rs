//! The descriptor slot on the plugin side: the safe trait and the `extern "C"` functions of its table.

use skid_msgs::Point;

use super::glue::{Failure, create_with, destroy, guard, instance};
use super::{ConfigError, InstanceContext};
use crate::ffi::{AbiStr, DescriptorVTable, ErrorBuf, Handle, HostContext, Status};

/// A global place-recognition descriptor implemented in safe Rust, exported with
/// [`export_descriptor!`](crate::export_descriptor).
pub trait DescriptorPlugin: Sized + Send + 'static {
    /// The registry name, e.g. `ring_histogram`.
    const NAME: &'static str;
    /// One line for `skid plugins`.
    const SUMMARY: &'static str;
    /// The default parameters as TOML text; [`from_config`](Self::from_config) must accept it.
    const DEFAULT_CONFIG: &'static str;

    /// Builds an instance from TOML config text; missing keys take their defaults, unknown keys are
    /// an error.
    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError>;

    /// The number of values [`describe`](Self::describe) writes.
    fn descriptor_len(&self) -> usize;

    /// Describes a keyframe cloud (sensor frame) into `out`, which has exactly
    /// [`descriptor_len`](Self::descriptor_len) values.
    fn describe(&mut self, points: &[Point], out: &mut [f32]) -> Result<(), String>;
}

/// The descriptor function table of plugin type `T`.
pub const fn descriptor_vtable<T: DescriptorPlugin>() -> DescriptorVTable {
    DescriptorVTable {
        create: Some(create::<T>),
        descriptor_len: Some(descriptor_len::<T>),
        describe: Some(describe::<T>),
        destroy: Some(destroy::<T>),
    }
}

unsafe extern "C" fn create<T: DescriptorPlugin>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    // SAFETY: the host's pointers, passed on unchanged.
    unsafe { create_with(config, context, out_handle, error, T::from_config) }
}

unsafe extern "C" fn descriptor_len<T: DescriptorPlugin>(
    handle: Handle,
    out_len: *mut usize,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let plugin = unsafe { instance::<T>(handle) }?;
        if out_len.is_null() {
            return Err(Failure::InvalidArgument("descriptor_len: null output".to_owned()));
        }
        // SAFETY: `out_len` is non-null and points to a host-owned `usize`.
        unsafe { out_len.write(plugin.descriptor_len()) };
        Ok(())
    })
}

unsafe extern "C" fn describe<T: DescriptorPlugin>(
    handle: Handle,
    points: *const Point,
    count: usize,
    out: *mut f32,
    capacity: usize,
    out_len: *mut usize,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let plugin = unsafe { instance::<T>(handle) }?;
        if out_len.is_null() || (count > 0 && points.is_null()) {
            return Err(Failure::InvalidArgument(
                "describe: null points or length output".to_owned(),
            ));
        }
        let len = plugin.descriptor_len();
        // SAFETY: `out_len` is non-null and points to a host-owned `usize`.
        unsafe { out_len.write(len) };
        if capacity < len || (len > 0 && out.is_null()) {
            return Err(Failure::BufferTooSmall(format!(
                "describe: {len} values needed, room for {capacity}"
            )));
        }
        let points: &[Point] = if count == 0 {
            &[]
        } else {
            // SAFETY: the host passes `count` initialised, aligned points that it does not mutate
            // during this call; the layout is the same on both sides (checked by the fingerprint).
            unsafe { std::slice::from_raw_parts(points, count) }
        };
        let out: &mut [f32] = if len == 0 {
            &mut []
        } else {
            // SAFETY: `out` is non-null and writable for `capacity >= len` values owned by the host.
            unsafe { std::slice::from_raw_parts_mut(out, len) }
        };
        plugin.describe(points, out).map_err(Failure::Failed)
    })
}
