//! One call into a plugin: the host-owned error buffers, the mapping of a status to an error, and the
//! `create` and `destroy` calls every slot shares.

use std::ffi::c_void;
use std::ptr::NonNull;

use skid_core::{ParamError, Params, PluginContext, PluginError};

use super::library::PluginSpec;
use crate::ffi::{AbiStr, Checked, CreateFn, DestroyFn, ErrorBuf, Handle, HostContext, Status};

/// Room for an error message; longer messages are cut by the plugin.
const MESSAGE_CAPACITY: usize = 4096;
/// Room for the dotted path of an offending config key.
const KEY_CAPACITY: usize = 512;

/// What a failed call reported.
#[derive(Debug)]
pub(crate) struct CallError {
    pub(crate) status: Status,
    pub(crate) key: String,
    pub(crate) message: String,
}

impl CallError {
    /// The skid-core error for this failure in plugin `plugin`.
    pub(crate) fn into_plugin_error(self, plugin: &str) -> PluginError {
        match self.status {
            Status::CONFIG => PluginError::Params(self.into_param_error(plugin)),
            Status::PANICKED => PluginError::Panicked {
                plugin: plugin.to_owned(),
                message: self.message,
            },
            Status::FAILED => PluginError::failed(plugin, self.message),
            Status::BUFFER_TOO_SMALL | Status::INVALID_ARGUMENT => PluginError::failed(
                plugin,
                format!("ABI misuse (status {}): {}", self.status.0, self.message),
            ),
            Status(other) => PluginError::failed(plugin, format!("unknown status {other}: {}", self.message)),
        }
    }

    /// The parameter error for this failure; failures other than a refused config name the status.
    pub(crate) fn into_param_error(self, plugin: &str) -> ParamError {
        match self.status {
            Status::CONFIG => ParamError {
                path: self.key,
                message: self.message,
            },
            Status::PANICKED => ParamError {
                path: String::new(),
                message: format!(
                    "plugin `{plugin}` panicked while reading its parameters: {}",
                    self.message
                ),
            },
            _ => ParamError {
                path: String::new(),
                message: format!(
                    "plugin `{plugin}` failed while reading its parameters: {}",
                    self.message
                ),
            },
        }
    }
}

/// Host-allocated buffers for one call's error report.
pub(crate) struct ErrorSlot {
    message: Vec<u8>,
    key: Vec<u8>,
    raw: ErrorBuf,
}

impl ErrorSlot {
    pub(crate) fn new() -> Self {
        let mut message = vec![0_u8; MESSAGE_CAPACITY];
        let mut key = vec![0_u8; KEY_CAPACITY];
        let raw = ErrorBuf {
            message: message.as_mut_ptr(),
            message_capacity: message.len(),
            message_len: 0,
            key: key.as_mut_ptr(),
            key_capacity: key.len(),
            key_len: 0,
        };
        // Moving the vectors into the struct moves only their headers; the heap buffers stay put.
        Self { message, key, raw }
    }

    /// The pointer to pass to the plugin.
    pub(crate) fn as_mut_ptr(&mut self) -> *mut ErrorBuf {
        &mut self.raw
    }

    /// `Ok` for [`Status::OK`], otherwise the error the plugin wrote.
    pub(crate) fn result(&self, status: Status) -> Result<(), CallError> {
        if status == Status::OK {
            return Ok(());
        }
        let text =
            |bytes: &[u8], len: usize| String::from_utf8_lossy(&bytes[..len.min(bytes.len())]).into_owned();
        Err(CallError {
            status,
            key: text(&self.key, self.raw.key_len),
            message: text(&self.message, self.raw.message_len),
        })
    }
}

/// Calls a plugin's `create` with `params` as TOML and `context`.
pub(crate) fn create_instance(
    plugin: &PluginSpec,
    create: Checked<CreateFn>,
    params: &Params,
    context: &PluginContext,
) -> Result<NonNull<c_void>, CallError> {
    let config = params.to_toml_string();
    let output_dir = context
        .output_dir
        .as_ref()
        .and_then(|dir| dir.to_str())
        .unwrap_or("");
    let host_context = HostContext {
        robot: context.robot.0,
        fleet_size: context.fleet_size,
        threads: u32::try_from(context.threads.max(1)).unwrap_or(u32::MAX),
        reserved: 0,
        seed: context.seed,
        output_dir: AbiStr::borrowed(output_dir),
    };
    let mut handle: Handle = std::ptr::null_mut();
    let mut error = ErrorSlot::new();
    let _serial = plugin.serialise();
    // SAFETY: every pointer is to host data valid for the whole call; `create` is a checked, non-null
    // function of a library that stays loaded.
    let status = unsafe {
        create(
            AbiStr::borrowed(&config),
            &host_context,
            &mut handle,
            error.as_mut_ptr(),
        )
    };
    error.result(status)?;
    NonNull::new(handle).ok_or_else(|| CallError {
        status: Status::FAILED,
        key: String::new(),
        message: format!(
            "`{}`: create reported success but returned a null handle",
            plugin.name
        ),
    })
}

/// Calls a plugin's `destroy`; a failure there can only be logged.
pub(crate) fn destroy_instance(plugin: &PluginSpec, destroy: Checked<DestroyFn>, handle: NonNull<c_void>) {
    let mut error = ErrorSlot::new();
    let _serial = plugin.serialise();
    // SAFETY: the handle came from this plugin's `create` and is destroyed exactly once.
    let status = unsafe { destroy(handle.as_ptr(), error.as_mut_ptr()) };
    if let Err(error) = error.result(status) {
        tracing::warn!(target: "skid::plugin", plugin = %plugin.name, "destroying an instance failed: {}", error.message);
    }
}

/// Checks parameters by creating an instance (with a default context) and destroying it again.
pub(crate) fn validate_params(
    plugin: &PluginSpec,
    create: Checked<CreateFn>,
    destroy: Checked<DestroyFn>,
    params: &Params,
) -> Result<(), ParamError> {
    create_instance(plugin, create, params, &PluginContext::default())
        .map(|handle| destroy_instance(plugin, destroy, handle))
        .map_err(|error| error.into_param_error(&plugin.name))
}

/// A copy of `count` values a plugin lent at `pointer`. A buffer not aligned to `T` (a C plugin's packed
/// array) is copied value by value with unaligned reads, never read in place.
///
/// # Safety
///
/// `pointer` must point to `count` initialised values when `count` is not zero.
pub(crate) unsafe fn copy_lent<T: Copy>(pointer: *const T, count: usize) -> Vec<T> {
    if count == 0 {
        return Vec::new();
    }
    if pointer.is_aligned() {
        // SAFETY: the caller's guarantee, and the pointer is aligned.
        unsafe { std::slice::from_raw_parts(pointer, count) }.to_vec()
    } else {
        // SAFETY: the caller's guarantee; each value is read without assuming alignment.
        (0..count)
            .map(|index| unsafe { pointer.add(index).read_unaligned() })
            .collect()
    }
}
