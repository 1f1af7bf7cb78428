//! One robot's host: its plugin instances and the state that joins them (keyframes, odometry chains,
//! the descriptor index, loops), and the front-end step that turns one scan into odometry, keyframes,
//! descriptors and loop candidates.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;
use std::time::Instant;

use skid_config::ResolvedConfig;
use skid_core::slots::{
    Backend, CoarseRegistration, Descriptor, DescriptorBuf, DescriptorIndex, FineRegistration, LoopClosure,
    Odometry, OdometryMeasurement, OptimizeBudget, PreparedCloud, Source, Transport, Verifier,
};
use skid_core::{Cloud, Keyframe, KeyframeId, LoopId, PluginError, Pose, RobotId, Slot};
use skid_geometry::OdometryChains;
use skid_protocol::ProtocolEndpoint;

use crate::clock::HostClock;
use crate::error::RuntimeError;
use crate::frontend::{
    DetachedSource, FrontEnd, FrontEndError, FrontEndFeed, FrontEndOutput, OdometryOutcome,
};
use crate::peer_faults::PeerFaults;
use crate::settings::{information_from_covariance, odometry_step_covariance};
use crate::warn_limit::WarnLimiter;

/// The plugin instances of one robot; every slot but the source may be empty.
pub struct Plugins {
    pub source: Box<dyn Source>,
    pub odometry: Option<Box<dyn Odometry>>,
    pub descriptor: Option<Box<dyn Descriptor>>,
    pub coarse: Option<Box<dyn CoarseRegistration>>,
    pub fine: Option<Box<dyn FineRegistration>>,
    pub verifier: Option<Box<dyn Verifier>>,
    pub backend: Option<Box<dyn Backend>>,
    pub transport: Option<Box<dyn Transport>>,
}

/// One scan's odometry, remembered so the optimised trajectory can be rebuilt for every scan.
#[derive(Clone, Copy, Debug)]
pub struct ScanRecord {
    pub stamp_nanos: u64,
    pub world_from_sensor: Pose,
    /// The keyframe at or before this scan.
    pub keyframe: Option<u32>,
    pub ground_truth: Option<Pose>,
}

/// What became of this robot's loop candidates. Every candidate ends in exactly one outcome, so the
/// candidates add up: `candidates_intra + candidates_inter` equals `repeated_pair + cloud_missing +
/// awaiting_cloud + coarse_invalid + fine_not_converged + accepted_intra + accepted_inter + rejected +
/// undecided` ([`LoopStats::outcomes`]). The accepted, rejected and undecided counts are the state at the
/// time of reading (a loop PCM retracts counts as rejected); the last three fields count events.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct LoopStats {
    pub candidates_intra: usize,
    pub candidates_inter: usize,
    /// The same keyframe pair had been registered before.
    pub repeated_pair: usize,
    /// A keyframe's cloud was not held (a peer keyframe whose cloud never came).
    pub cloud_missing: usize,
    /// Inter-robot candidates still waiting for the peer's cloud.
    pub awaiting_cloud: usize,
    /// The coarse registration found no valid alignment.
    pub coarse_invalid: usize,
    /// The fine registration did not converge.
    pub fine_not_converged: usize,
    /// In this robot's graph, found by this robot.
    pub accepted_intra: usize,
    pub accepted_inter: usize,
    /// Refused by the verifier (truncated MSE or consistency), or accepted and later retracted.
    pub rejected: usize,
    /// Submitted to the verifier, which has not decided yet (PCM waits for enough loops of a pair).
    pub undecided: usize,
    /// Events: coarse alignments judged invalid but refined anyway (`loops.refine_invalid_coarse`),
    /// loops retracted, and accepted loops received from peers.
    pub coarse_invalid_refined: usize,
    pub retracted: usize,
    pub received_from_peers: usize,
}

impl LoopStats {
    /// The sum of the outcome counts, which equals the number of candidates.
    pub fn outcomes(&self) -> usize {
        self.repeated_pair
            + self.cloud_missing
            + self.awaiting_cloud
            + self.coarse_invalid
            + self.fine_not_converged
            + self.accepted_intra
            + self.accepted_inter
            + self.rejected
            + self.undecided
    }

    pub fn candidates(&self) -> usize {
        self.candidates_intra + self.candidates_inter
    }
}

/// Where one of this robot's own loops stands with the verifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopStanding {
    Accepted,
    Rejected,
    Undecided,
}

