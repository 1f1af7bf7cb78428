//! The verifier plugins: `pcm` (SKiD-SLAM's two stages, the cloud checks — truncated MSE, free space,
//! the peer's visibility — then PCM) and `gnc` (the cloud checks only; the outliers are left to graduated non-convexity in the
//! back-end, for ablation).

use serde::{Deserialize, Serialize};
use skid_core::slots::{GraphView, LoopCandidate, Verdict, Verifier};
use skid_core::{PluginError, PluginResult};

use crate::consistency::PcmLoop;
use crate::fitness::FitnessConfig;
use crate::free_space::FreeSpaceConfig;
use crate::odometry_bound::OdometryBound;
use crate::pcm::{Pcm, PcmParams};
use crate::peer_seen::{PeerSeenConfig, Sighting};

/// Parameters of the `pcm` verifier: `[verifier.pcm]` with the fitness check in `[verifier.pcm.fitness]`,
/// the free-space check in `[verifier.pcm.free_space]`, the peer-visibility check in
/// `[verifier.pcm.peer_seen]`, the odometry bound on intra-robot loops in `[verifier.pcm.odometry]` and
/// PCM in `[verifier.pcm.consistency]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PcmConfig {
    pub fitness: FitnessConfig,
    pub free_space: FreeSpaceConfig,
    pub peer_seen: PeerSeenConfig,
    pub odometry: OdometryBound,
    pub consistency: PcmParams,
}

/// Parameters of the `gnc` verifier.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct GncConfig {
    pub fitness: FitnessConfig,
    pub free_space: FreeSpaceConfig,
    pub peer_seen: PeerSeenConfig,
}

/// Runs the fitness check on a candidate: `Some(reason)` when it fails. A candidate without clouds (a
/// recorded pose graph replayed) is judged on its pose alone.
fn fitness_rejection(config: &FitnessConfig, candidate: &LoopCandidate<'_>) -> Option<String> {
    if !config.enabled || (candidate.target_cloud.is_empty() && candidate.source_cloud.is_empty()) {
        return None;
    }
    let closure = &candidate.closure;
    match config.measure(
        candidate.target_cloud.points(),
        candidate.source_cloud.points(),
        &closure.target_from_source,
    ) {
        Ok(fitness) => config.judge(&fitness),
        Err(reason) => Some(format!("truncated MSE: {reason}")),
    }
}

/// Runs the free-space check on a candidate: `Some(reason)` when its clouds see through each other. A
/// candidate without both clouds is judged on its pose alone.
fn free_space_rejection(config: &FreeSpaceConfig, candidate: &LoopCandidate<'_>) -> Option<String> {
    if !config.enabled || candidate.target_cloud.is_empty() || candidate.source_cloud.is_empty() {
        return None;
    }
    let closure = &candidate.closure;
    let count = config.count(
        candidate.target_cloud.points(),
        candidate.source_cloud.points(),
        &closure.target_from_source,
    );
    tracing::debug!(
        target_keyframe = %closure.target,
        source_keyframe = %closure.source,
        violating = count.violating,
        clustered = count.clustered,
        agreeing = count.agreeing,
        undecided = count.undecided,
        translation_m = ?closure.target_from_source.translation.vector.as_slice(),
        rotation_xyzw = ?closure.target_from_source.rotation.coords.as_slice(),
        "free space counted"
    );
    config.judge(&count)
}

/// Runs the peer-visibility check on a candidate: whether it puts one robot in the other's view at one
/// moment, and whether the scans show it absent or (with `confirm`) there.
fn peer_sighting(
    config: &PeerSeenConfig,
    candidate: &LoopCandidate<'_>,
    graph: &dyn GraphView,
    confirm: bool,
) -> Sighting {
    config.judge(
        &candidate.closure,
        (candidate.target_cloud.points(), candidate.source_cloud.points()),
        graph,
        confirm,
    )
}

/// [`peer_sighting`]'s refusal only: `Some(reason)` when the scans show the place empty.
fn peer_seen_rejection(
    config: &PeerSeenConfig,
    candidate: &LoopCandidate<'_>,
    graph: &dyn GraphView,
) -> Option<String> {
    config.refusal(
        &candidate.closure,
        (candidate.target_cloud.points(), candidate.source_cloud.points()),
        graph,
    )
}

/// Checks that both keyframes of a loop are in the graph.
fn unknown_keyframe(candidate: &LoopCandidate<'_>, graph: &dyn GraphView) -> Option<String> {
    let closure = &candidate.closure;
    [closure.target, closure.source]
        .into_iter()
        .find(|id| graph.pose(*id).is_none())
        .map(|id| format!("keyframe {id} is not in the graph"))
}

/// The `pcm` verifier.
pub struct PcmVerifier {
    fitness: FitnessConfig,
    free_space: FreeSpaceConfig,
    peer_seen: PeerSeenConfig,
    odometry: OdometryBound,
    pcm: Pcm,
}

impl PcmVerifier {
    pub fn new(config: PcmConfig) -> PluginResult<Self> {
        Ok(Self::from_checked(skid_core::registry::check::checked(
            "pcm", config,
        )?))
    }

    /// [`PcmVerifier::new`] for a configuration the registry has checked already (it is checked once,
    /// when the configuration is loaded).
    pub(crate) fn from_checked(config: PcmConfig) -> Self {
        Self {
            fitness: config.fitness,
            free_space: config.free_space,
            peer_seen: config.peer_seen,
            odometry: config.odometry,
            pcm: Pcm::from_checked(config.consistency),
        }
    }

    /// The PCM state (accepted loops, threshold).
    pub fn pcm(&self) -> &Pcm {
        &self.pcm
    }
}

