//! The descriptor slot on the plugin side: the safe trait and the `extern "C"` functions of its table.

use skid_msgs::Point;

use super::glue::{Failure, create_with, destroy, guard, instance, lent};
use super::{ConfigError, InstanceContext};
use crate::ffi::{
    AbiKeyframeId, AbiPlaceCandidate, AbiStr, DescriptorVTable, ErrorBuf, ExcludeFn, Handle, HostContext,
    Status,
};

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

    /// An empty retrieval index of the plugin's own; `None` (the default) lets the host retrieve by exact
    /// L2 distance.
    fn new_index(&self) -> Option<Box<dyn IndexPlugin>> {
        None
    }
}

/// The descriptor function table of plugin type `T`.
pub const fn descriptor_vtable<T: DescriptorPlugin>() -> DescriptorVTable {
    DescriptorVTable {
        create: Some(create::<T>),
        descriptor_len: Some(descriptor_len::<T>),
        describe: Some(describe::<T>),
        new_index: Some(new_index::<T>),
        index_insert: Some(index_insert),
        index_query: Some(index_query),
        index_len: Some(index_len),
        destroy_index: Some(destroy::<IndexLending>),
        destroy: Some(destroy::<T>),
    }
}

/// One keyframe an index retrieved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexCandidate {
    pub id: AbiKeyframeId,
    /// Smaller is more similar.
    pub distance: f64,
    /// The yaw of `candidate_from_query` in radians, when the descriptor can tell.
    pub yaw_hint_rad: Option<f64>,
}

/// A descriptor plugin's own retrieval index (for a distance other than L2, or a faster search).
pub trait IndexPlugin: Send + 'static {
    /// Stores a descriptor; one of another length is an error.
    fn insert(&mut self, id: AbiKeyframeId, values: &[f32]) -> Result<(), String>;

    /// The up to `k` most similar stored keyframes for which `exclude` is false, best first.
    fn query(
        &mut self,
        values: &[f32],
        k: usize,
        exclude: &dyn Fn(AbiKeyframeId) -> bool,
    ) -> Result<Vec<IndexCandidate>, String>;

    /// The number of stored descriptors.
    fn len(&self) -> usize;

    /// True when nothing is stored.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// An index and the candidates it last lent the host.
struct IndexLending {
    index: Box<dyn IndexPlugin>,
    candidates: Vec<AbiPlaceCandidate>,
}

unsafe extern "C" fn new_index<T: DescriptorPlugin>(
    handle: Handle,
    out_index: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let plugin = unsafe { instance::<T>(handle) }?;
        if out_index.is_null() {
            return Err(Failure::InvalidArgument("new_index: null output".to_owned()));
        }
        let index = plugin.new_index().map_or(std::ptr::null_mut(), |index| {
            Box::into_raw(Box::new(IndexLending {
                index,
                candidates: Vec::new(),
            }))
            .cast::<std::ffi::c_void>()
        });
        // SAFETY: `out_index` is non-null and points to a slot the host owns.
        unsafe { out_index.write(index) };
        Ok(())
    })
}

unsafe extern "C" fn index_insert(
    index: Handle,
    id: AbiKeyframeId,
    values: *const f32,
    len: usize,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live index handle from `new_index`, called from one thread at a time.
        let lending = unsafe { instance::<IndexLending>(index) }?;
        // SAFETY: the host's descriptor is valid for this call.
        let values = unsafe { lent(values, len, "descriptor values") }?;
        lending.index.insert(id, values).map_err(Failure::Failed)
    })
}

unsafe extern "C" fn index_query(
    index: Handle,
    values: *const f32,
    len: usize,
    k: usize,
    exclude: ExcludeFn,
    exclude_context: *const std::ffi::c_void,
    out_candidates: *mut *const AbiPlaceCandidate,
    out_count: *mut usize,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: a live index handle from `new_index`, called from one thread at a time.
        let lending = unsafe { instance::<IndexLending>(index) }?;
        // SAFETY: the host's descriptor is valid for this call.
        let values = unsafe { lent(values, len, "descriptor values") }?;
        // SAFETY: the host passes null or outputs it owns for this call.
        let (Some(out_candidates), Some(out_count)) =
            (unsafe { out_candidates.as_mut() }, unsafe { out_count.as_mut() })
        else {
            return Err(Failure::InvalidArgument("index_query: null output".to_owned()));
        };
        let excluded = |id: AbiKeyframeId| match exclude {
            // SAFETY: the host's callback and context are valid for this call and never unwind.
            Some(exclude) => (unsafe { exclude(exclude_context, id) }) != 0,
            None => false,
        };
        let found = lending
            .index
            .query(values, k, &excluded)
            .map_err(Failure::Failed)?;
        lending.candidates = found
            .into_iter()
            .take(k)
            .map(|candidate| AbiPlaceCandidate {
                id: candidate.id,
                distance: candidate.distance,
                has_yaw_hint: u32::from(candidate.yaw_hint_rad.is_some()),
                reserved: 0,
                yaw_hint_rad: candidate.yaw_hint_rad.unwrap_or(0.0),
            })
            .collect();
        *out_candidates = lending.candidates.as_ptr();
        *out_count = lending.candidates.len();
        Ok(())
    })
}

unsafe extern "C" fn index_len(index: Handle, out_len: *mut usize, error: *mut ErrorBuf) -> Status {
    guard(error, || {
        // SAFETY: a live index handle from `new_index`, called from one thread at a time.
        let lending = unsafe { instance::<IndexLending>(index) }?;
        // SAFETY: the host passes null or a `usize` it owns for this call.
        let out_len = unsafe { out_len.as_mut() }
            .ok_or_else(|| Failure::InvalidArgument("index_len: null output".to_owned()))?;
        *out_len = lending.index.len();
        Ok(())
    })
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
