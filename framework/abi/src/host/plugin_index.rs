//! A descriptor plugin's own retrieval index, seen through skid-core's [`DescriptorIndex`] trait. The
//! host's exclusion test crosses as a non-unwinding callback; the candidates the plugin lends back are
//! checked (no more than asked for, finite distances) and copied.

use std::ffi::c_void;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::ptr::NonNull;

use skid_core::slots::{DescriptorBuf, DescriptorIndex, PlaceCandidate};
use skid_core::{KeyframeId, PluginError, PluginResult, RobotId};

use super::call::ErrorSlot;
use super::instance::Instance;
use super::library::{DescriptorFns, PluginSpec};
use crate::ffi::{AbiKeyframeId, AbiPlaceCandidate};

/// An index the plugin made with `new_index`.
pub struct PluginIndex {
    instance: Instance,
    fns: DescriptorFns,
}

/// The host's exclusion test as the plugin calls it: `context` points to a `&dyn Fn(KeyframeId) -> bool`.
unsafe extern "C" fn excluded(context: *const c_void, id: AbiKeyframeId) -> u32 {
    catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: the context is the one `query` passes, valid for that call.
        let exclude = unsafe { *context.cast::<&dyn Fn(KeyframeId) -> bool>() };
        u32::from(exclude(KeyframeId::new(id.robot, id.index)))
    }))
    // An exclusion test that panicked cannot vouch for the keyframe: leave it out.
    .unwrap_or(1)
}

impl PluginIndex {
    /// The plugin's index for an instance, or `None` when the plugin has none of its own.
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: DescriptorFns,
        descriptor: &Instance,
    ) -> PluginResult<Option<Self>> {
        let _serial = descriptor.enter()?;
        let mut handle = std::ptr::null_mut();
        let mut error = ErrorSlot::new();
        // SAFETY: a live descriptor handle of this plugin and host-owned outputs valid for the call.
        let status = unsafe { (fns.new_index)(descriptor.handle.as_ptr(), &mut handle, error.as_mut_ptr()) };
        error.result(status).map_err(|error| descriptor.fail(error))?;
        Ok(NonNull::new(handle).map(|handle| Self {
            instance: Instance::adopt(handle, plugin, fns.destroy_index),
            fns,
        }))
    }

    fn check_kind(&self, descriptor: &DescriptorBuf) -> PluginResult<()> {
        if descriptor.kind != self.instance.plugin.name {
            return Err(PluginError::InvalidInput(format!(
                "a `{}` descriptor offered to the index of `{}`",
                descriptor.kind, self.instance.plugin.name
            )));
        }
        Ok(())
    }
}

impl DescriptorIndex for PluginIndex {
    fn insert(&mut self, id: KeyframeId, descriptor: DescriptorBuf) -> PluginResult<()> {
        let _serial = self.instance.enter()?;
        self.check_kind(&descriptor)?;
        let id = AbiKeyframeId {
            robot: id.robot.0,
            index: id.index,
        };
        let mut error = ErrorSlot::new();
        // SAFETY: a live index handle of this plugin; the values are host data valid for the call.
        let status = unsafe {
            (self.fns.index_insert)(
                self.instance.handle.as_ptr(),
                id,
                descriptor.values.as_ptr(),
                descriptor.values.len(),
                error.as_mut_ptr(),
            )
        };
        error.result(status).map_err(|error| self.instance.fail(error))
    }

    fn query(
        &mut self,
        descriptor: &DescriptorBuf,
        k: usize,
        exclude: &dyn Fn(KeyframeId) -> bool,
    ) -> PluginResult<Vec<PlaceCandidate>> {
        let _serial = self.instance.enter()?;
        self.check_kind(descriptor)?;
        let (mut candidates, mut count) = (std::ptr::null::<AbiPlaceCandidate>(), 0_usize);
        let mut error = ErrorSlot::new();
        // SAFETY: a live index handle of this plugin; the values, the exclusion context (a reference to
        // `exclude` that outlives the call) and the outputs are host data valid for the call.
        let status = unsafe {
            (self.fns.index_query)(
                self.instance.handle.as_ptr(),
                descriptor.values.as_ptr(),
                descriptor.values.len(),
                k,
                Some(excluded),
                (&raw const exclude).cast::<c_void>(),
                &mut candidates,
                &mut count,
                error.as_mut_ptr(),
            )
        };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        if count > k || (count > 0 && candidates.is_null()) {
            return Err(self
                .instance
                .bad_output(format!("index_query: {count} candidates for k = {k}")));
        }
        // SAFETY: the plugin lends `count` candidates until its next call; non-null and no more than `k`,
        // both checked above.
        let lent = unsafe { crate::host::call::copy_lent(candidates, count) };
        lent.iter()
            .map(|candidate| {
                if !candidate.distance.is_finite() {
                    return Err(self.instance.bad_output(format!(
                        "index_query: a non-finite distance {}",
                        candidate.distance
                    )));
                }
                Ok(PlaceCandidate {
                    id: KeyframeId {
                        robot: RobotId(candidate.id.robot),
                        index: candidate.id.index,
                    },
                    distance: candidate.distance,
                    yaw_hint_rad: (candidate.has_yaw_hint != 0 && candidate.yaw_hint_rad.is_finite())
                        .then_some(candidate.yaw_hint_rad),
                })
            })
            .collect()
    }

    fn len(&self) -> usize {
        let mut len = 0_usize;
        let mut error = ErrorSlot::new();
        let _serial = self.instance.plugin.serialise();
        // SAFETY: a live index handle of this plugin and host-owned outputs valid for the call.
        let status =
            unsafe { (self.fns.index_len)(self.instance.handle.as_ptr(), &mut len, error.as_mut_ptr()) };
        match error.result(status) {
            Ok(()) => len,
            Err(error) => {
                let error = self.instance.fail(error);
                tracing::warn!(target: "skid::plugin", "index_len failed: {error}");
                0
            }
        }
    }
}
