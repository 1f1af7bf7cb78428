//! The fleet: one [`RobotHost`] per robot, built from the resolved configuration, stepped in lockstep
//! (one thread, every robot in turn, bit-for-bit reproducible), with messages delivered between steps.

use std::time::{Duration, Instant};

use skid_config::{DeployMode, ResolvedConfig};
use skid_core::{PluginContext, PluginError, Registry, RobotId, Slot};
use skid_protocol::{Incoming, Message, ProtocolConfig, ProtocolEndpoint};

use crate::RuntimeError;
use crate::frontend::ThreadFeed;
use crate::host::{Plugins, RobotHost};
use crate::observer::Observers;
use crate::summary::RunSummary;

/// Every robot of the run.
pub struct Fleet {
    pub config: ResolvedConfig,
    pub robots: Vec<RobotHost>,
    /// The in-process hub when the robots talk through the `loopback` transport: its simulated clock
    /// follows the scans' stamps and its link model sees the robots' true positions.
    pub hub: Option<skid_transport_loopback::LoopbackHub>,
    /// What watches the robots as they run (a live ROS 2 bridge, …).
    pub observers: Observers,
}

/// Gives the `loopback` transport's hub a name unique to this fleet, so two runs in one process (tests,
/// benchmarks) never share links. Returns the name.
fn isolate_loopback_hub(config: &mut ResolvedConfig) -> Option<String> {
    let transport = config.slots.get_mut(&Slot::Transport)?;
    if transport.plugin != "loopback" {
        return None;
    }
    static FLEETS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let serial = FLEETS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut table = transport.params.table().clone();
    let base = table
        .get("hub")
        .and_then(|v| v.as_str())
        .unwrap_or("default")
        .to_owned();
    let name = format!("{base}/{}/{serial}", std::process::id());
    table.insert("hub".into(), toml::Value::String(name.clone()));
    transport.params = skid_core::Params::new(table);
    Some(name)
}

pub(crate) fn build<T: ?Sized + 'static>(
    table: &skid_core::SlotTable<T>,
    config: &ResolvedConfig,
    context: &PluginContext,
) -> Result<Option<Box<T>>, RuntimeError> {
    let slot = table.slot();
    let resolved = config.slot(slot);
    if resolved.is_none() {
        return Ok(None);
    }
    table
        .create(&resolved.plugin, &resolved.params, context)
        .map(Some)
        .map_err(|source| RuntimeError::Plugin {
            robot: context.robot,
            slot,
            plugin: resolved.plugin.clone(),
            source,
        })
}

/// The context robot `robot`'s plugins are built with, in any executor.
pub(crate) fn plugin_context(config: &ResolvedConfig, robot: RobotId) -> PluginContext {
    let threads = if config.run.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        config.run.threads
    };
    PluginContext {
        robot,
        fleet_size: config.run.robots,
        threads: threads.max(1),
        seed: config.run.seed,
        output_dir: Some(crate::run_folder::run_folder(config).path().to_path_buf()),
        source_provides_imu: false,
    }
}

/// Builds one robot's host: robot `robot` of a fleet of `run.robots`, with the whole host's thread
/// budget (in lockstep only one robot runs at a time) and protocol session number `session`.
pub(crate) fn build_host(
    config: &ResolvedConfig,
    registry: &Registry,
    robot: RobotId,
    session: u32,
) -> Result<RobotHost, RuntimeError> {
    let context = plugin_context(config, robot);
    let source = build(&registry.source, config, &context)?.ok_or_else(|| RuntimeError::Plugin {
        robot,
        slot: Slot::Source,
        plugin: "none".into(),
        source: PluginError::InvalidInput("a source is required".into()),
    })?;
    let context = context.after_source(source.as_ref());
    let plugins = Plugins {
        source,
        odometry: build(&registry.odometry, config, &context)?,
        descriptor: build(&registry.descriptor, config, &context)?,
        coarse: build(&registry.coarse, config, &context)?,
        fine: build(&registry.fine, config, &context)?,
        verifier: build(&registry.verifier, config, &context)?,
        backend: build(&registry.backend, config, &context)?,
        transport: build(&registry.transport, config, &context)?,
    };
    let protocol = ProtocolEndpoint::new(robot, session, ProtocolConfig::default());
    Ok(RobotHost::new(robot, plugins, protocol))
}

/// Rounds of message delivery after each step, so a request and its reply complete within one step.
const DELIVERY_ROUNDS: usize = 4;

