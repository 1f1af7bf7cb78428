//! Dynamic coarse and fine registration plugins seen through skid-core's [`CoarseRegistration`] and
//! [`FineRegistration`] traits, and their registry entries.
//!
//! Everything a plugin writes is checked before it reaches the pipeline: transforms must be finite
//! rigid motions, lengths must fit the buffers they describe, a prepared cloud may not claim more points
//! than it was given, and a prepared cloud is only ever handed back to the plugin that made it.

use std::ffi::c_void;
use std::ptr::NonNull;
use std::sync::Arc;

use skid_core::slots::{CoarseAlignment, CoarseRegistration, FineAlignment, FineRegistration, PreparedCloud};
use skid_core::{
    Cloud, CloudView, Information, Params, PluginContext, PluginEntry, PluginError, PluginResult, Pose,
};

use super::call::{ErrorSlot, copy_lent};
use super::instance::{Instance, registry_entry};
use super::library::{CoarseFns, FineFns, PluginSpec};
use crate::ffi::{
    AbiCloud, AbiTransform, Checked, CoarseResult, DestroyPreparedFn, FineResult, Handle, TextBuf,
};
use crate::transform::{abi_from_pose, pose_from_abi};

/// Room for a fine registration's failure sentence.
const FAILURE_CAPACITY: usize = 1024;

/// A borrowed cloud for one call.
fn abi_cloud(cloud: CloudView<'_>) -> AbiCloud {
    AbiCloud {
        points: cloud.points().as_ptr(),
        count: cloud.len(),
    }
}

/// The registry entry of a loaded coarse registration plugin.
pub(super) fn coarse_entry(
    plugin: &'static PluginSpec,
    fns: CoarseFns,
) -> PluginEntry<dyn CoarseRegistration> {
    registry_entry(plugin, fns.create, fns.destroy, move |params, context| {
        DynCoarse::create(plugin, fns, params, context)
            .map(|coarse| Box::new(coarse) as Box<dyn CoarseRegistration>)
    })
}

/// The registry entry of a loaded fine registration plugin.
pub(super) fn fine_entry(plugin: &'static PluginSpec, fns: FineFns) -> PluginEntry<dyn FineRegistration> {
    registry_entry(plugin, fns.create, fns.destroy, move |params, context| {
        DynFine::create(plugin, fns, params, context).map(|fine| Box::new(fine) as Box<dyn FineRegistration>)
    })
}

/// An instance of a dynamically loaded coarse registration plugin.
pub struct DynCoarse {
    instance: Instance,
    fns: CoarseFns,
}

impl DynCoarse {
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: CoarseFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let instance = Instance::create(plugin, fns.create, fns.destroy, params, context)?;
        Ok(Self { instance, fns })
    }
}

impl CoarseRegistration for DynCoarse {
    fn align(
        &mut self,
        target: CloudView<'_>,
        source: CloudView<'_>,
        prior: Option<&Pose>,
    ) -> PluginResult<CoarseAlignment> {
        let _serial = self.instance.enter()?;
        let prior = prior.map(abi_from_pose);
        let mut out = CoarseResult {
            target_from_source: AbiTransform::IDENTITY,
            inlier_count: 0,
            correspondence_count: 0,
            rival_inlier_count: 0,
            valid: 0,
            reserved: 0,
        };
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this plugin; the clouds, prior and outputs are host data valid for
        // the call.
        let status = unsafe {
            (self.fns.align)(
                self.instance.handle.as_ptr(),
                abi_cloud(target),
                abi_cloud(source),
                prior
                    .as_ref()
                    .map_or(std::ptr::null(), |prior| prior as *const AbiTransform),
                &mut out,
                error.as_mut_ptr(),
            )
        };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        let target_from_source = pose_from_abi(&out.target_from_source)
            .map_err(|reason| self.instance.bad_output(format!("align: {reason}")))?;
        Ok(CoarseAlignment {
            target_from_source,
            inlier_count: usize::try_from(out.inlier_count).unwrap_or(usize::MAX),
            correspondence_count: usize::try_from(out.correspondence_count).unwrap_or(usize::MAX),
            rival_inlier_count: usize::try_from(out.rival_inlier_count).unwrap_or(usize::MAX),
            valid: out.valid != 0,
        })
    }
}

/// A prepared cloud owned by a dynamic fine registration plugin; freed through the plugin when the
/// last holder drops it.
struct DynPrepared {
    handle: NonNull<c_void>,
    plugin: &'static PluginSpec,
    destroy: Checked<DestroyPreparedFn>,
}

// SAFETY: a prepared cloud is never mutated after `prepare` (the ABI's contract; `FinePlugin::Prepared`
// is `Send + Sync`), so it may be read from several threads and freed from any.
unsafe impl Send for DynPrepared {}
// SAFETY: as above.
unsafe impl Sync for DynPrepared {}

impl Drop for DynPrepared {
    fn drop(&mut self) {
        let mut error = ErrorSlot::new();
        let _serial = self.plugin.serialise();
        // SAFETY: the handle came from this plugin's `prepare` and is freed exactly once, here.
        let status = unsafe { (self.destroy)(self.handle.as_ptr(), error.as_mut_ptr()) };
        if let Err(error) = error.result(status) {
            tracing::warn!(target: "skid::plugin", plugin = %self.plugin.name, "freeing a prepared cloud failed: {}", error.message);
        }
    }
}