impl Verifier for PcmVerifier {
    fn submit(&mut self, candidate: &LoopCandidate<'_>, graph: &dyn GraphView) -> PluginResult<Verdict> {
        let id = candidate.closure.id;
        let reject = |reason: String| {
            Ok(Verdict {
                rejected: vec![(id, reason)],
                ..Verdict::default()
            })
        };
        if let Some(reason) = unknown_keyframe(candidate, graph) {
            return reject(reason);
        }
        let mut pcm_loop = match PcmLoop::from_closure(&candidate.closure) {
            Ok(pcm_loop) => pcm_loop,
            Err(reason) => return reject(reason),
        };
        if let Some(reason) = self
            .odometry
            .refusal(&candidate.closure, graph)
            .or_else(|| fitness_rejection(&self.fitness, candidate))
            .or_else(|| free_space_rejection(&self.free_space, candidate))
        {
            return reject(reason);
        }
        match peer_sighting(&self.peer_seen, candidate, graph, self.pcm.reads_sightings()) {
            Sighting::Unseen(reason) => {
                // The refused loop still speaks against the frame hypotheses it agrees with.
                let retracted = self
                    .pcm
                    .add_unseen(pcm_loop, graph)
                    .map_err(PluginError::InvalidInput)?;
                if !retracted.is_empty() {
                    tracing::debug!(
                        target = %candidate.closure.target,
                        source = %candidate.closure.source,
                        withdrawn = retracted.len(),
                        "PCM: a granted set is withdrawn: a loop it agrees with puts a robot where the scans show nobody"
                    );
                }
                return Ok(Verdict {
                    rejected: vec![(id, reason)],
                    retracted,
                    ..Verdict::default()
                });
            }
            Sighting::Seen => {
                tracing::debug!(
                    target = %candidate.closure.target,
                    source = %candidate.closure.source,
                    "PCM: the loop's scans show each robot where it puts them"
                );
                pcm_loop.sighted = true;
            }
            Sighting::Unjudged => {}
        }
        let update = self.pcm.add(pcm_loop, graph).map_err(PluginError::InvalidInput)?;
        let mut verdict = Verdict {
            accepted: update.accepted.clone(),
            retracted: update.retracted.clone(),
            rejected: Vec::new(),
        };
        // A loop of a leading set that is not earned yet waits, neither accepted nor rejected.
        let waits = update.pending || (update.withheld.is_some() && update.in_leading_set);
        if let Some(reason) = &update.withheld {
            tracing::debug!(
                target = %candidate.closure.target,
                source = %candidate.closure.source,
                loops = update.clique_size,
                "PCM: the leading consistent set is not granted yet: {reason}"
            );
        }
        if !waits && !update.accepted.contains(&id) {
            verdict.rejected.push((
                id,
                format!(
                    "PCM: not in the maximum consistent set ({} of {} loops{})",
                    update.clique_size,
                    update.group_size,
                    if update.exact { "" } else { ", heuristic clique" }
                ),
            ));
        }
        Ok(verdict)
    }

    fn reconsider(&mut self, graph: &dyn GraphView) -> PluginResult<Verdict> {
        let (accepted, retracted) = self.pcm.reconsider(graph);
        Ok(Verdict {
            accepted,
            retracted,
            rejected: Vec::new(),
        })
    }
}

/// The `gnc` verifier: accepts every loop that passes the fitness check.
pub struct GncVerifier {
    fitness: FitnessConfig,
    free_space: FreeSpaceConfig,
    peer_seen: PeerSeenConfig,
}

impl GncVerifier {
    pub fn new(config: GncConfig) -> PluginResult<Self> {
        Self::from_checked(skid_core::registry::check::checked("gnc", config)?)
    }

    /// [`GncVerifier::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: GncConfig) -> PluginResult<Self> {
        Ok(Self {
            fitness: config.fitness,
            free_space: config.free_space,
            peer_seen: config.peer_seen,
        })
    }
}

impl Verifier for GncVerifier {
    fn submit(&mut self, candidate: &LoopCandidate<'_>, graph: &dyn GraphView) -> PluginResult<Verdict> {
        let id = candidate.closure.id;
        let reason = unknown_keyframe(candidate, graph)
            .or_else(|| PcmLoop::from_closure(&candidate.closure).err())
            .or_else(|| fitness_rejection(&self.fitness, candidate))
            .or_else(|| free_space_rejection(&self.free_space, candidate))
            .or_else(|| peer_seen_rejection(&self.peer_seen, candidate, graph));
        Ok(match reason {
            Some(reason) => Verdict {
                rejected: vec![(id, reason)],
                ..Verdict::default()
            },
            None => Verdict {
                accepted: vec![id],
                ..Verdict::default()
            },
        })
    }
}

impl skid_core::PluginParams for PcmConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.fitness
            .validate()
            .map_err(|error| error.in_table("fitness"))?;
        self.free_space
            .validate()
            .map_err(|error| error.in_table("free_space"))?;
        self.peer_seen
            .validate()
            .map_err(|error| error.in_table("peer_seen"))?;
        self.odometry
            .validate()
            .map_err(|error| error.in_table("odometry"))?;
        self.consistency
            .validate()
            .map_err(|error| error.in_table("consistency"))
    }
}

impl skid_core::PluginParams for GncConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.fitness
            .validate()
            .map_err(|error| error.in_table("fitness"))?;
        self.free_space
            .validate()
            .map_err(|error| error.in_table("free_space"))?;
        self.peer_seen
            .validate()
            .map_err(|error| error.in_table("peer_seen"))
    }
}
