//! One robot's host: its plugin instances and the state that joins them, with read-only views for the
//! outputs and observers. The state is kept in parts with one job each, each in its own file under
//! `host/`: the robot's own track (`own_track`), its loops (`loop_book`), the peer clouds it fetched
//! (`peer_clouds`), its record of the back-end's graph (`backend_book`) and the frames of the robots it
//! and its peers merged with (`frame_book`). The work is split the same
//! way: one scan's step (`scan_step`), a candidate's way to a loop (`loops`), and the peers' messages
//! (`peers`).

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::Instant;

use skid_config::ResolvedConfig;
use skid_core::slots::{
    Backend, CoarseRegistration, Descriptor, DescriptorBuf, DescriptorIndex, FineRegistration, GraphView,
    LoopClosure, Odometry, PreparedCloud, Source, Transport, Verifier,
};
use skid_core::{Cloud, Keyframe, KeyframeId, LoopId, PluginError, Pose, RobotId, Slot};
use skid_geometry::OdometryChains;
use skid_protocol::ProtocolEndpoint;

use crate::clock::HostClock;
use crate::error::RuntimeError;
use crate::frontend::FrontEndFeed;
use crate::peer_faults::PeerFaults;

mod admission;
mod announced;
mod backend_book;
mod candidate_queue;
mod fleet_loops;
mod frame_book;
mod loop_book;
mod loops;
mod merges;
mod own_track;
mod peer_clouds;
mod peers;
mod placements;
mod prior_peer;
mod repeats;
mod restatements;
mod retrieval;
mod scan_step;
mod served_clouds;

use announced::Announced;
use backend_book::BackendBook;
use candidate_queue::CandidateQueue;
use frame_book::FrameBook;
pub use frame_book::JoinedFrame;
use loop_book::LoopBook;
pub use loop_book::{LoopStanding, LoopStats, StandingLoop};
use own_track::OwnTrack;
pub use own_track::ScanRecord;
use peer_clouds::PeerClouds;
pub use placements::Placement;
pub use prior_peer::Localisation;
use repeats::Repeats;
pub use served_clouds::CloudServing;
use served_clouds::ServedClouds;

/// The plugin instances of one robot; every slot but the source may be empty.
pub struct Plugins {
    pub source: Box<dyn Source>,
    pub odometry: Option<Box<dyn Odometry>>,
    pub descriptor: Option<Box<dyn Descriptor>>,
    pub coarse: Option<Box<dyn CoarseRegistration>>,
    pub fine: Option<Box<dyn FineRegistration>>,
    pub verifier: Option<Box<dyn Verifier>>,
    /// A second instance of the verifier, for the loops peers found between other robots
    /// (`loops.fleet_loops`); `None` otherwise.
    pub fleet_verifier: Option<Box<dyn Verifier>>,
    pub backend: Option<Box<dyn Backend>>,
    pub transport: Option<Box<dyn Transport>>,
}

