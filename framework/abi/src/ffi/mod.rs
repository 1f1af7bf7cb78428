//! The `#[repr(C)]` types that cross the plugin boundary, shared verbatim by the plugin and the host.
//!
//! The entry symbol [`ENTRY_SYMBOL`](crate::ENTRY_SYMBOL) returns a pointer to a static [`LibraryDecl`],
//! which lists the library's plugins as [`PluginDecl`]s. Its first three fields (ABI version at offset 0, layout fingerprint at offset 8, framework version at
//! offset 16) keep their place in every ABI version, so a host can refuse a plugin from another version
//! without reading anything else. The slot-specific function table sits behind an untyped pointer whose
//! type [`SlotKind`] names, so new slots add a kind and a table without touching the declaration.
//!
//! Function-pointer types are `Option`s (nullable, as a C function pointer is) so that a null pointer from
//! a foreign plugin is an error the host can report rather than undefined behaviour; [`Checked`] names
//! the function type inside once the host has checked it.

mod backend;
mod descriptor;
mod frontend;
mod registration;
mod verifier;

use std::ffi::c_void;

pub use backend::{
    AbiOptimizeReport, AbiPrior, AddEdgeFn, AddKeyframeFn, AddPriorFn, BackendListsFn, BackendOdometryFn,
    BackendPoseFn, BackendVTable, OptimizeFn, RejectedLoopsFn, RemoveLoopFn,
};
pub use descriptor::{
    AbiPlaceCandidate, DescribeFn, DescriptorLenFn, DescriptorVTable, ExcludeFn, IndexInsertFn, IndexLenFn,
    IndexQueryFn, NewIndexFn,
};
pub use frontend::{
    AbiScan, NextScanFn, OdometryResult, OdometryVTable, RegisterFn, SourceInfo, SourceInfoFn, SourceVTable,
};
pub use registration::{
    AbiCloud, AbiTransform, AlignFn, CoarseResult, CoarseVTable, DestroyPreparedFn, FineResult, FineVTable,
    PrepareFn, PreparedPointsFn, RefineFn, TextBuf,
};
pub use verifier::{
    AbiGraph, AbiKeyframeId, AbiLoop, AbiRejection, AbiRelativePose, AbiVerdict, GraphOdometryFn,
    GraphPoseFn, SubmitFn, VerifierVTable,
};

/// A borrowed UTF-8 string: pointer and length in bytes, not NUL-terminated.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiStr {
    pub ptr: *const u8,
    pub len: usize,
}

impl AbiStr {
    /// A string that lives for the whole program, such as a plugin's name.
    pub const fn from_static(text: &'static str) -> Self {
        Self {
            ptr: text.as_ptr(),
            len: text.len(),
        }
    }

    /// A string borrowed for the duration of one call.
    pub const fn borrowed(text: &str) -> Self {
        Self {
            ptr: text.as_ptr(),
            len: text.len(),
        }
    }

    /// The bytes as a string slice, or `None` when the pointer is null or the bytes are not UTF-8.
    ///
    /// # Safety
    ///
    /// `ptr` must be null or point to `len` initialised bytes that stay valid and unchanged for `'a`.
    pub unsafe fn to_str<'a>(self) -> Option<&'a str> {
        if self.len == 0 {
            return Some("");
        }
        if self.ptr.is_null() {
            return None;
        }
        // SAFETY: the caller guarantees `len` readable bytes at a non-null `ptr` for `'a`.
        let bytes = unsafe { std::slice::from_raw_parts(self.ptr, self.len) };
        std::str::from_utf8(bytes).ok()
    }
}

/// The outcome of every exported call.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Status(pub i32);

impl Status {
    /// The call succeeded.
    pub const OK: Status = Status(0);
    /// The config string was rejected; the error buffer holds the offending key and the reason.
    pub const CONFIG: Status = Status(1);
    /// The plugin failed for a reason of its own; the error buffer holds the message.
    pub const FAILED: Status = Status(2);
    /// The plugin panicked; the panic was caught and its message is in the error buffer.
    pub const PANICKED: Status = Status(3);
    /// The output buffer is too small; the length output holds the length needed.
    pub const BUFFER_TOO_SMALL: Status = Status(4);
    /// A pointer or handle argument was null or otherwise unusable.
    pub const INVALID_ARGUMENT: Status = Status(5);
}

