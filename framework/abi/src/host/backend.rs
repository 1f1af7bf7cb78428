//! A dynamic back-end plugin seen through skid-core's [`Backend`] trait, and its registry entry. The
//! wrapper is also the graph view the host reads: each query is a call into the plugin, and the keyframe
//! and loop lists it lends are copied after their lengths are checked against a plausible bound.

use skid_core::slots::{
    Backend, GraphView, LoopClosure, OdometryMeasurement, OptimizeBudget, OptimizeReport, RelativePose,
};
use skid_core::{Information, KeyframeId, LoopId, Params, PluginContext, PluginEntry, PluginResult, Pose};

use super::call::{CallError, ErrorSlot, copy_lent};
use super::instance::{Instance, registry_entry};
use super::library::{BackendFns, PluginSpec};
use crate::ffi::{
    AbiKeyframeId, AbiLoop, AbiOptimizeReport, AbiPrior, AbiRelativePose, AbiTransform, Status,
};
use crate::graph::{abi_id, abi_loop, host_id, loop_from_abi, row_major};
use crate::transform::{abi_from_pose, pose_from_abi};

/// More keyframes or loops than any graph SKiD builds; a larger count is a lie.
const MAX_GRAPH_ITEMS: usize = 10_000_000;

/// The registry entry of a loaded back-end plugin.
pub(super) fn entry(plugin: &'static PluginSpec, fns: BackendFns) -> PluginEntry<dyn Backend> {
    registry_entry(plugin, fns.create, fns.destroy, move |params, context| {
        DynBackend::create(plugin, fns, params, context).map(|backend| Box::new(backend) as Box<dyn Backend>)
    })
}

/// An instance of a dynamically loaded back-end plugin. After a panic it refuses further calls.
pub struct DynBackend {
    instance: Instance,
    fns: BackendFns,
}

impl DynBackend {
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: BackendFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let instance = Instance::create(plugin, fns.create, fns.destroy, params, context)?;
        Ok(Self { instance, fns })
    }

    /// Runs one call with a fresh error slot and maps its status.
    fn call(&self, body: impl FnOnce(*mut crate::ffi::ErrorBuf) -> Status) -> PluginResult<()> {
        let _serial = self.instance.enter()?;
        let mut error = ErrorSlot::new();
        let status = body(error.as_mut_ptr());
        error
            .result(status)
            .map_err(|error: CallError| self.instance.fail(error))
    }

    /// A query's failure cannot be returned through [`GraphView`]; it is logged and reads as absent.
    fn absent<T>(&self, result: PluginResult<Option<T>>) -> Option<T> {
        result.unwrap_or_else(|error| {
            tracing::warn!(target: "skid::plugin", plugin = %self.instance.plugin.name, "a graph query failed: {error}");
            None
        })
    }

    fn add_edge(&mut self, edge: &AbiLoop, is_loop: bool) -> PluginResult<()> {
        let handle = self.instance.handle.as_ptr();
        let add_edge = self.fns.add_edge;
        // SAFETY: a live handle of this plugin; the edge and the error slot are host data valid for the call.
        self.call(|error| unsafe { add_edge(handle, edge, u32::from(is_loop), error) })
    }

    /// The graph's keyframes and loops, copied from the plugin's lent lists.
    fn lists(&self) -> PluginResult<(Vec<AbiKeyframeId>, Vec<AbiLoop>)> {
        let (mut keyframes, mut keyframe_count) = (std::ptr::null(), 0_usize);
        let (mut loops, mut loop_count) = (std::ptr::null(), 0_usize);
        let (handle, lists) = (self.instance.handle.as_ptr(), self.fns.lists);
        // SAFETY: a live handle of this plugin and host-owned outputs valid for the call.
        self.call(|error| unsafe {
            lists(
                handle,
                &mut keyframes,
                &mut keyframe_count,
                &mut loops,
                &mut loop_count,
                error,
            )
        })?;
        if keyframe_count > MAX_GRAPH_ITEMS
            || loop_count > MAX_GRAPH_ITEMS
            || (keyframe_count > 0 && keyframes.is_null())
            || (loop_count > 0 && loops.is_null())
        {
            return Err(self.instance.bad_output(format!(
                "lists: an implausible graph of {keyframe_count} keyframes and {loop_count} loops"
            )));
        }
        // SAFETY: the plugin lends both lists until its next call; non-null when non-empty and within the
        // plausible bound, both checked above.
        Ok(unsafe { (copy_lent(keyframes, keyframe_count), copy_lent(loops, loop_count)) })
    }
}

impl Backend for DynBackend {
    fn add_keyframe(&mut self, id: KeyframeId, world_from_sensor: Pose) -> PluginResult<()> {
        let (handle, add_keyframe) = (self.instance.handle.as_ptr(), self.fns.add_keyframe);
        let pose = abi_from_pose(&world_from_sensor);
        // SAFETY: a live handle of this plugin; the pose and the error slot are host data valid for the call.
        self.call(|error| unsafe { add_keyframe(handle, abi_id(id), &pose, error) })
    }

    fn add_odometry(&mut self, measurement: OdometryMeasurement) -> PluginResult<()> {
        let edge = abi_loop(&LoopClosure {
            id: LoopId(0),
            target: measurement.target,
            source: measurement.source,
            target_from_source: measurement.target_from_source,
            information: measurement.information,
        });
        self.add_edge(&edge, false)
    }