/// A peer candidate waiting for the peer's cloud.
#[derive(Clone, Copy, Debug)]
pub struct PendingCandidate {
    pub target: KeyframeId,
    pub source: KeyframeId,
    pub yaw_hint_rad: Option<f64>,
}

/// Everything one robot runs and knows.
pub struct RobotHost {
    pub robot: RobotId,
    pub plugins: Plugins,
    pub protocol: ProtocolEndpoint,
    pub chains: OdometryChains,
    pub keyframes: BTreeMap<u32, Arc<Keyframe>>,
    pub peer_clouds: HashMap<KeyframeId, Arc<Cloud>>,
    pub prepared: HashMap<KeyframeId, PreparedCloud>,
    pub index: Option<Box<dyn DescriptorIndex>>,
    pub pending: Vec<PendingCandidate>,
    /// Peer keyframes whose cloud was requested and has not arrived.
    pub requested: BTreeMap<KeyframeId, CloudRequestState>,
    /// The time cloud requests are kept in, chosen by the executor.
    pub clock: HostClock,
    pub loops: BTreeMap<LoopId, LoopClosure>,
    /// Loops identified across robots by their keyframe pair.
    pub loop_by_pair: BTreeMap<(KeyframeId, KeyframeId), LoopId>,
    pub next_loop_id: u64,
    /// Keyframes present in the back-end's graph.
    pub in_backend: BTreeSet<KeyframeId>,
    /// Peers whose odometry chain has been added to the back-end.
    pub peers_in_backend: BTreeSet<RobotId>,
    /// Submitted loops that are not (or no longer) accepted, kept because PCM may accept them later.
    pub pending_closures: BTreeMap<LoopId, LoopClosure>,
    /// Accepted loops that wait for a peer keyframe's odometry before entering the back-end.
    pub deferred_loops: Vec<LoopClosure>,
    /// Where each peer's odometry frame sits in this robot's frame, from the first loop with it.
    pub peer_frames: BTreeMap<RobotId, Pose>,
    pub scans: Vec<ScanRecord>,
    /// Event counters; [`RobotHost::loop_stats`] completes them with the loops' current standing.
    pub stats: LoopStats,
    /// Each loop this robot registered and submitted, with whether it is inter-robot.
    pub loop_standing: BTreeMap<LoopId, (bool, LoopStanding)>,
    /// Why the verifier refused (or retracted) each loop that stands rejected.
    pub rejection_reasons: BTreeMap<LoopId, String>,
    pub stage_ms: BTreeMap<&'static str, f64>,
    pub points_read: usize,
    /// Scans read from the source, including those the odometry skipped.
    pub scans_read: usize,
    /// Scans the odometry refused (too few points, a stamp going backwards, …), counted and warned about
    /// at a limited rate.
    pub skipped_scans: WarnLimiter,
    /// Well-formed peer messages refused (wrong descriptor kind, foreign loops, …), by class.
    pub peer_faults: PeerFaults,
    pub finished: bool,
    /// Set when the front-end runs on a thread or in another process.
    pub feed: Option<Box<dyn FrontEndFeed>>,
    /// How many times the back-end has optimised (observers learn of new optimisations from it).
    pub optimizations: u64,
    keyframes_since_optimize: u32,
}

/// When a cloud request was last sent, in this robot's [`HostClock`], and how long to wait before asking again (0: the first
/// retry period); the wait doubles with each retry so a congested link is not flooded with copies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CloudRequestState {
    pub sent_nanos: u64,
    pub wait_nanos: u64,
}

impl RobotHost {
    /// A host for `robot` that times its cloud requests by `clock`.
    pub fn new(robot: RobotId, plugins: Plugins, protocol: ProtocolEndpoint, clock: HostClock) -> Self {
        let index = plugins
            .descriptor
            .as_ref()
            .map(|descriptor| descriptor.new_index());
        Self {
            robot,
            plugins,
            protocol,
            chains: OdometryChains::default(),
            keyframes: BTreeMap::new(),
            peer_clouds: HashMap::new(),
            prepared: HashMap::new(),
            index,
            pending: Vec::new(),
            requested: BTreeMap::new(),
            clock,
            loops: BTreeMap::new(),
            loop_by_pair: BTreeMap::new(),
            next_loop_id: 0,
            in_backend: BTreeSet::new(),
            peers_in_backend: BTreeSet::new(),
            pending_closures: BTreeMap::new(),
            deferred_loops: Vec::new(),
            peer_frames: BTreeMap::new(),
            scans: Vec::new(),
            stats: LoopStats::default(),
            loop_standing: BTreeMap::new(),
            rejection_reasons: BTreeMap::new(),
            stage_ms: BTreeMap::new(),
            points_read: 0,
            scans_read: 0,
            skipped_scans: WarnLimiter::default(),
            peer_faults: PeerFaults::default(),
            finished: false,
            feed: None,
            optimizations: 0,
            keyframes_since_optimize: 0,
        }
    }

