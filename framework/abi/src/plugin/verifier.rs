//! The verifier slot on the plugin side: the safe trait, the graph access it is given, the verdict it
//! returns, and the `extern "C"` functions of its table. The last verdict lives in the instance's
//! wrapper, so the host can read its lists by pointer until its next call.

use skid_msgs::Point;

use super::glue::{Failure, create_with, destroy, guard, instance, lent};
use super::{ConfigError, InstanceContext};
use crate::ffi::{
    AbiCloud, AbiGraph, AbiKeyframeId, AbiLoop, AbiRejection, AbiRelativePose, AbiStr, AbiTransform,
    AbiVerdict, ErrorBuf, Handle, HostContext, Status, VerifierVTable,
};

/// The host's pose graph as a plugin reads it during one submission.
pub struct GraphAccess<'a> {
    graph: &'a AbiGraph,
    keyframes: &'a [AbiKeyframeId],
    loops: &'a [AbiLoop],
}

impl GraphAccess<'_> {
    /// The current estimate of a keyframe's pose, when the graph has it.
    pub fn pose(&self, id: AbiKeyframeId) -> Option<AbiTransform> {
        let pose = self.graph.pose?;
        let mut out = AbiTransform::IDENTITY;
        // SAFETY: the host's callback and context are valid for this submission; `out` is ours.
        (unsafe { pose(self.graph.context, id, &mut out) } != 0).then_some(out)
    }

    /// The odometry-only relative pose between two keyframes of one robot, with its covariance.
    pub fn odometry_between(&self, target: AbiKeyframeId, source: AbiKeyframeId) -> Option<AbiRelativePose> {
        let odometry_between = self.graph.odometry_between?;
        let mut out = AbiRelativePose {
            target_from_source: AbiTransform::IDENTITY,
            covariance: [0.0; 36],
        };
        // SAFETY: as for `pose`.
        (unsafe { odometry_between(self.graph.context, target, source, &mut out) } != 0).then_some(out)
    }

    /// Every keyframe in the graph.
    pub fn keyframes(&self) -> &[AbiKeyframeId] {
        self.keyframes
    }

    /// Every loop closure currently in the graph.
    pub fn loops(&self) -> &[AbiLoop] {
        self.loops
    }
}

/// What a verifier decided after one submission; PCM may retract loops it accepted earlier.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VerdictOutcome {
    pub accepted: Vec<u64>,
    pub retracted: Vec<u64>,
    /// Rejected loops with the reason.
    pub rejected: Vec<(u64, String)>,
}

/// A loop-closure verifier implemented in safe Rust, exported with
/// [`export_plugins!`](crate::export_plugins).
pub trait VerifierPlugin: Sized + Send + 'static {
    /// The registry name.
    const NAME: &'static str;
    /// One line for `skid plugins`.
    const SUMMARY: &'static str;
    /// The default parameters as TOML text; [`from_config`](Self::from_config) must accept it.
    const DEFAULT_CONFIG: &'static str;

    /// Builds an instance from TOML config text.
    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError>;

    /// Decides on a candidate (and possibly on earlier ones), given its clouds and the graph.
    fn submit(
        &mut self,
        candidate: &AbiLoop,
        target_cloud: &[Point],
        source_cloud: &[Point],
        graph: &GraphAccess<'_>,
    ) -> Result<VerdictOutcome, String>;
}

/// A verifier instance and the verdict it last lent the host.
struct Lending<T> {
    plugin: T,
    verdict: VerdictOutcome,
    rejections: Vec<AbiRejection>,
}

// SAFETY: `rejections` only points into `verdict`'s strings, owned by the same value; `T` is `Send`.
unsafe impl<T: Send> Send for Lending<T> {}

/// The verifier function table of plugin type `T`.
pub const fn verifier_vtable<T: VerifierPlugin>() -> VerifierVTable {
    VerifierVTable {
        create: Some(create::<T>),
        submit: Some(submit::<T>),
        destroy: Some(destroy::<Lending<T>>),
    }
}

fn lending<T: VerifierPlugin>(config: &str, context: &InstanceContext) -> Result<Lending<T>, ConfigError> {
    Ok(Lending {
        plugin: T::from_config(config, context)?,
        verdict: VerdictOutcome::default(),
        rejections: Vec::new(),
    })
}

unsafe extern "C" fn create<T: VerifierPlugin>(
    config: AbiStr,
    context: *const HostContext,
    out_handle: *mut Handle,
    error: *mut ErrorBuf,
) -> Status {
    // SAFETY: the host's pointers, passed on unchanged.
    unsafe { create_with(config, context, out_handle, error, lending::<T>) }
}

unsafe extern "C" fn submit<T: VerifierPlugin>(
    handle: Handle,
    candidate: *const AbiLoop,
    target_cloud: AbiCloud,
    source_cloud: AbiCloud,
    graph: *const AbiGraph,
    out: *mut AbiVerdict,
    error: *mut ErrorBuf,
) -> Status {
    guard(error, || {
        // SAFETY: the host passes a live handle from `create` and calls it from one thread at a time.
        let lending = unsafe { instance::<Lending<T>>(handle) }?;
        // SAFETY: the host passes null or values valid for this call.
        let (candidate, graph, out) = unsafe { (candidate.as_ref(), graph.as_ref(), out.as_mut()) };
        let (Some(candidate), Some(graph), Some(out)) = (candidate, graph, out) else {
            return Err(Failure::InvalidArgument("submit: null argument".to_owned()));
        };
        // SAFETY: the host's clouds and graph snapshots are valid for this call.
        let (target_cloud, source_cloud, keyframes, loops) = unsafe {
            (
                lent(target_cloud.points, target_cloud.count, "target points")?,
                lent(source_cloud.points, source_cloud.count, "source points")?,
                lent(graph.keyframes, graph.keyframe_count, "keyframes")?,
                lent(graph.loops, graph.loop_count, "loops")?,
            )
        };
        let access = GraphAccess {
            graph,
            keyframes,
            loops,
        };
        let verdict = lending
            .plugin
            .submit(candidate, target_cloud, source_cloud, &access)
            .map_err(Failure::Failed)?;
        lending.verdict = verdict;
        lending.rejections = lending
            .verdict
            .rejected
            .iter()
            .map(|(id, reason)| AbiRejection {
                id: *id,
                reason: AbiStr::borrowed(reason),
            })
            .collect();
        let verdict = &lending.verdict;
        *out = AbiVerdict {
            accepted: verdict.accepted.as_ptr(),
            accepted_count: verdict.accepted.len(),
            retracted: verdict.retracted.as_ptr(),
            retracted_count: verdict.retracted.len(),
            rejected: lending.rejections.as_ptr(),
            rejected_count: lending.rejections.len(),
        };
        Ok(())
    })
}
