//! What every slot's wrapper shares: the plugin instance behind a handle (created and destroyed through
//! the plugin, refusing calls after a panic), and the registry entry that builds wrappers.

use std::cell::Cell;
use std::ffi::c_void;
use std::ptr::NonNull;

use parking_lot::ReentrantMutexGuard;

use skid_core::{Params, PluginContext, PluginEntry, PluginError, PluginResult};

use super::call::{CallError, create_instance, destroy_instance, validate_params};
use super::library::PluginSpec;
use crate::ffi::{Checked, CreateFn, DestroyFn, Status};

/// The registry entry of a loaded plugin: parameters are validated by creating and destroying an
/// instance, and `build` makes the slot's wrapper.
pub(super) fn registry_entry<T: ?Sized + 'static>(
    plugin: &'static PluginSpec,
    create: Checked<CreateFn>,
    destroy: Checked<DestroyFn>,
    build: impl Fn(&Params, &PluginContext) -> PluginResult<Box<T>> + Send + Sync + 'static,
) -> PluginEntry<T> {
    PluginEntry::from_parts(
        &plugin.name,
        &plugin.summary,
        &plugin.path.display().to_string(),
        plugin.defaults.clone(),
        move |params: &Params| validate_params(plugin, create, destroy, params),
        build,
    )
}

/// A plugin instance: its handle, its plugin, and whether it panicked (after which its state may be
/// broken, so it refuses further calls). Destroyed through the plugin when dropped.
pub(super) struct Instance {
    pub(super) handle: NonNull<c_void>,
    pub(super) plugin: &'static PluginSpec,
    destroy: Checked<DestroyFn>,
    poisoned: Cell<bool>,
}

// SAFETY: the plugin declared whether its instances may move between threads: a plugin pinned to its
// creating thread is refused at load, a serial one is called under its lock, and every other one is
// `Send` by declaration (and, for Rust plugins, by the slot traits). The wrappers serialise calls on
// one instance with `&mut self`.
unsafe impl Send for Instance {}

impl std::fmt::Debug for Instance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Instance")
            .field("plugin", &self.plugin.name)
            .field("poisoned", &self.poisoned.get())
            .finish()
    }
}

impl Instance {
    /// Creates an instance through the plugin's `create`.
    pub(super) fn create(
        plugin: &'static PluginSpec,
        create: Checked<CreateFn>,
        destroy: Checked<DestroyFn>,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let handle = create_instance(plugin, create, params, context)
            .map_err(|error| error.into_plugin_error(&plugin.name))?;
        Ok(Self {
            handle,
            plugin,
            destroy,
            poisoned: Cell::new(false),
        })
    }

    /// Takes ownership of a handle the plugin made in another call (an index, say), destroyed with
    /// `destroy` when dropped.
    pub(super) fn adopt(
        handle: NonNull<c_void>,
        plugin: &'static PluginSpec,
        destroy: Checked<DestroyFn>,
    ) -> Self {
        Self {
            handle,
            plugin,
            destroy,
            poisoned: Cell::new(false),
        }
    }

    /// Prepares a call: an error when an earlier call panicked, otherwise the plugin's serial lock
    /// (for a plugin declared serial) to hold until the call's outputs are read.
    pub(super) fn enter(&self) -> PluginResult<Option<ReentrantMutexGuard<'static, ()>>> {
        if self.poisoned.get() {
            return Err(PluginError::failed(
                &self.plugin.name,
                "this instance panicked in an earlier call and is unusable; create a new one",
            ));
        }
        Ok(self.plugin.serialise())
    }

    /// The error for a failed call, poisoning the instance on a panic.
    pub(super) fn fail(&self, error: CallError) -> PluginError {
        if error.status == Status::PANICKED {
            self.poisoned.set(true);
        }
        error.into_plugin_error(&self.plugin.name)
    }

    /// An error about what the plugin returned.
    pub(super) fn bad_output(&self, message: String) -> PluginError {
        PluginError::failed(&self.plugin.name, message)
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        destroy_instance(self.plugin, self.destroy, self.handle);
    }
}