    /// The time now by this host's clock.
    pub fn now_nanos(&self) -> u64 {
        self.clock
            .now_nanos(self.scans.last().map_or(0, |scan| scan.stamp_nanos))
    }

    /// The loop counters with the accepted, rejected, undecided and awaiting counts as they stand now.
    pub fn loop_stats(&self) -> LoopStats {
        let mut stats = self.stats.clone();
        for (inter, standing) in self.loop_standing.values() {
            match (standing, inter) {
                (LoopStanding::Accepted, true) => stats.accepted_inter += 1,
                (LoopStanding::Accepted, false) => stats.accepted_intra += 1,
                (LoopStanding::Rejected, _) => stats.rejected += 1,
                (LoopStanding::Undecided, _) => stats.undecided += 1,
            }
        }
        stats.awaiting_cloud = self.pending.len();
        stats
    }

    pub(crate) fn plugin_error(
        &self,
        config: &ResolvedConfig,
        slot: Slot,
        source: PluginError,
    ) -> RuntimeError {
        RuntimeError::Plugin {
            robot: self.robot,
            slot,
            plugin: config.slot(slot).plugin.clone(),
            source,
        }
    }

    pub(crate) fn time<T>(&mut self, stage: &'static str, work: impl FnOnce(&mut Self) -> T) -> T {
        let started = Instant::now();
        let value = work(self);
        *self.stage_ms.entry(stage).or_default() += started.elapsed().as_secs_f64() * 1e3;
        value
    }