/// Host-allocated buffers into which the plugin copies an error message and, for config errors, the
/// dotted path of the offending key. The plugin writes at most the capacity (cutting at a character
/// boundary) and stores the written length; it never allocates or frees these buffers. The host passes
/// one, never null, to every call (4096 bytes for the message, 512 for the key).
#[repr(C)]
#[derive(Debug)]
pub struct ErrorBuf {
    pub message: *mut u8,
    pub message_capacity: usize,
    pub message_len: usize,
    pub key: *mut u8,
    pub key_capacity: usize,
    pub key_len: usize,
}

/// What the host tells a plugin instance about where it runs (mirrors skid-core's `PluginContext`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct HostContext {
    /// The robot this instance serves.
    pub robot: u32,
    /// Number of robots in the fleet.
    pub fleet_size: u32,
    /// Threads the instance may use; at least 1.
    pub threads: u32,
    /// Explicit padding.
    pub reserved: u32,
    /// Seed for anything random.
    pub seed: u64,
    /// Output folder as UTF-8, empty when there is none. Valid only during the `create` call.
    pub output_dir: AbiStr,
}

/// Which slot a plugin fills, and so which table [`PluginDecl::slot_table`] points to.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotKind(pub u32);

impl SlotKind {
    /// The table is a [`SourceVTable`].
    pub const SOURCE: SlotKind = SlotKind(1);
    /// The table is an [`OdometryVTable`].
    pub const ODOMETRY: SlotKind = SlotKind(2);
    /// The table is a [`DescriptorVTable`].
    pub const DESCRIPTOR: SlotKind = SlotKind(3);
    /// The table is a [`CoarseVTable`].
    pub const COARSE: SlotKind = SlotKind(4);
    /// The table is a [`FineVTable`].
    pub const FINE: SlotKind = SlotKind(5);
    /// The table is a [`VerifierVTable`].
    pub const VERIFIER: SlotKind = SlotKind(6);
    /// The table is a [`BackendVTable`].
    pub const BACKEND: SlotKind = SlotKind(7);
    /// Reserved: transports do not cross the C boundary (a robot's network link stays in the host), so
    /// no plugin may declare this kind and it has no table.
    pub const TRANSPORT: SlotKind = SlotKind(8);
}

/// What a plugin's code tolerates from threads, declared per plugin.
///
/// SKiD calls one instance from one thread at a time, but it moves instances between threads (each
/// robot's stages run on worker threads) and, with several robots in one process, runs different
/// instances of the same plugin at the same time.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Threading(pub u32);

impl Threading {
    /// Instances share nothing mutable: any instance may be called from any thread, and different
    /// instances may run at the same time. Every Rust plugin is this (the slot traits are `Send` and
    /// statics are `Sync`).
    pub const INDEPENDENT_INSTANCES: Threading = Threading(0);
    /// The plugin keeps mutable state shared by its instances (globals, a library that is not
    /// re-entrant): the host serialises every call to any of its instances, `create` and `destroy`
    /// included, so that at most one runs at a time in the process.
    pub const SERIAL: Threading = Threading(1);
    /// An instance must only ever be called from the thread that created it (thread-local state, a
    /// thread-bound interpreter or context). SKiD moves instances between threads, so the host
    /// refuses such a plugin when it loads the library.
    pub const PINNED_TO_CREATING_THREAD: Threading = Threading(2);
}

/// Log levels on the wire: 1 = error, 2 = warn, 3 = info, 4 = debug, 5 = trace.
pub mod level {
    pub const ERROR: u32 = 1;
    pub const WARN: u32 = 2;
    pub const INFO: u32 = 3;
    pub const DEBUG: u32 = 4;
    pub const TRACE: u32 = 5;
}

/// The host's logging callback: level, the library's name, the event's target, the formatted message.
/// The strings are valid only during the call.
pub type LogFn = Option<unsafe extern "C" fn(level: u32, library: AbiStr, target: AbiStr, message: AbiStr)>;

/// The host's filter: whether an event of this level and target would be recorded.
pub type EnabledFn = Option<unsafe extern "C" fn(level: u32, target: AbiStr) -> bool>;

/// Installs the host's logging callbacks as the plugin's `tracing` subscriber (once per library).
pub type SetLoggerFn = Option<unsafe extern "C" fn(log: LogFn, enabled: EnabledFn) -> Status>;