/// Most delivery rounds after the sources end, while requested clouds are still missing.
const DRAIN_ROUNDS: usize = 20;

/// How long, in scan time, a robot waits for a requested cloud before asking again (the wall-clock
/// executors use [`crate::single::CLOUD_RETRY_PERIOD`]).
const CLOUD_RETRY_NANOS: u64 = crate::single::CLOUD_RETRY_PERIOD.as_nanos() as u64;

impl Fleet {
    /// Builds every robot's plugins. `threads` is the whole host's budget; in lockstep every robot may
    /// use all of it, since only one robot runs at a time.
    pub fn build(mut config: ResolvedConfig, registry: &Registry) -> Result<Self, RuntimeError> {
        let hub_name = isolate_loopback_hub(&mut config);
        let mut robots = Vec::new();
        for index in 0..config.run.robots {
            // Lockstep runs must reproduce bit for bit, so the session number comes from the seed.
            let session = (config.run.seed as u32)
                .wrapping_mul(2_654_435_761)
                .wrapping_add(index);
            robots.push(build_host(&config, registry, RobotId(index), session)?);
        }
        let hub = hub_name.and_then(|name| skid_transport_loopback::LoopbackHub::find(&name));
        Ok(Self {
            config,
            robots,
            hub,
            observers: Observers::default(),
        })
    }

    /// Runs every robot in lockstep until all sources end (or `max_scans` per robot), calling
    /// `progress(scans_done)` after each round.
    pub fn run_lockstep(&mut self, mut progress: impl FnMut(usize)) -> Result<RunSummary, RuntimeError> {
        let started = Instant::now();
        let max_scans = self.config.run.max_scans as usize;
        crate::run_folder::begin(&self.config)?;
        self.start_feeds()?;
        let mut done = 0;
        while self.robots.iter().any(|robot| !robot.finished) {
            crate::stop::check()?;
            for index in 0..self.robots.len() {
                let robot = &mut self.robots[index];
                if robot.finished {
                    continue;
                }
                if max_scans > 0 && robot.scans_read >= max_scans {
                    robot.finished = true;
                    continue;
                }
                let mut outbox = Vec::new();
                let (scans, optimizations) = (robot.scans.len(), robot.optimizations);
                robot.finished = !robot
                    .step(&self.config, &mut outbox)
                    .map_err(crate::stop::or_interrupted)?;
                self.observers.after_step(robot, scans, optimizations);
                done += usize::from(!robot.finished);
                if let Some(now_nanos) = robot.scans.last().map(|s| s.stamp_nanos) {
                    outbox.extend(robot.due_cloud_requests(now_nanos, CLOUD_RETRY_NANOS));
                }
                send_all(robot, outbox);
            }
            self.sync_hub();
            self.deliver()?;
            progress(done);
        }
        // Let the last messages arrive: advance the simulated clock past the link latency, asking again
        // for clouds still missing (over a lossy link, for up to `DRAIN_ROUNDS` retry periods).
        for round in 0..DRAIN_ROUNDS {
            let waiting = self.robots.iter().any(|robot| !robot.requested.is_empty());
            if round >= DELIVERY_ROUNDS && !waiting {
                break;
            }
            if let Some(hub) = &self.hub {
                hub.advance_to(hub.now_nanos() + CLOUD_RETRY_NANOS);
                for robot in &mut self.robots {
                    let again = robot.due_cloud_requests(hub.now_nanos(), CLOUD_RETRY_NANOS);
                    send_all(robot, again);
                }
            }
            self.deliver()?;
        }
        for robot in &mut self.robots {
            robot.optimize(&self.config)?;
        }
        self.observers.finished(&self.robots);
        Ok(RunSummary::of(self, started.elapsed().as_secs_f64()))
    }

    /// Under `deploy.mode = "threads"` moves each robot's source and odometry onto its own thread, so
    /// the front-ends run ahead in parallel while the host consumes their outputs in lockstep order
    /// (the result is the same as `lockstep`). Under `processes` each front-end runs in a child process
    /// that hands its keyframes over iceoryx2 shared memory.
    fn start_feeds(&mut self) -> Result<(), RuntimeError> {
        let max_scans = self.config.run.max_scans as usize;
        match self.config.deploy.mode {
            DeployMode::Lockstep => Ok(()),
            DeployMode::Threads => {
                for robot in &mut self.robots {
                    if robot.feed.is_some() {
                        continue;
                    }
                    let front_end = robot.detach_front_end();
                    let feed = ThreadFeed::spawn(robot.robot, front_end, max_scans).map_err(|e| {
                        RuntimeError::Plugin {
                            robot: robot.robot,
                            slot: Slot::Source,
                            plugin: self.config.slot(Slot::Source).plugin.clone(),
                            source: PluginError::Failed {
                                plugin: "front-end thread".into(),
                                message: e.to_string(),
                            },
                        }
                    })?;
                    robot.feed = Some(Box::new(feed));
                }
                Ok(())
            }
            DeployMode::Processes => crate::process::start_process_feeds(self),
        }
    }