    /// Reads and processes one scan; false when the source has ended. Returns new descriptors to
    /// broadcast through `outbox`. The scan comes from the robot's feed when its front-end runs on a
    /// thread or in another process, else from its own source and odometry.
    pub fn step(
        &mut self,
        config: &ResolvedConfig,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<bool, RuntimeError> {
        let output = match self.feed.as_mut() {
            Some(feed) => feed.next(),
            None => {
                let mut front_end = self.detach_front_end();
                let output = front_end.next_output();
                self.plugins.source = front_end.source;
                self.plugins.odometry = front_end.odometry;
                output
            }
        };
        match output {
            Ok(Some(output)) => {
                self.apply_front_end(config, output, outbox)?;
                Ok(true)
            }
            Ok(None) => Ok(false),
            Err(FrontEndError { slot, source }) => Err(self.plugin_error(config, slot, source)),
        }
    }

    /// Moves this robot's source and odometry onto a feed (a thread or a process) that runs ahead.
    pub fn detach_front_end(&mut self) -> FrontEnd {
        FrontEnd {
            source: std::mem::replace(&mut self.plugins.source, Box::new(DetachedSource)),
            odometry: self.plugins.odometry.take(),
        }
    }

    /// Records one scan's front-end output and, for a keyframe, runs the rest of the pipeline.
    pub fn apply_front_end(
        &mut self,
        config: &ResolvedConfig,
        output: FrontEndOutput,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        self.points_read += output.points;
        self.scans_read += 1;
        *self.stage_ms.entry("source").or_default() += output.source_ms;
        let (world_from_sensor, keyframe) = match output.odometry {
            None => (Pose::identity(), None),
            Some(OdometryOutcome::Skipped { reason }) => {
                // A scan the odometry cannot use is skipped with a warning; the run goes on.
                if let Some(count) = self.skipped_scans.occurrence() {
                    tracing::warn!(
                        robot = %self.robot,
                        sequence = output.sequence,
                        skipped_so_far = count,
                        %reason,
                        "scan skipped (repeats are logged at 10, 100, 1000, …; all are counted in summary.json)"
                    );
                }
                return Ok(());
            }
            Some(OdometryOutcome::Registered {
                world_from_sensor,
                keyframe,
            }) => {
                *self.stage_ms.entry("odometry").or_default() += output.odometry_ms;
                (world_from_sensor, keyframe)
            }
        };
        let keyframe_index = keyframe
            .as_ref()
            .map(|k| k.id.index)
            .or_else(|| self.scans.last().and_then(|s| s.keyframe));
        self.scans.push(ScanRecord {
            stamp_nanos: output.stamp_nanos,
            world_from_sensor,
            keyframe: keyframe_index,
            ground_truth: output.ground_truth,
        });
        if let Some(keyframe) = keyframe {
            self.on_keyframe(config, keyframe, outbox)?;
        }
        Ok(())
    }

    /// Adds a keyframe to the chains and the back-end, describes it, shares it, and looks for loops.
    fn on_keyframe(
        &mut self,
        config: &ResolvedConfig,
        keyframe: Keyframe,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        let id = keyframe.id;
        let previous = id
            .index
            .checked_sub(1)
            .and_then(|index| self.keyframes.get(&index).map(|k| (index, k.world_from_sensor)));
        let step = previous.map_or(Pose::identity(), |(_, pose)| {
            pose.inverse() * keyframe.world_from_sensor
        });
        let step_covariance = odometry_step_covariance(&config.loops, &step);
        self.chains
            .insert(id, keyframe.world_from_sensor, step_covariance);
        let keyframe = Arc::new(keyframe);
        self.keyframes.insert(id.index, Arc::clone(&keyframe));
        outbox.push(crate::messages::chain_message(
            self.robot,
            id.index,
            &keyframe.world_from_sensor,
            step,
            step_covariance,
        ));

        if let Some(backend) = self.plugins.backend.as_mut() {
            let guess = match previous {
                Some((index, _)) => backend
                    .graph()
                    .pose(KeyframeId {
                        robot: self.robot,
                        index,
                    })
                    .map_or(keyframe.world_from_sensor, |p| p * step),
                None => keyframe.world_from_sensor,
            };
            backend
                .add_keyframe(id, guess)
                .map_err(|e| RuntimeError::Plugin {
                    robot: self.robot,
                    slot: Slot::Backend,
                    plugin: config.slot(Slot::Backend).plugin.clone(),
                    source: e,
                })?;
            self.in_backend.insert(id);
            if let Some((index, _)) = previous {
                let measurement = OdometryMeasurement {
                    target: KeyframeId {
                        robot: self.robot,
                        index,
                    },
                    source: id,
                    target_from_source: step,
                    information: information_from_covariance(&step_covariance),
                };
                backend
                    .add_odometry(measurement)
                    .map_err(|e| RuntimeError::Plugin {
                        robot: self.robot,
                        slot: Slot::Backend,
                        plugin: config.slot(Slot::Backend).plugin.clone(),
                        source: e,
                    })?;
            }
        }

        if self.plugins.descriptor.is_some() {
            let described = self.time("descriptor", |host| {
                host.plugins
                    .descriptor
                    .as_mut()
                    .map(|d| d.describe(keyframe.cloud.view()))
            });
            match described {
                Some(Ok(descriptor)) => self.on_descriptor(config, &keyframe, descriptor, outbox)?,
                Some(Err(PluginError::InvalidInput(reason))) => {
                    tracing::warn!(robot = %self.robot, keyframe = id.index, %reason, "keyframe not described");
                }
                Some(Err(error)) => return Err(self.plugin_error(config, Slot::Descriptor, error)),
                None => {}
            }
        }

        self.keyframes_since_optimize += 1;
        if self.keyframes_since_optimize >= config.loops.optimize_every_keyframes.max(1) {
            self.optimize(config)?;
        }
        Ok(())
    }

    /// Stores and shares a keyframe's descriptor, then queries the index for loop candidates.
    fn on_descriptor(
        &mut self,
        config: &ResolvedConfig,
        keyframe: &Keyframe,
        descriptor: DescriptorBuf,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        let id = keyframe.id;
        outbox.push(crate::messages::descriptor_message(
            self.robot,
            keyframe,
            &descriptor,
        ));
        let loops = &config.loops;
        let robot = self.robot;
        let threshold = if loops.max_descriptor_distance > 0.0 {
            loops.max_descriptor_distance
        } else {
            self.plugins
                .descriptor
                .as_ref()
                .map_or(f64::INFINITY, |d| d.match_threshold())
        };
        let exclude = |candidate: KeyframeId| {
            if candidate.robot == robot {
                !loops.intra_robot || candidate.index + loops.exclude_recent_keyframes >= id.index
            } else {
                !loops.inter_robot
            }
        };
        let Some(index) = self.index.as_mut() else {
            return Ok(());
        };
        let started = Instant::now();
        let found = index.query(&descriptor, loops.candidates, &exclude);
        index.insert(id, descriptor).map_err(|e| RuntimeError::Plugin {
            robot,
            slot: Slot::Descriptor,
            plugin: config.slot(Slot::Descriptor).plugin.clone(),
            source: e,
        })?;
        *self.stage_ms.entry("retrieval").or_default() += started.elapsed().as_secs_f64() * 1e3;
        let found = found.map_err(|e| self.plugin_error(config, Slot::Descriptor, e))?;
        for candidate in found.into_iter().filter(|c| c.distance <= threshold) {
            let pending = PendingCandidate {
                target: candidate.id,
                source: id,
                yaw_hint_rad: candidate.yaw_hint_rad,
            };
            if candidate.id.robot == robot {
                self.stats.candidates_intra += 1;
                self.process_candidate(config, pending, outbox)?;
            } else {
                self.stats.candidates_inter += 1;
                if self.peer_clouds.contains_key(&candidate.id) {
                    self.process_candidate(config, pending, outbox)?;
                } else {
                    if !self.requested.contains_key(&candidate.id) {
                        let sent_nanos = self.now_nanos();
                        self.requested.insert(
                            candidate.id,
                            CloudRequestState {
                                sent_nanos,
                                wait_nanos: 0,
                            },
                        );
                        outbox.push(crate::messages::cloud_request(self.robot, candidate.id));
                    }
                    self.pending.push(pending);
                }
            }
        }
        Ok(())
    }

    /// Optimises the back-end's graph, if there is one.
    pub fn optimize(&mut self, config: &ResolvedConfig) -> Result<(), RuntimeError> {
        self.keyframes_since_optimize = 0;
        self.optimizations += 1;
        let budget = OptimizeBudget {
            max_iterations: config.loops.optimize_iterations,
            ..OptimizeBudget::default()
        };
        let result = self.time("backend", |host| {
            host.plugins
                .backend
                .as_mut()
                .map(|backend| backend.optimize(budget))
        });
        match result {
            Some(Err(error)) => Err(self.plugin_error(config, Slot::Backend, error)),
            _ => Ok(()),
        }
    }

    /// The fine registration's preparation of a keyframe cloud, computed once per keyframe.
    pub(crate) fn prepared_cloud(
        &mut self,
        config: &ResolvedConfig,
        id: KeyframeId,
        cloud: &Cloud,
    ) -> Result<PreparedCloud, RuntimeError> {
        if let Some(prepared) = self.prepared.get(&id) {
            return Ok(prepared.clone());
        }
        let Some(fine) = self.plugins.fine.as_mut() else {
            return Err(self.plugin_error(
                config,
                Slot::Fine,
                PluginError::InvalidInput("no fine registration".into()),
            ));
        };
        let started = Instant::now();
        let prepared = fine.prepare(cloud.view()).map_err(|error| RuntimeError::Plugin {
            robot: self.robot,
            slot: Slot::Fine,
            plugin: config.slot(Slot::Fine).plugin.clone(),
            source: error,
        })?;
        *self.stage_ms.entry("fine_prepare").or_default() += started.elapsed().as_secs_f64() * 1e3;
        self.prepared.insert(id, prepared.clone());
        Ok(prepared)
    }

    /// The cloud of a keyframe this robot holds (its own, or a peer's it fetched).
    pub fn cloud_of(&self, id: KeyframeId) -> Option<Arc<Cloud>> {
        if id.robot == self.robot {
            self.keyframes.get(&id.index).map(|k| Arc::new(k.cloud.clone()))
        } else {
            self.peer_clouds.get(&id).cloned()
        }
    }

    /// The optimised pose of one of this robot's keyframes (odometry when there is no back-end).
    pub fn keyframe_pose(&self, index: u32) -> Option<Pose> {
        let id = KeyframeId {
            robot: self.robot,
            index,
        };
        self.plugins
            .backend
            .as_ref()
            .and_then(|backend| backend.graph().pose(id))
            .or_else(|| self.chains.pose(id))
    }

    /// The trajectory of every scan, corrected by the optimised keyframe poses.
    pub fn optimised_trajectory(&self) -> Vec<(u64, Pose)> {
        self.scans
            .iter()
            .map(|scan| {
                let corrected = scan.keyframe.and_then(|index| {
                    let odometry = self.chains.pose(KeyframeId {
                        robot: self.robot,
                        index,
                    })?;
                    Some(self.keyframe_pose(index)? * odometry.inverse() * scan.world_from_sensor)
                });
                (scan.stamp_nanos, corrected.unwrap_or(scan.world_from_sensor))
            })
            .collect()
    }
}