/// The static declaration a library's entry symbol returns: the version prefix, then the plugins it holds.
#[repr(C)]
#[derive(Debug)]
pub struct LibraryDecl {
    /// [`ABI_VERSION`](crate::ABI_VERSION) of the skid-abi the library was built with. Offset 0, forever.
    pub abi_version: u32,
    /// Explicit padding.
    pub reserved: u32,
    /// `skid_msgs::LAYOUT_FINGERPRINT` of the library's build. Offset 8, forever.
    pub layout_fingerprint: u64,
    /// Version of the skid-abi crate the library was built with. Offset 16, forever.
    pub framework_version: AbiStr,
    /// The library's own name (its crate or project), for logs.
    pub name: AbiStr,
    /// Installs the host's logging callbacks; may be null for a library that does not log.
    pub set_logger: SetLoggerFn,
    /// The number of entries behind [`plugins`](Self::plugins); at least one.
    pub plugin_count: usize,
    /// The plugins the library provides, one declaration each.
    pub plugins: *const PluginDecl,
}

// SAFETY: a library declaration holds only pointers to immutable `'static` data (string literals, the
// static array of plugin declarations) and function pointers, so sharing it between threads is sound.
unsafe impl Sync for LibraryDecl {}

/// The declaration of one plugin in a library.
#[repr(C)]
#[derive(Debug)]
pub struct PluginDecl {
    /// The slot the plugin fills.
    pub slot_kind: SlotKind,
    /// What the plugin's code tolerates from threads; zero (the padding of ABI 2.0) is
    /// [`Threading::INDEPENDENT_INSTANCES`].
    pub threading: Threading,
    /// The registry name.
    pub name: AbiStr,
    /// One line for `skid plugins`.
    pub summary: AbiStr,
    /// The default parameters as TOML text.
    pub default_config: AbiStr,
    /// Points to the slot's function table: a [`SourceVTable`], [`OdometryVTable`], [`DescriptorVTable`],
    /// [`CoarseVTable`], [`FineVTable`], [`VerifierVTable`] or [`BackendVTable`] as
    /// [`slot_kind`](Self::slot_kind) says.
    pub slot_table: *const c_void,
}

// SAFETY: a declaration holds only pointers to immutable `'static` data (string literals and a static
// function table) and function pointers, so sharing it between threads is sound.
unsafe impl Sync for PluginDecl {}

/// The function type inside one of the nullable function-pointer aliases (`CreateFn`, …): what a
/// table entry is once checked non-null.
pub type Checked<F> = <F as NullableFn>::Fn;

/// Names the function type inside a nullable function-pointer alias.
pub trait NullableFn {
    type Fn: Copy;
}

impl<F: Copy> NullableFn for Option<F> {
    type Fn = F;
}

/// An opaque instance handle, owned by the plugin; the host only passes it back.
pub type Handle = *mut c_void;

/// Builds an instance from a UTF-8 TOML config string and the host context. The string is the plugin's
/// own table from the run's configuration (`[<slot>.<name>]`, without the header), the plugin's
/// `default_config` laid under it, so every key is present. `skid config check` and the loading of a
/// configuration call `create` once to check the table and `destroy` the instance straight away: refuse a
/// bad value with SkidStatus_CONFIG (the key in the error buffer) and start nothing that outlives
/// `destroy`.
pub type CreateFn = Option<
    unsafe extern "C" fn(
        config: AbiStr,
        context: *const HostContext,
        out_handle: *mut Handle,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// Drops an instance; the handle is invalid afterwards whatever the status.
pub type DestroyFn = Option<unsafe extern "C" fn(handle: Handle, error: *mut ErrorBuf) -> Status>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_version_prefix_never_moves() {
        assert_eq!(std::mem::offset_of!(LibraryDecl, abi_version), 0);
        assert_eq!(std::mem::offset_of!(LibraryDecl, layout_fingerprint), 8);
        assert_eq!(std::mem::offset_of!(LibraryDecl, framework_version), 16);
    }

    #[test]
    fn abi_str_round_trips() {
        let text = AbiStr::from_static("ring_histogram");
        // SAFETY: the string is a literal.
        assert_eq!(unsafe { text.to_str() }, Some("ring_histogram"));
        let null = AbiStr {
            ptr: std::ptr::null(),
            len: 3,
        };
        // SAFETY: a null pointer is checked before any read.
        assert_eq!(unsafe { null.to_str() }, None);
    }
}
