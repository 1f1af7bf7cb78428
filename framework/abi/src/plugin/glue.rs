//! What every slot's `extern "C"` functions share: the call guard, error and text copying, instance
//! creation and destruction, the logger installer and the library declaration. The functions are generic
//! over the plugin type and instantiated in the plugin's own crate by the export macro.
//!
//! Each exported function runs the plugin's safe code under `catch_unwind`, turns any failure into a
//! [`Status`] plus a message copied into the host's [`ErrorBuf`], and never lets a panic cross the C
//! boundary.

use std::any::Any;
use std::ffi::c_void;
use std::panic::{AssertUnwindSafe, catch_unwind};

use super::{ConfigError, InstanceContext};
use super::{logger, panic_hook};
use crate::ffi::{
    AbiStr, EnabledFn, ErrorBuf, Handle, HostContext, LibraryDecl, LogFn, PluginDecl, SlotKind, Status,
    TextBuf, Threading,
};

/// A failure inside an exported call, before it is flattened into a status and the error buffer.
pub(super) enum Failure {
    Config(ConfigError),
    Failed(String),
    BufferTooSmall(String),
    InvalidArgument(String),
}

/// The name of the library, for the logger: the export macro implements it for a marker type with the
/// plugin crate's package name.
pub trait LibraryName {
    const NAME: &'static str;
}

/// The declaration of a library holding `plugins`.
pub const fn library_decl<L: LibraryName>(plugins: &'static [PluginDecl]) -> LibraryDecl {
    LibraryDecl {
        abi_version: crate::ABI_VERSION,
        reserved: 0,
        layout_fingerprint: skid_msgs::LAYOUT_FINGERPRINT,
        framework_version: AbiStr::from_static(crate::FRAMEWORK_VERSION),
        name: AbiStr::from_static(L::NAME),
        set_logger: Some(set_logger::<L>),
        plugin_count: plugins.len(),
        plugins: plugins.as_ptr(),
    }
}

/// The declaration of one plugin whose function table of kind `slot_kind` is `table`.
pub const fn plugin_decl<T>(
    slot_kind: SlotKind,
    name: &'static str,
    summary: &'static str,
    default_config: &'static str,
    table: &'static T,
) -> PluginDecl {
    PluginDecl {
        slot_kind,
        threading: Threading::INDEPENDENT_INSTANCES,
        name: AbiStr::from_static(name),
        summary: AbiStr::from_static(summary),
        default_config: AbiStr::from_static(default_config),
        slot_table: (table as *const T).cast::<c_void>(),
    }
}

/// Runs `call` with panics caught, and reports its outcome through `error`.
pub(super) fn guard(error: *mut ErrorBuf, call: impl FnOnce() -> Result<(), Failure>) -> Status {
    let scope = panic_hook::enter_call();
    let (status, key, message) = match catch_unwind(AssertUnwindSafe(call)) {
        Ok(Ok(())) => return Status::OK,
        Ok(Err(Failure::Config(config))) => (Status::CONFIG, config.key, config.message),
        Ok(Err(Failure::Failed(message))) => (Status::FAILED, String::new(), message),
        Ok(Err(Failure::BufferTooSmall(message))) => (Status::BUFFER_TOO_SMALL, String::new(), message),
        Ok(Err(Failure::InvalidArgument(message))) => (Status::INVALID_ARGUMENT, String::new(), message),
        Err(payload) => {
            let message = panic_message(payload);
            let message = match scope.take_location() {
                Some(location) => format!("{message} (at {location})"),
                None => message,
            };
            (Status::PANICKED, String::new(), message)
        }
    };
    drop(scope);
    // Writing the error only copies bytes, but stay defensive: nothing may unwind out of here.
    // SAFETY: the host passes null or a valid `ErrorBuf` describing buffers it owns for this call.
    let _ = catch_unwind(AssertUnwindSafe(|| unsafe { write_error(error, &key, &message) }));
    status
}

/// The text of a panic payload; dropping the payload is itself guarded, as its destructor may panic.
fn panic_message(payload: Box<dyn Any + Send>) -> String {
    let message = if let Some(text) = payload.downcast_ref::<&str>() {
        (*text).to_owned()
    } else if let Some(text) = payload.downcast_ref::<String>() {
        text.clone()
    } else {
        "a panic with a non-string payload".to_owned()
    };
    if let Err(nested) = catch_unwind(AssertUnwindSafe(move || drop(payload))) {
        std::mem::forget(nested);
    }
    message
}

/// The longest prefix of `text` of at most `capacity` bytes that ends on a character boundary.
fn truncated(text: &str, capacity: usize) -> &str {
    let mut end = capacity.min(text.len());
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    &text[..end]
}

/// Copies `key` and `message` into the host's buffers, cut to their capacities.
///
/// # Safety
///
/// `error` must be null or point to a valid `ErrorBuf` whose non-null buffers are writable for their
/// stated capacities.
unsafe fn write_error(error: *mut ErrorBuf, key: &str, message: &str) {
    // SAFETY: the caller guarantees `error` is null or valid and exclusively ours for this call.
    let Some(error) = (unsafe { error.as_mut() }) else {
        return;
    };
    for (text, buffer, capacity, len) in [
        (
            message,
            error.message,
            error.message_capacity,
            &mut error.message_len,
        ),
        (key, error.key, error.key_capacity, &mut error.key_len),
    ] {
        *len = 0;
        if buffer.is_null() {
            continue;
        }
        let text = truncated(text, capacity);
        // SAFETY: `buffer` is writable for `capacity >= text.len()` bytes and cannot overlap `text`,
        // which lives in this library's memory.
        unsafe { std::ptr::copy_nonoverlapping(text.as_ptr(), buffer, text.len()) };
        *len = text.len();
    }
}

