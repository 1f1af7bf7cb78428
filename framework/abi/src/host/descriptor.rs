//! A dynamic descriptor plugin seen through skid-core's [`Descriptor`] trait, and its registry entry.

use skid_core::slots::{Descriptor, DescriptorBuf, DescriptorIndex};
use skid_core::{CloudView, Params, PluginContext, PluginEntry, PluginError, PluginResult};

use super::call::{CallError, ErrorSlot};
use super::index::ExactL2Index;
use super::instance::{Instance, registry_entry};
use super::library::{DescriptorFns, PluginSpec};
use super::plugin_index::PluginIndex;
use crate::ffi::Status;

/// The registry entry of a loaded descriptor plugin.
pub(super) fn entry(plugin: &'static PluginSpec, fns: DescriptorFns) -> PluginEntry<dyn Descriptor> {
    registry_entry(plugin, fns.create, fns.destroy, move |params, context| {
        DynDescriptor::create(plugin, fns, params, context)
            .map(|descriptor| Box::new(descriptor) as Box<dyn Descriptor>)
    })
}

/// An instance of a dynamically loaded descriptor plugin.
///
/// After the plugin panics in a call, the instance refuses further calls (its state may be broken);
/// create a fresh one.
#[derive(Debug)]
pub struct DynDescriptor {
    instance: Instance,
    fns: DescriptorFns,
}

impl DynDescriptor {
    /// Creates an instance from parameters.
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: DescriptorFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let instance = Instance::create(plugin, fns.create, fns.destroy, params, context)?;
        Ok(Self { instance, fns })
    }

    /// The descriptor length this instance produces.
    pub fn descriptor_len(&mut self) -> PluginResult<usize> {
        let _serial = self.instance.enter()?;
        let mut len = 0_usize;
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this library and host-owned outputs valid for the call.
        let status =
            unsafe { (self.fns.descriptor_len)(self.instance.handle.as_ptr(), &mut len, error.as_mut_ptr()) };
        error
            .result(status)
            .map_err(|error| self.instance.fail(error))
            .map(|()| len)
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
                self.instance.handle.as_ptr(),
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
        &self.instance.plugin.name
    }

    fn describe(&mut self, cloud: CloudView<'_>) -> PluginResult<DescriptorBuf> {
        let len = self.descriptor_len()?;
        let mut values = vec![0.0_f32; len];
        let plugin = &self.instance.plugin.name;
        let written = match self.describe_into(cloud, &mut values) {
            Ok(Ok(written)) => written,
            Ok(Err(needed)) => {
                return Err(PluginError::failed(
                    plugin,
                    format!("describe asked for {needed} values, but descriptor_len declared {len}"),
                ));
            }
            Err(error) => return Err(self.instance.fail(error)),
        };
        // What crosses the boundary is checked here, so nothing malformed reaches the pipeline: the
        // declared length, and finite values.
        if written != len {
            return Err(PluginError::failed(
                plugin,
                format!("describe wrote {written} values, but descriptor_len declared {len}"),
            ));
        }
        if let Some(index) = values.iter().position(|value| !value.is_finite()) {
            return Err(PluginError::failed(
                plugin,
                format!(
                    "describe returned value {index} = {}; descriptor values must be finite",
                    values[index]
                ),
            ));
        }
        Ok(DescriptorBuf {
            kind: self.instance.plugin.name.clone(),
            values,
        })
    }

    fn new_index(&self) -> Box<dyn DescriptorIndex> {
        let plugin = self.instance.plugin;
        match PluginIndex::create(plugin, self.fns, &self.instance) {
            Ok(Some(index)) => Box::new(index),
            Ok(None) => Box::new(ExactL2Index::new(&plugin.name)),
            Err(error) => {
                // The trait cannot fail here: fall back to the exact L2 index, and say so.
                tracing::warn!(target: "skid::plugin", plugin = %plugin.name, "new_index failed, retrieving by exact L2 distance instead: {error}");
                Box::new(ExactL2Index::new(&plugin.name))
            }
        }
    }
}