    fn add_prior(
        &mut self,
        id: KeyframeId,
        world_from_sensor: Pose,
        information: Information,
    ) -> PluginResult<()> {
        let prior = AbiPrior {
            id: abi_id(id),
            world_from_sensor: abi_from_pose(&world_from_sensor),
            information: row_major(&information),
        };
        let (handle, add_prior) = (self.instance.handle.as_ptr(), self.fns.add_prior);
        // SAFETY: a live handle of this plugin; the prior and the error slot are host data valid for the call.
        self.call(|error| unsafe { add_prior(handle, &prior, error) })
    }

    fn add_loop(&mut self, closure: LoopClosure) -> PluginResult<()> {
        self.add_edge(&abi_loop(&closure), true)
    }

    fn remove_loop(&mut self, id: LoopId) -> PluginResult<()> {
        let (handle, remove_loop) = (self.instance.handle.as_ptr(), self.fns.remove_loop);
        // SAFETY: a live handle of this plugin and a host-owned error slot.
        self.call(|error| unsafe { remove_loop(handle, id.0, error) })
    }

    fn optimize(&mut self, budget: OptimizeBudget) -> PluginResult<OptimizeReport> {
        let (handle, optimize) = (self.instance.handle.as_ptr(), self.fns.optimize);
        let mut report = AbiOptimizeReport::default();
        let max_iterations = u64::try_from(budget.max_iterations).unwrap_or(u64::MAX);
        let max_duration_s = budget.max_duration.as_secs_f64();
        // SAFETY: a live handle of this plugin and host-owned outputs valid for the call.
        self.call(|error| unsafe { optimize(handle, max_iterations, max_duration_s, &mut report, error) })?;
        Ok(OptimizeReport {
            iterations: usize::try_from(report.iterations).unwrap_or(usize::MAX),
            initial_cost: report.initial_cost,
            final_cost: report.final_cost,
            converged: report.converged != 0,
        })
    }

    fn graph(&self) -> &dyn GraphView {
        self
    }

    fn rejected_loops(&self) -> Vec<LoopId> {
        let (mut ids, mut count) = (std::ptr::null(), 0_usize);
        let (handle, rejected_loops) = (self.instance.handle.as_ptr(), self.fns.rejected_loops);
        // SAFETY: a live handle of this plugin and host-owned outputs valid for the call.
        let called = self.call(|error| unsafe { rejected_loops(handle, &mut ids, &mut count, error) });
        let result = called.and_then(|()| {
            if count > MAX_GRAPH_ITEMS || (count > 0 && ids.is_null()) {
                return Err(self
                    .instance
                    .bad_output(format!("rejected_loops: an implausible list of {count} loops")));
            }
            // SAFETY: the plugin lends the list until its next call; non-null when non-empty and within
            // the plausible bound, both checked above.
            let ids: Vec<u64> = unsafe { copy_lent(ids, count) };
            Ok(Some(ids.into_iter().map(LoopId).collect()))
        });
        self.absent(result).unwrap_or_default()
    }
}

impl GraphView for DynBackend {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        let (handle, pose) = (self.instance.handle.as_ptr(), self.fns.pose);
        let (mut out, mut found) = (AbiTransform::IDENTITY, 0_u32);
        // SAFETY: a live handle of this plugin and host-owned outputs valid for the call.
        let called = self.call(|error| unsafe { pose(handle, abi_id(id), &mut out, &mut found, error) });
        let result = called.and_then(|()| {
            if found == 0 {
                return Ok(None);
            }
            pose_from_abi(&out)
                .map(Some)
                .map_err(|reason| self.instance.bad_output(format!("pose: {reason}")))
        });
        self.absent(result)
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        let (handle, odometry_between) = (self.instance.handle.as_ptr(), self.fns.odometry_between);
        let mut out = AbiRelativePose {
            target_from_source: AbiTransform::IDENTITY,
            covariance: [0.0; 36],
        };
        let mut found = 0_u32;
        // SAFETY: a live handle of this plugin and host-owned outputs valid for the call.
        let called = self.call(|error| unsafe {
            odometry_between(
                handle,
                abi_id(target),
                abi_id(source),
                &mut out,
                &mut found,
                error,
            )
        });
        let result = called.and_then(|()| {
            if found == 0 {
                return Ok(None);
            }
            let target_from_source = pose_from_abi(&out.target_from_source)
                .map_err(|reason| self.instance.bad_output(format!("odometry_between: {reason}")))?;
            Ok(Some(RelativePose {
                target_from_source,
                covariance: Information::from_row_slice(&out.covariance),
            }))
        });
        self.absent(result)
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        let keyframes = self
            .lists()
            .map(|(keyframes, _)| Some(keyframes.into_iter().map(host_id).collect()));
        self.absent(keyframes).unwrap_or_default()
    }

    fn loops(&self) -> Vec<LoopClosure> {
        let loops = self.lists().and_then(|(_, loops)| {
            loops
                .iter()
                .map(loop_from_abi)
                .collect::<Result<Vec<_>, _>>()
                .map(Some)
                .map_err(|reason| self.instance.bad_output(format!("lists: {reason}")))
        });
        self.absent(loops).unwrap_or_default()
    }
}
