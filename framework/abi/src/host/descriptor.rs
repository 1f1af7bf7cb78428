//! A dynamic descriptor plugin seen through skid-core's [`Descriptor`] trait, and its registry entry.

use std::ffi::c_void;
use std::ptr::NonNull;

use skid_core::slots::{Descriptor, DescriptorBuf, DescriptorIndex};
use skid_core::{CloudView, ParamError, Params, PluginContext, PluginEntry, PluginError, PluginResult};

use super::call::{CallError, ErrorSlot};
use super::index::ExactL2Index;
use super::library::Library;
use crate::ffi::{AbiStr, Handle, HostContext, Status};

/// The registry entry of a loaded descriptor library.
pub(super) fn entry(library: &'static Library) -> PluginEntry<dyn Descriptor> {
    PluginEntry::from_parts(
        &library.name,
        &library.summary,
        &library.path.display().to_string(),
        library.defaults.clone(),
        move |params: &Params| validate(library, params),
        move |params: &Params, context: &PluginContext| {
            DynDescriptor::create(library, params, context)
                .map(|descriptor| Box::new(descriptor) as Box<dyn Descriptor>)
        },
    )
}

/// Checks parameters by creating an instance (with a default context) and destroying it.
pub(super) fn validate(library: &'static Library, params: &Params) -> Result<(), ParamError> {
    create_handle(library, params, &PluginContext::default())
        .map(|handle| destroy_handle(library, handle))
        .map_err(|error| error.into_param_error(&library.name))
}

/// Calls the plugin's `create`.
fn create_handle(
    library: &'static Library,
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
    // SAFETY: every pointer is to host data valid for the whole call; `create` is a checked, non-null
    // function of a library that stays loaded.
    let status = unsafe {
        (library.descriptor.create)(
            AbiStr::borrowed(&config),
            &host_context,
            &mut handle,
            error.as_mut_ptr(),
        )
    };
    error.result(status)?;
    NonNull::new(handle).ok_or(CallError {
        status: Status::FAILED,
        key: String::new(),
        message: "create reported success but returned a null handle".to_owned(),
    })
}

/// Calls the plugin's `destroy`; a failure there can only be logged.
fn destroy_handle(library: &'static Library, handle: NonNull<c_void>) {
    let mut error = ErrorSlot::new();
    // SAFETY: the handle came from this library's `create` and is destroyed exactly once.
    let status = unsafe { (library.descriptor.destroy)(handle.as_ptr(), error.as_mut_ptr()) };
    if let Err(error) = error.result(status) {
        tracing::warn!(target: "skid::plugin", plugin = %library.name, "destroying an instance failed: {}", error.message);
    }
}

/// An instance of a dynamically loaded descriptor plugin.
///
/// After the plugin panics in a call, the instance refuses further calls (its state may be broken);
/// create a fresh one.
pub struct DynDescriptor {
    handle: NonNull<c_void>,
    library: &'static Library,
    poisoned: bool,
}

// SAFETY: the plugin type behind the handle is `Send` (required by `DescriptorPlugin`), the library's
// function table is immutable static data, and `&mut self` serialises every call on one instance.
unsafe impl Send for DynDescriptor {}

impl std::fmt::Debug for DynDescriptor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DynDescriptor")
            .field("plugin", &self.library.name)
            .field("poisoned", &self.poisoned)
            .finish()
    }
}

impl DynDescriptor {
    /// Creates an instance from parameters.
    pub(super) fn create(
        library: &'static Library,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let handle = create_handle(library, params, context)
            .map_err(|error| error.into_plugin_error(&library.name))?;
        Ok(Self {
            handle,
            library,
            poisoned: false,
        })
    }

    /// The descriptor length this instance produces.
    pub fn descriptor_len(&mut self) -> PluginResult<usize> {
        self.check_poison()?;
        let mut len = 0_usize;
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this library and host-owned outputs valid for the call.
        let status = unsafe {
            (self.library.descriptor.descriptor_len)(self.handle.as_ptr(), &mut len, error.as_mut_ptr())
        };
        self.finish(error.result(status)).map(|()| len)
    }

    fn check_poison(&self) -> PluginResult<()> {
        if self.poisoned {
            return Err(PluginError::failed(
                &self.library.name,
                "this instance panicked in an earlier call and is unusable; create a new one",
            ));
        }
        Ok(())
    }

    /// Maps a call's outcome, poisoning the instance on a panic.
    fn finish(&mut self, result: Result<(), CallError>) -> PluginResult<()> {
        result.map_err(|error| self.fail(error))
    }

    /// The error for a failed call, poisoning the instance on a panic.
    fn fail(&mut self, error: CallError) -> PluginError {
        self.poisoned |= error.status == Status::PANICKED;
        error.into_plugin_error(&self.library.name)
    }

    /// One `describe` call into `values`: the length written, or the length needed when the buffer was
    /// too small (`Ok(Err(needed))`).
    fn describe_into(
        &mut self,
        cloud: CloudView<'_>,
        values: &mut [f32],
    ) -> Result<Result<usize, usize>, CallError> {
        let points = cloud.points();
        let mut len = 0_usize;
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this library; `points` and `values` are host buffers valid for the
        // call and `values` is writable for its length.
        let status = unsafe {
            (self.library.descriptor.describe)(
                self.handle.as_ptr(),
                points.as_ptr(),
                points.len(),
                values.as_mut_ptr(),
                values.len(),
                &mut len,
                error.as_mut_ptr(),
            )
        };
        match error.result(status) {
            Ok(()) if len <= values.len() => Ok(Ok(len)),
            Ok(()) => Err(CallError {
                status: Status::FAILED,
                key: String::new(),
                message: format!("describe reported {len} values for a buffer of {}", values.len()),
            }),
            Err(error) if error.status == Status::BUFFER_TOO_SMALL && len > values.len() => Ok(Err(len)),
            Err(error) => Err(error),
        }
    }
}

impl Descriptor for DynDescriptor {
    fn kind(&self) -> &str {
        &self.library.name
    }

    fn describe(&mut self, cloud: CloudView<'_>) -> PluginResult<DescriptorBuf> {
        let len = self.descriptor_len()?;
        let mut values = vec![0.0_f32; len];
        let mut result = self.describe_into(cloud, &mut values);
        // The buffer can only be too small if the plugin's `descriptor_len` was wrong: retry once.
        if let Ok(Err(needed)) = result {
            values = vec![0.0_f32; needed];
            result = self.describe_into(cloud, &mut values);
        }
        let written = match result {
            Ok(Ok(written)) => written,
            Ok(Err(needed)) => {
                return Err(PluginError::failed(
                    &self.library.name,
                    format!("describe keeps asking for a larger buffer ({needed} values)"),
                ));
            }
            Err(error) => return Err(self.fail(error)),
        };
        values.truncate(written);
        Ok(DescriptorBuf {
            kind: self.library.name.clone(),
            values,
        })
    }

    fn new_index(&self) -> Box<dyn DescriptorIndex> {
        Box::new(ExactL2Index::new(&self.library.name))
    }
}

impl Drop for DynDescriptor {
    fn drop(&mut self) {
        destroy_handle(self.library, self.handle);
    }
}