    /// Moves the hub's simulated clock to the newest scan stamp and tells it where the robots are.
    fn sync_hub(&self) {
        let Some(hub) = &self.hub else { return };
        let newest = self
            .robots
            .iter()
            .filter_map(|r| r.scans.last().map(|s| s.stamp_nanos))
            .max()
            .unwrap_or(0);
        if newest > hub.now_nanos() {
            hub.advance_to(newest);
        }
        for robot in &self.robots {
            if let Some(truth) = robot.scans.last().and_then(|s| s.ground_truth) {
                let t = truth.translation.vector;
                hub.set_position(robot.robot, [t.x, t.y, t.z]);
            }
        }
    }

    /// Polls every robot's transport and acts on what arrived, a few rounds so replies come through.
    fn deliver(&mut self) -> Result<(), RuntimeError> {
        for _ in 0..DELIVERY_ROUNDS {
            let mut delivered = 0;
            for robot in &mut self.robots {
                delivered += deliver_to(robot, &self.config)?;
            }
            if delivered == 0 {
                break;
            }
        }
        Ok(())
    }
}

/// Encodes and sends messages from `robot` to their destinations. A send that fails (link down,
/// oversized) is logged: a robot never stops because a peer cannot be reached.
pub(crate) fn send_all(robot: &mut RobotHost, messages: Vec<Message>) {
    let Some(transport) = robot.plugins.transport.as_mut() else {
        return;
    };
    for message in messages {
        let destination = crate::peers::destination(robot.robot, &message);
        match robot.protocol.encode(&message) {
            Ok(bytes) => {
                if let Err(error) = transport.send(destination, &bytes) {
                    tracing::warn!(robot = %robot.robot, %error, "send failed");
                }
            }
            Err(error) => tracing::warn!(robot = %robot.robot, %error, "message not encoded"),
        }
    }
}

/// Receives and handles everything waiting for `robot`; returns how many messages it handled.
pub(crate) fn deliver_to(robot: &mut RobotHost, config: &ResolvedConfig) -> Result<usize, RuntimeError> {
    deliver_filtered(robot, config, |_| true)
}

/// [`deliver_to`], with `keep` seeing (and possibly editing) every new message before it is handled;
/// a message for which it returns false is dropped.
pub(crate) fn deliver_filtered(
    robot: &mut RobotHost,
    config: &ResolvedConfig,
    mut keep: impl FnMut(&mut skid_protocol::Received) -> bool,
) -> Result<usize, RuntimeError> {
    let Some(transport) = robot.plugins.transport.as_mut() else {
        return Ok(0);
    };
    let datagrams = match transport.poll(Duration::ZERO) {
        Ok(datagrams) => datagrams,
        Err(error) => {
            tracing::warn!(robot = %robot.robot, %error, "poll failed");
            return Ok(0);
        }
    };
    let count = datagrams.len();
    let mut outbox = Vec::new();
    let mut replies = Vec::new();
    for datagram in datagrams {
        match robot.protocol.receive(datagram.from, &datagram.payload) {
            Ok(Incoming::Message(mut received)) => {
                if !keep(&mut received) {
                    continue;
                }
                robot.handle_message(config, datagram.from, received.message, &mut replies, &mut outbox)?;
            }
            Ok(Incoming::Dropped { .. }) => {}
            Err(error) => {
                tracing::warn!(robot = %robot.robot, from = %datagram.from, %error, "malformed message dropped")
            }
        }
    }
    send_all(robot, outbox);
    if let Some(transport) = robot.plugins.transport.as_mut() {
        for (to, message) in replies {
            match robot.protocol.encode(&message) {
                Ok(bytes) => {
                    if let Err(error) = transport.send(skid_core::slots::Destination::Robot(to), &bytes) {
                        tracing::warn!(robot = %robot.robot, %error, "reply failed");
                    }
                }
                Err(error) => tracing::warn!(robot = %robot.robot, %error, "reply not encoded"),
            }
        }
    }
    Ok(count)
}