/// Everything one robot runs and knows, in parts with one job each: its own track ([`OwnTrack`]), the
/// loops it registered and was sent ([`LoopBook`]), the peer clouds it fetched ([`PeerClouds`]), and
/// its record of the back-end's graph ([`BackendBook`]). The odometry chains (its own and its peers')
/// and the descriptor index are shared by all of them.
pub struct RobotHost {
    robot: RobotId,
    plugins: Plugins,
    protocol: ProtocolEndpoint,
    /// The time cloud requests are kept in, chosen by the executor.
    clock: HostClock,
    chains: OdometryChains,
    /// When each known keyframe was recorded: own keyframes as they are made, peers' from their
    /// descriptors (the verifier tells robots that would have stood on each other apart).
    keyframe_stamps: BTreeMap<KeyframeId, u64>,
    index: Option<Box<dyn DescriptorIndex>>,
    /// The fine registration's preparation of each keyframe cloud, computed once per keyframe.
    prepared: HashMap<KeyframeId, PreparedCloud>,
    own: OwnTrack,
    loops: LoopBook,
    peer_clouds: PeerClouds,
    /// Inter-robot candidates waiting for the loop-closure budget.
    candidates: CandidateQueue,
    /// The own clouds sent to each peer.
    served: ServedClouds,
    /// The newest keyframe of each peer whose descriptor the index holds (sent with each own descriptor,
    /// so a peer knows which candidates this robot could not see).
    held_descriptors: BTreeMap<RobotId, u32>,
    /// When (by the host's clock) a message from each peer last arrived.
    heard_nanos: BTreeMap<RobotId, u64>,
    /// Well-formed peer messages refused (wrong descriptor kind, foreign loops, …), by class.
    peer_faults: PeerFaults,
    graph: BackendBook,
    /// Where this robot and its peers place the robots they merged with.
    frames: FrameBook,
    /// The own inter-robot loops told to each peer, and when they are stated again.
    announced: Announced,
    /// Loops peers found that do not join this robot (`loops.fleet_loops`).
    fleet_loops: fleet_loops::FleetLoopBook,
    /// Every `Loops` message goes to every peer (`loops.fleet_loops`), not only to the one it concerns.
    pub(crate) loops_to_fleet: bool,
    /// When this robot's frames are next sent again after a change.
    frame_repeats: Repeats<()>,
    stage_ms: BTreeMap<&'static str, f64>,
    /// The session robot that recorded each keyframe of the prior peer, by its index (`[prior]`).
    prior_session_robots: Vec<u32>,
    /// Set by the executor once the robot's source has ended.
    pub(crate) finished: bool,
    /// Set when the front-end runs on a thread or in another process.
    pub(crate) feed: Option<Box<dyn FrontEndFeed>>,
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
            clock,
            chains: OdometryChains::default(),
            keyframe_stamps: BTreeMap::new(),
            index,
            prepared: HashMap::new(),
            own: OwnTrack::default(),
            loops: LoopBook::default(),
            peer_clouds: PeerClouds::default(),
            candidates: CandidateQueue::default(),
            served: ServedClouds::default(),
            held_descriptors: BTreeMap::new(),
            heard_nanos: BTreeMap::new(),
            peer_faults: PeerFaults::default(),
            graph: BackendBook::default(),
            frames: FrameBook::default(),
            announced: Announced::default(),
            fleet_loops: fleet_loops::FleetLoopBook::default(),
            loops_to_fleet: false,
            frame_repeats: Repeats::default(),
            stage_ms: BTreeMap::new(),
            prior_session_robots: Vec::new(),
            finished: false,
            feed: None,
        }
    }

    pub fn robot(&self) -> RobotId {
        self.robot
    }

    /// Every registered scan, in order.
    pub fn scans(&self) -> &[ScanRecord] {
        self.own.scans()
    }

    /// This robot's keyframes by index.
    pub fn keyframes(&self) -> &BTreeMap<u32, Arc<Keyframe>> {
        self.own.keyframes()
    }

    /// The descriptors of its own keyframes, by keyframe index.
    pub fn own_descriptors(&self) -> &BTreeMap<u32, DescriptorBuf> {
        self.own.descriptors()
    }

    /// Scans read from the source, including those the odometry skipped.
    pub fn scans_read(&self) -> usize {
        self.own.scans_read()
    }

    /// Scans the odometry skipped.
    pub fn scans_skipped(&self) -> u64 {
        self.own.scans_skipped()
    }

    /// Registered scans the odometry found degenerate.
    pub fn degenerate_scans(&self) -> u64 {
        self.own.degenerate_scans()
    }

    /// Points read from the source.
    pub fn points_read(&self) -> usize {
        self.own.points_read()
    }

    /// The odometry chains this robot knows: its own and its peers'.
    pub fn chains(&self) -> &OdometryChains {
        &self.chains
    }

    /// The back-end's graph, when there is a back-end.
    pub fn backend_graph(&self) -> Option<&dyn GraphView> {
        self.plugins.backend.as_ref().map(|backend| backend.graph())
    }

    /// The peers whose keyframes are in this robot's graph, each with where its odometry frame was placed
    /// in this robot's frame when it joined.
    pub fn joined_peers(&self) -> impl Iterator<Item = (RobotId, Pose)> + '_ {
        self.graph
            .peers()
            .filter_map(|peer| Some((peer, self.graph.peer_frame(peer)?)))
    }

    /// The keyframes of `robot` in this robot's graph, in index order.
    pub fn graph_keyframes_of(&self, robot: RobotId) -> impl Iterator<Item = KeyframeId> + '_ {
        self.graph.keyframes_of(robot)
    }

    /// Whether a keyframe is in this robot's graph.
    pub fn in_graph(&self, id: KeyframeId) -> bool {
        self.graph.contains(id)
    }

    /// How many times the back-end has optimised (observers learn of new optimisations from it).
    pub fn optimizations(&self) -> u64 {
        self.graph.optimizations()
    }

    /// Milliseconds spent per pipeline stage.
    pub fn stage_ms(&self) -> &BTreeMap<&'static str, f64> {
        &self.stage_ms
    }

    pub fn protocol(&self) -> &ProtocolEndpoint {
        &self.protocol
    }

    pub(crate) fn protocol_mut(&mut self) -> &mut ProtocolEndpoint {
        &mut self.protocol
    }

    /// The transport plugin, when this robot has one.
    pub fn transport(&self) -> Option<&dyn Transport> {
        self.plugins.transport.as_deref()
    }

    /// The transport and the protocol endpoint together, to send or receive through them.
    pub(crate) fn transport_and_protocol(
        &mut self,
    ) -> Option<(&mut (dyn Transport + 'static), &mut ProtocolEndpoint)> {
        let transport = self.plugins.transport.as_deref_mut()?;
        Some((transport, &mut self.protocol))
    }

    /// The kind of descriptor this robot computes and matches, when it has a descriptor.
    pub fn descriptor_kind(&self) -> Option<String> {
        self.plugins.descriptor.as_ref().map(|d| d.kind().to_owned())
    }

    /// Refused peer messages by class.
    pub fn peer_faults(&self) -> &PeerFaults {
        &self.peer_faults
    }

    pub(crate) fn peer_faults_mut(&mut self) -> &mut PeerFaults {
        &mut self.peer_faults
    }

    /// The robots this robot has merged with (it holds accepted loops with them), each with the pose of
    /// its first keyframe in the frame of this robot's first keyframe and the loops behind it, as of the
    /// last refresh (each keyframe and each loop decision).
    pub fn merged_frames(&self) -> &BTreeMap<RobotId, (Pose, u32)> {
        self.frames.own()
    }

    /// Every robot this robot can place in its frame: those it merged with, and those joined through
    /// the frames its merged peers reported (see [`JoinedFrame`]).
    pub fn joined_frames(&self) -> BTreeMap<RobotId, JoinedFrame> {
        self.frames.joined(self.robot)
    }

    /// When each robot was first placed in this robot's frame (directly or through others), by this
    /// host's clock (scan time in a fleet run); a robot that left and came back keeps its first time.
    pub fn first_joined_nanos(&self) -> BTreeMap<RobotId, u64> {
        self.frames.placements().first_placed_nanos()
    }

    /// Every placement of every robot in this robot's frame over the run, oldest first: a merge
    /// withdrawn, or a frame that jumped to another hypothesis, ends one.
    pub fn placements(&self) -> &BTreeMap<RobotId, Vec<Placement>> {
        self.frames.placements().all()
    }

    /// The loops in this robot's graph (its own accepted ones and those its peers accepted with it).
    pub fn accepted_loops(&self) -> &BTreeMap<LoopId, LoopClosure> {
        self.loops.accepted()
    }

    /// Whether this robot knows the loop between `target` and `source` (found it, or was told of it by
    /// the peer that did).
    pub fn knows_loop(&self, target: KeyframeId, source: KeyframeId) -> bool {
        self.loops.knows_pair((target, source))
    }

    /// Whether the loop `id` was found by a peer (this robot was told of it) rather than by this robot.
    pub fn loop_from_peer(&self, id: LoopId) -> bool {
        self.loops.is_from_peer(id)
    }

    /// This robot's submitted loops, each with where it stands.
    pub fn standing_loops(&self) -> impl Iterator<Item = StandingLoop<'_>> {
        self.loops.standings()
    }

    /// When the oldest unanswered cloud request was (last) sent, by this host's clock.
    pub fn oldest_cloud_request_nanos(&self) -> Option<u64> {
        self.peer_clouds.oldest_request_nanos()
    }

    /// Whether inter-robot candidates still wait for a peer's cloud or for the budget.
    pub fn awaits_clouds(&self) -> bool {
        self.peer_clouds.waiting() > 0 || self.candidates.len() > 0
    }

    /// Whether this robot still has loop sets or frames to state again (see `host::repeats`).
    pub fn restating(&self) -> bool {
        self.announced.pending() || self.frame_repeats.pending()
    }

    /// Peer clouds that arrived while a copy was held already.
    pub fn clouds_received_again(&self) -> u64 {
        self.peer_clouds.received_again()
    }

    /// What this robot did with its peers' requests for its clouds.
    pub fn cloud_serving(&self) -> CloudServing {
        self.served.counts()
    }

    /// Moves this host's clock on to `nanos` (scan-time executors, after the sources end).
    pub(crate) fn advance_clock_to(&mut self, nanos: u64) {
        self.clock.advance_to(nanos);
    }

    /// The time now by this host's clock.
    pub fn now_nanos(&self) -> u64 {
        self.clock.now_nanos(self.own.newest_stamp_nanos().unwrap_or(0))
    }

    /// Inter-robot candidates still wait here, queued for the budget or for a peer's cloud (the
    /// `queued` and `awaiting_cloud` of [`Self::loop_stats`], without building the counters).
    pub(crate) fn candidates_waiting(&self) -> bool {
        self.candidates.len() > 0 || self.peer_clouds.waiting() > 0
    }

    /// The loop counters with the accepted, rejected, undecided and awaiting counts as they stand now.
    pub fn loop_stats(&self) -> LoopStats {
        let mut stats = self.loops.stats(loop_book::BudgetFigures {
            queued: self.candidates.len(),
            expired: self.candidates.expired(),
            admitted: self.candidates.admitted(),
            awaiting_cloud: self.peer_clouds.waiting(),
        });
        (stats.fleet_loops_held, stats.fleet_loops_in_graph) = self.fleet_loop_counts();
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

    /// Adds `elapsed_ms` to a stage's time.
    pub(crate) fn add_stage_ms(&mut self, stage: &'static str, elapsed_ms: f64) {
        *self.stage_ms.entry(stage).or_default() += elapsed_ms;
    }

    pub(crate) fn time<T>(&mut self, stage: &'static str, work: impl FnOnce(&mut Self) -> T) -> T {
        let started = Instant::now();
        let value = work(self);
        self.add_stage_ms(stage, started.elapsed().as_secs_f64() * 1e3);
        value
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
        self.add_stage_ms("fine_prepare", started.elapsed().as_secs_f64() * 1e3);
        self.prepared.insert(id, prepared.clone());
        Ok(prepared)
    }

    /// The cloud of a keyframe this robot holds (its own, or a peer's it fetched).
    pub fn cloud_of(&self, id: KeyframeId) -> Option<Arc<Cloud>> {
        if id.robot == self.robot {
            self.own.keyframe(id.index).map(|k| Arc::new(k.cloud.clone()))
        } else {
            self.peer_clouds.get(id)
        }
    }

    /// The optimised pose of one of this robot's keyframes (odometry when there is no back-end).
    pub fn keyframe_pose(&self, index: u32) -> Option<Pose> {
        let id = KeyframeId {
            robot: self.robot,
            index,
        };
        self.backend_graph()
            .and_then(|graph| graph.pose(id))
            .or_else(|| self.chains.pose(id))
    }

    /// The trajectory of every scan, corrected by the optimised keyframe poses.
    pub fn optimised_trajectory(&self) -> Vec<(u64, Pose)> {
        self.own
            .scans()
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
