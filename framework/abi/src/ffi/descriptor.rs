//! The descriptor slot's function table: describing a cloud into a host buffer, and optionally the
//! plugin's own retrieval index (insert, query with an exclusion callback, length), whose query results
//! the plugin lends until its next call. A plugin without an index of its own answers `new_index` with a
//! null handle, and the host retrieves its descriptors by exact L2 distance.

use std::ffi::c_void;

use skid_msgs::Point;

use super::verifier::AbiKeyframeId;
use super::{CreateFn, DestroyFn, ErrorBuf, Handle, Status};

/// The length of the descriptor this instance produces.
pub type DescriptorLenFn =
    Option<unsafe extern "C" fn(handle: Handle, out_len: *mut usize, error: *mut ErrorBuf) -> Status>;

/// Describes `count` points into `out` (capacity `capacity` values); stores the length written, or the
/// length needed with [`Status::BUFFER_TOO_SMALL`].
pub type DescribeFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        points: *const Point,
        count: usize,
        out: *mut f32,
        capacity: usize,
        out_len: *mut usize,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// Makes an empty index for this instance's descriptors; a null `out_index` means "use the host's".
pub type NewIndexFn =
    Option<unsafe extern "C" fn(handle: Handle, out_index: *mut Handle, error: *mut ErrorBuf) -> Status>;

/// Stores a descriptor under a keyframe id; a descriptor of another length is an error.
pub type IndexInsertFn = Option<
    unsafe extern "C" fn(
        index: Handle,
        id: AbiKeyframeId,
        values: *const f32,
        len: usize,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The host's exclusion test during a query: non-zero when the keyframe must not be returned.
pub type ExcludeFn = Option<unsafe extern "C" fn(context: *const c_void, id: AbiKeyframeId) -> u32>;

/// One retrieved keyframe.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiPlaceCandidate {
    pub id: AbiKeyframeId,
    /// Descriptor distance as the plugin defines it; smaller is more similar.
    pub distance: f64,
    /// Non-zero when `yaw_hint_rad` holds the yaw of `candidate_from_query`.
    pub has_yaw_hint: u32,
    /// Explicit padding.
    pub reserved: u32,
    pub yaw_hint_rad: f64,
}

/// The up to `k` most similar stored keyframes that `exclude` lets through, best first, lent until the
/// next call on the index.
pub type IndexQueryFn = Option<
    unsafe extern "C" fn(
        index: Handle,
        values: *const f32,
        len: usize,
        k: usize,
        exclude: ExcludeFn,
        exclude_context: *const c_void,
        out_candidates: *mut *const AbiPlaceCandidate,
        out_count: *mut usize,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The number of stored descriptors.
pub type IndexLenFn =
    Option<unsafe extern "C" fn(index: Handle, out_len: *mut usize, error: *mut ErrorBuf) -> Status>;

/// The descriptor slot's function table ([`SlotKind::DESCRIPTOR`](super::SlotKind::DESCRIPTOR)). The
/// index entries are required even for a plugin without an index: its `new_index` returns null.
#[repr(C)]
#[derive(Debug)]
pub struct DescriptorVTable {
    pub create: CreateFn,
    pub descriptor_len: DescriptorLenFn,
    pub describe: DescribeFn,
    pub new_index: NewIndexFn,
    pub index_insert: IndexInsertFn,
    pub index_query: IndexQueryFn,
    pub index_len: IndexLenFn,
    pub destroy_index: DestroyFn,
    pub destroy: DestroyFn,
}