/// A borrowed slice from a pointer and a count the host passed; null is allowed for an empty slice only.
///
/// # Safety
///
/// `pointer` must be null or point to `count` initialised values valid for `'a`.
pub(super) unsafe fn lent<'a, V>(pointer: *const V, count: usize, what: &str) -> Result<&'a [V], Failure> {
    if count == 0 {
        return Ok(&[]);
    }
    if pointer.is_null() {
        return Err(Failure::InvalidArgument(format!(
            "{count} {what} at a null pointer"
        )));
    }
    // SAFETY: the caller's guarantee.
    Ok(unsafe { std::slice::from_raw_parts(pointer, count) })
}

/// Copies `text` into a host-owned text buffer, cut to its capacity at a character boundary.
///
/// # Safety
///
/// `buffer.ptr` must be null or writable for `buffer.capacity` bytes.
pub(super) unsafe fn write_text(buffer: &mut TextBuf, text: &str) {
    buffer.len = 0;
    if buffer.ptr.is_null() {
        return;
    }
    let text = truncated(text, buffer.capacity);
    // SAFETY: `ptr` is writable for `capacity >= text.len()` bytes (the caller's guarantee) and cannot
    // overlap `text`, which lives in this library's memory.
    unsafe { std::ptr::copy_nonoverlapping(text.as_ptr(), buffer.ptr, text.len()) };
    buffer.len = text.len();
}

/// Installs the host's logging callbacks (see [`logger`]).
unsafe extern "C" fn set_logger<L: LibraryName>(log: LogFn, enabled: EnabledFn) -> Status {
    guard(std::ptr::null_mut(), || match (log, enabled) {
        (Some(log), Some(enabled)) => {
            logger::install(L::NAME, log, enabled);
            Ok(())
        }
        _ => Err(Failure::InvalidArgument(
            "set_logger needs both callbacks".to_owned(),
        )),
    })
}

/// The body of every slot's `create`: reads the config and context, builds the instance with `build`
/// and hands the host a boxed handle.
///
/// # Safety
///
/// The pointers must be as the host passes them to `create`: null or valid for the call.
pub(super) unsafe fn create_with<T: Send + 'static>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
    build: fn(&str, &InstanceContext) -> Result<T, ConfigError>,
) -> Status {
    guard(error, || {
        if out_handle.is_null() {
            return Err(Failure::InvalidArgument("create: null output handle".to_owned()));
        }
        // SAFETY: the host passes a config string that stays valid for the duration of this call.
        let config = unsafe { config.to_str() }
            .ok_or_else(|| Failure::InvalidArgument("create: the config is not UTF-8".to_owned()))?;
        // SAFETY: the host passes null or a context valid for the duration of this call.
        let context = unsafe { context.as_ref() }
            .ok_or_else(|| Failure::InvalidArgument("create: null context".to_owned()))?;
        // SAFETY: as above, the output-folder string is valid during this call.
        let output_dir = unsafe { context.output_dir.to_str() }
            .filter(|dir| !dir.is_empty())
            .map(str::to_owned);
        let context = InstanceContext {
            robot: context.robot,
            fleet_size: context.fleet_size,
            threads: (context.threads as usize).max(1),
            seed: context.seed,
            output_dir,
        };
        let plugin = build(config, &context).map_err(Failure::Config)?;
        let handle = Box::into_raw(Box::new(plugin)).cast::<c_void>();
        // SAFETY: `out_handle` is non-null and points to a slot the host owns.
        unsafe { out_handle.write(handle) };
        Ok(())
    })
}

/// The instance behind a handle.
///
/// # Safety
///
/// `handle` must be null or come from `create::<T>` and not have been destroyed, and no other
/// reference to the instance may be live.
pub(super) unsafe fn instance<'a, T>(handle: Handle) -> Result<&'a mut T, Failure> {
    // SAFETY: guaranteed by the caller; the host serialises calls on one handle (`&mut self`).
    unsafe { handle.cast::<T>().as_mut() }.ok_or_else(|| Failure::InvalidArgument("null handle".to_owned()))
}

/// Drops the instance behind a handle of type `T`.
pub(super) unsafe extern "C" fn destroy<T: Send + 'static>(handle: Handle, error: *mut ErrorBuf) -> Status {
    guard(error, || {
        if handle.is_null() {
            return Err(Failure::InvalidArgument("destroy: null handle".to_owned()));
        }
        // SAFETY: the handle came from `Box::into_raw` in `create::<T>` and the host destroys it once.
        drop(unsafe { Box::from_raw(handle.cast::<T>()) });
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncation_respects_char_boundaries() {
        assert_eq!(truncated("héllo", 2), "h");
        assert_eq!(truncated("héllo", 3), "hé");
        assert_eq!(truncated("abc", 10), "abc");
    }

    #[test]
    fn guard_catches_panics_and_copies_the_message() {
        let mut message = vec![0_u8; 8];
        let mut error = ErrorBuf {
            message: message.as_mut_ptr(),
            message_capacity: message.len(),
            message_len: 0,
            key: std::ptr::null_mut(),
            key_capacity: 0,
            key_len: 0,
        };
        let status = guard(&mut error, || panic!("boom at the boundary"));
        assert_eq!(status, Status::PANICKED);
        assert_eq!(&message[..error.message_len], b"boom at ");
    }
}
