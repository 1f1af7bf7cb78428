//! A dynamic verifier plugin seen through skid-core's [`Verifier`] trait, and its registry entry.
//!
//! Each submission lends the plugin the candidate, both clouds and the graph: snapshots of its keyframes
//! and loops, and callbacks (which never unwind) for poses and odometry. The verdict the plugin lends back
//! is copied after its lengths are checked against a plausible bound.

use std::ffi::c_void;
use std::panic::{AssertUnwindSafe, catch_unwind};

use skid_core::slots::{GraphView, LoopCandidate, Verdict, Verifier};
use skid_core::{LoopId, Params, PluginContext, PluginEntry, PluginResult};

use super::call::{ErrorSlot, copy_lent};
use super::instance::{Instance, registry_entry};
use super::library::{PluginSpec, VerifierFns};
use crate::ffi::{AbiCloud, AbiGraph, AbiKeyframeId, AbiLoop, AbiRelativePose, AbiTransform, AbiVerdict};
use crate::graph::{abi_id, abi_loop, host_id, row_major};
use crate::transform::abi_from_pose;

/// More loop ids than one verdict can plausibly name; a larger count is a lie.
const MAX_VERDICT_ENTRIES: usize = 1_000_000;

/// The registry entry of a loaded verifier plugin.
pub(super) fn entry(plugin: &'static PluginSpec, fns: VerifierFns) -> PluginEntry<dyn Verifier> {
    registry_entry(plugin, fns.create, fns.destroy, move |params, context| {
        DynVerifier::create(plugin, fns, params, context)
            .map(|verifier| Box::new(verifier) as Box<dyn Verifier>)
    })
}

/// The graph a callback reads: a pointer to the host's `&dyn GraphView`, valid during one submission.
///
/// # Safety
///
/// `context` must be the pointer `submit` passes, to a `&dyn GraphView` that outlives the call.
unsafe fn graph_of<'a>(context: *const c_void) -> &'a dyn GraphView {
    // SAFETY: the caller's guarantee.
    unsafe { *context.cast::<&dyn GraphView>() }
}

unsafe extern "C" fn graph_pose(context: *const c_void, id: AbiKeyframeId, out: *mut AbiTransform) -> u32 {
    catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: the context is the one this host passed for the current submission.
        let graph = unsafe { graph_of(context) };
        // SAFETY: the plugin passes null or a transform it owns for this call.
        match (graph.pose(host_id(id)), unsafe { out.as_mut() }) {
            (Some(pose), Some(out)) => {
                *out = abi_from_pose(&pose);
                1
            }
            _ => 0,
        }
    }))
    .unwrap_or(0)
}

unsafe extern "C" fn graph_odometry(
    context: *const c_void,
    target: AbiKeyframeId,
    source: AbiKeyframeId,
    out: *mut AbiRelativePose,
) -> u32 {
    catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: the context is the one this host passed for the current submission.
        let graph = unsafe { graph_of(context) };
        // SAFETY: the plugin passes null or a struct it owns for this call.
        match (graph.odometry_between(host_id(target), host_id(source)), unsafe {
            out.as_mut()
        }) {
            (Some(relative), Some(out)) => {
                *out = AbiRelativePose {
                    target_from_source: abi_from_pose(&relative.target_from_source),
                    covariance: row_major(&relative.covariance),
                };
                1
            }
            _ => 0,
        }
    }))
    .unwrap_or(0)
}

/// An instance of a dynamically loaded verifier plugin. After a panic it refuses further calls.
pub struct DynVerifier {
    instance: Instance,
    fns: VerifierFns,
}

impl DynVerifier {
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: VerifierFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let instance = Instance::create(plugin, fns.create, fns.destroy, params, context)?;
        Ok(Self { instance, fns })
    }

    /// Copies a lent verdict after checking its lengths.
    fn copy_verdict(&self, lent: &AbiVerdict) -> PluginResult<Verdict> {
        let counts = [lent.accepted_count, lent.retracted_count, lent.rejected_count];
        let pointers = [
            lent.accepted.cast::<c_void>(),
            lent.retracted.cast::<c_void>(),
            lent.rejected.cast::<c_void>(),
        ];
        if counts.iter().any(|&count| count > MAX_VERDICT_ENTRIES)
            || counts
                .iter()
                .zip(pointers)
                .any(|(&count, pointer)| count > 0 && pointer.is_null())
        {
            return Err(self.instance.bad_output(format!(
                "submit: an implausible verdict ({} accepted, {} retracted, {} rejected)",
                counts[0], counts[1], counts[2]
            )));
        }
        // SAFETY: the plugin lends these lists until its next call; each is non-null when non-empty and
        // within the plausible bound, both checked above.
        let (accepted, retracted, rejected) = unsafe {
            (
                copy_lent(lent.accepted, lent.accepted_count),
                copy_lent(lent.retracted, lent.retracted_count),
                copy_lent(lent.rejected, lent.rejected_count),
            )
        };
        Ok(Verdict {
            accepted: accepted.into_iter().map(LoopId).collect(),
            retracted: retracted.into_iter().map(LoopId).collect(),
            rejected: rejected
                .into_iter()
                .map(|rejection| {
                    // SAFETY: the reason is lent with the verdict, until the plugin's next call.
                    let reason =
                        unsafe { rejection.reason.to_str() }.unwrap_or("<a reason that is not UTF-8>");
                    (LoopId(rejection.id), reason.to_owned())
                })
                .collect(),
        })
    }
}

impl Verifier for DynVerifier {
    fn submit(&mut self, candidate: &LoopCandidate<'_>, graph: &dyn GraphView) -> PluginResult<Verdict> {
        let _serial = self.instance.enter()?;
        let keyframes: Vec<AbiKeyframeId> = graph.keyframes().into_iter().map(abi_id).collect();
        let loops: Vec<AbiLoop> = graph.loops().iter().map(abi_loop).collect();
        let context: &dyn GraphView = graph;
        let lent_graph = AbiGraph {
            context: (&raw const context).cast::<c_void>(),
            pose: Some(graph_pose),
            odometry_between: Some(graph_odometry),
            keyframes: keyframes.as_ptr(),
            keyframe_count: keyframes.len(),
            loops: loops.as_ptr(),
            loop_count: loops.len(),
        };
        let closure = abi_loop(&candidate.closure);
        let cloud = |view: skid_core::CloudView<'_>| AbiCloud {
            points: view.points().as_ptr(),
            count: view.len(),
        };
        let mut verdict = AbiVerdict {
            accepted: std::ptr::null(),
            accepted_count: 0,
            retracted: std::ptr::null(),
            retracted_count: 0,
            rejected: std::ptr::null(),
            rejected_count: 0,
        };
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this plugin; the candidate, clouds, graph (with its context, which
        // outlives the call) and outputs are host data valid for the call.
        let status = unsafe {
            (self.fns.submit)(
                self.instance.handle.as_ptr(),
                &closure,
                cloud(candidate.target_cloud),
                cloud(candidate.source_cloud),
                &lent_graph,
                &mut verdict,
                error.as_mut_ptr(),
            )
        };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        self.copy_verdict(&verdict)
    }
}
