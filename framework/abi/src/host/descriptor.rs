//! A dynamic descriptor plugin seen through skid-core's [`Descriptor`] trait, and its registry entry.

use std::ffi::c_void;
use std::ptr::NonNull;

use skid_core::slots::{Descriptor, DescriptorBuf, DescriptorIndex};
use skid_core::{CloudView, Params, PluginContext, PluginEntry, PluginError, PluginResult};

use super::call::{CallError, ErrorSlot, create_instance, destroy_instance, validate_params};
use super::index::ExactL2Index;
use super::library::{DescriptorFns, PluginSpec};
use crate::ffi::Status;

/// The registry entry of a loaded descriptor plugin.
pub(super) fn entry(plugin: &'static PluginSpec, fns: DescriptorFns) -> PluginEntry<dyn Descriptor> {
    PluginEntry::from_parts(
        &plugin.name,
        &plugin.summary,
        &plugin.path.display().to_string(),
        plugin.defaults.clone(),
        move |params: &Params| validate_params(plugin, fns.create, fns.destroy, params),
        move |params: &Params, context: &PluginContext| {
            DynDescriptor::create(plugin, fns, params, context)
                .map(|descriptor| Box::new(descriptor) as Box<dyn Descriptor>)
        },
    )
}

/// An instance of a dynamically loaded descriptor plugin.
///
/// After the plugin panics in a call, the instance refuses further calls (its state may be broken);
/// create a fresh one.
pub struct DynDescriptor {
    handle: NonNull<c_void>,
    library: &'static PluginSpec,
    fns: DescriptorFns,
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
        library: &'static PluginSpec,
        fns: DescriptorFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let handle = create_instance(library, fns.create, params, context)
            .map_err(|error| error.into_plugin_error(&library.name))?;
        Ok(Self {
            handle,
            library,
            fns,
            poisoned: false,
        })
    }

    /// The descriptor length this instance produces.
    pub fn descriptor_len(&mut self) -> PluginResult<usize> {
        self.check_poison()?;
        let mut len = 0_usize;
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this library and host-owned outputs valid for the call.
        let status = unsafe { (self.fns.descriptor_len)(self.handle.as_ptr(), &mut len, error.as_mut_ptr()) };
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
            (self.fns.describe)(
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
        destroy_instance(self.library, self.fns.destroy, self.handle);
    }
}