/// An instance of a dynamically loaded fine registration plugin.
pub struct DynFine {
    instance: Instance,
    fns: FineFns,
}

impl DynFine {
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: FineFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let instance = Instance::create(plugin, fns.create, fns.destroy, params, context)?;
        Ok(Self { instance, fns })
    }

    /// The plugin's prepared cloud behind `prepared`, refusing one another plugin made.
    fn own<'a>(&self, prepared: &'a PreparedCloud) -> PluginResult<&'a DynPrepared> {
        match prepared.cache.downcast_ref::<DynPrepared>() {
            Some(dynamic) if std::ptr::eq(dynamic.plugin, self.instance.plugin) => Ok(dynamic),
            _ => Err(PluginError::InvalidInput(format!(
                "`{}` was handed a cloud another plugin prepared",
                self.instance.plugin.name
            ))),
        }
    }

    /// Copies the points a prepared cloud kept, checking the count the plugin claims.
    fn kept_points(&mut self, prepared: NonNull<c_void>, given: usize) -> PluginResult<Cloud> {
        let mut kept = AbiCloud {
            points: std::ptr::null(),
            count: 0,
        };
        let mut error = ErrorSlot::new();
        // SAFETY: a live prepared handle of this plugin and a host-owned output.
        let status = unsafe { (self.fns.prepared_points)(prepared.as_ptr(), &mut kept, error.as_mut_ptr()) };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        if kept.count > given || (kept.count > 0 && kept.points.is_null()) {
            return Err(self.instance.bad_output(format!(
                "prepared_points claims {} points at {:p} for a cloud of {given}",
                kept.count, kept.points
            )));
        }
        // SAFETY: the plugin guarantees `count` points at `points` for the prepared cloud's life;
        // non-null when non-empty and no larger than the cloud it was given, both checked above.
        Ok(Cloud::new(unsafe { copy_lent(kept.points, kept.count) }))
    }
}

impl FineRegistration for DynFine {
    fn prepare(&mut self, cloud: CloudView<'_>) -> PluginResult<PreparedCloud> {
        let _serial = self.instance.enter()?;
        let mut handle: Handle = std::ptr::null_mut();
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this plugin; the cloud and the output are host data valid for the call.
        let status = unsafe {
            (self.fns.prepare)(
                self.instance.handle.as_ptr(),
                abi_cloud(cloud),
                &mut handle,
                error.as_mut_ptr(),
            )
        };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        let Some(handle) = NonNull::new(handle) else {
            return Err(self
                .instance
                .bad_output("prepare reported success but returned a null handle".to_owned()));
        };
        // From here on the prepared cloud is freed on every path, by `DynPrepared`'s drop.
        let prepared = DynPrepared {
            handle,
            plugin: self.instance.plugin,
            destroy: self.fns.destroy_prepared,
        };
        let points = self.kept_points(handle, cloud.len())?;
        Ok(PreparedCloud {
            cloud: Arc::new(points),
            cache: Arc::new(prepared),
        })
    }

    fn refine(
        &mut self,
        target: &PreparedCloud,
        source: &PreparedCloud,
        guess: &Pose,
    ) -> PluginResult<FineAlignment> {
        let _serial = self.instance.enter()?;
        let (target, source) = (self.own(target)?, self.own(source)?);
        let guess = abi_from_pose(guess);
        let mut failure = vec![0_u8; FAILURE_CAPACITY];
        let mut out = FineResult {
            target_from_source: guess,
            information: [0.0; 36],
            converged: 0,
            reserved: 0,
            iterations: 0,
            inlier_count: 0,
            inlier_ratio: 0.0,
            error: 0.0,
            failure: TextBuf {
                ptr: failure.as_mut_ptr(),
                capacity: failure.len(),
                len: 0,
            },
        };
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle and two live prepared clouds of this plugin; the guess and the outputs
        // (with the failure buffer) are host data valid for the call.
        let status = unsafe {
            (self.fns.refine)(
                self.instance.handle.as_ptr(),
                target.handle.as_ptr(),
                source.handle.as_ptr(),
                &guess,
                &mut out,
                error.as_mut_ptr(),
            )
        };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        if out.failure.len > failure.len() {
            return Err(self.instance.bad_output(format!(
                "refine reported a failure text of {} bytes for a buffer of {}",
                out.failure.len,
                failure.len()
            )));
        }
        let target_from_source = pose_from_abi(&out.target_from_source)
            .map_err(|reason| self.instance.bad_output(format!("refine: {reason}")))?;
        let converged = out.converged != 0;
        let failure = (!converged).then(|| {
            let text = String::from_utf8_lossy(&failure[..out.failure.len]).into_owned();
            if text.is_empty() {
                format!(
                    "`{}` did not converge and did not say why",
                    self.instance.plugin.name
                )
            } else {
                text
            }
        });
        Ok(FineAlignment {
            target_from_source,
            information: Information::from_row_slice(&out.information),
            converged,
            iterations: usize::try_from(out.iterations).unwrap_or(usize::MAX),
            inlier_count: usize::try_from(out.inlier_count).unwrap_or(usize::MAX),
            inlier_ratio: out.inlier_ratio,
            error: out.error,
            failure,
        })
    }
}
