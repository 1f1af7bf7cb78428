//! The fleet core every executor builds on: one [`RobotHost`] per robot, built from the resolved
//! configuration with its plugins and its clock. It runs nothing itself: `lockstep` steps a whole fleet
//! in one process (its front-ends inline, on threads or in child processes), `single` runs one robot of
//! it against live peers.

use std::sync::Arc;

use skid_config::ResolvedConfig;
use skid_core::slots::{SimulatedNetwork, Source};
use skid_core::{PluginContext, PluginError, Registry, RobotId, Slot};
use skid_protocol::{ProtocolConfig, ProtocolEndpoint};

use crate::clock::HostClock;
use crate::error::RuntimeError;
use crate::frontend::{DetachedSource, FrontEndFeed};
use crate::host::{Plugins, RobotHost};
use crate::observer::Observers;

/// Every robot of the run.
pub struct Fleet {
    pub config: ResolvedConfig,
    pub robots: Vec<RobotHost>,
    /// The in-process network when the robots' transport simulates one (`loopback`): its clock follows
    /// the scans' stamps and its link model sees the robots' true positions.
    pub network: Option<Arc<dyn SimulatedNetwork>>,
    /// What watches the robots as they run (a live ROS 2 bridge, …).
    pub observers: Observers,
    /// The prior map the robots localise in (`[prior]`), shared by every host.
    pub prior: Option<Arc<crate::prior::PriorMap>>,
}

/// A name for one fleet's run, unique within the process, for the plugins that share state between the
/// robots of one run (`PluginContext::run_scope`).
fn new_run_scope() -> String {
    static FLEETS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let serial = FLEETS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    format!("{}/{serial}", std::process::id())
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
    resolved
        .build(table, context)
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
        // Set once the source is built (`PluginContext::after_source`).
        ..PluginContext::default()
    }
}

/// Builds one robot's host: robot `robot` of a fleet of `run.robots`, with the whole host's thread
/// budget (in lockstep only one robot runs at a time), protocol session number `session` and the
/// executor's `clock`.
pub(crate) fn build_host(
    config: &ResolvedConfig,
    registry: &Registry,
    robot: RobotId,
    session: u32,
    clock: HostClock,
    run_scope: Option<String>,
) -> Result<RobotHost, RuntimeError> {
    build_host_fed(config, registry, robot, session, clock, run_scope, None)
}

/// Builds one robot's host as [`build_host`] does, or, given a `feed`, with no source or odometry: the
/// host reads the feed's outputs instead.
fn build_host_fed(
    config: &ResolvedConfig,
    registry: &Registry,
    robot: RobotId,
    session: u32,
    clock: HostClock,
    run_scope: Option<String>,
    feed: Option<Box<dyn FrontEndFeed>>,
) -> Result<RobotHost, RuntimeError> {
    let context = PluginContext {
        run_scope,
        ..plugin_context(config, robot)
    };
    let source: Box<dyn Source> = match &feed {
        Some(_) => Box::new(DetachedSource),
        None => build(&registry.source, config, &context)?.ok_or_else(|| RuntimeError::Plugin {
            robot,
            slot: Slot::Source,
            plugin: "none".into(),
            source: PluginError::InvalidInput("a source is required".into()),
        })?,
    };
    let context = context.after_source(source.as_ref());
    let odometry = match &feed {
        Some(_) => None,
        None => build(&registry.odometry, config, &context)?,
    };
    let plugins = Plugins {
        source,
        odometry,
        descriptor: build(&registry.descriptor, config, &context)?,
        coarse: build(&registry.coarse, config, &context)?,
        fine: build(&registry.fine, config, &context)?,
        verifier: build(&registry.verifier, config, &context)?,
        fleet_verifier: match config.loops.fleet_loops {
            true => build(&registry.verifier, config, &context)?,
            false => None,
        },
        backend: build(&registry.backend, config, &context)?,
        transport: build(&registry.transport, config, &context)?,
    };
    let protocol = ProtocolEndpoint::new(robot, session, ProtocolConfig::default());
    let mut host = RobotHost::new(robot, plugins, protocol, clock);
    host.feed = feed;
    host.loops_to_fleet = config.loops.fleet_loops;
    Ok(host)
}

impl Fleet {
    /// Builds every robot's plugins. `threads` is the whole host's budget; in lockstep every robot may
    /// use all of it, since only one robot runs at a time.
    pub fn build(config: ResolvedConfig, registry: &Registry) -> Result<Self, RuntimeError> {
        Self::build_fed(config, registry, Vec::new())
    }

    /// Builds the fleet with the first robots' front-ends replaced by `feeds`, one per robot in order
    /// (a replay of recorded keyframes, such as a saved session's): those robots have no source or
    /// odometry and take what their feed gives. Robots past the feeds' end are built as usual.
    pub fn build_fed(
        config: ResolvedConfig,
        registry: &Registry,
        feeds: Vec<Box<dyn FrontEndFeed>>,
    ) -> Result<Self, RuntimeError> {
        let run_scope = new_run_scope();
        let mut feeds = feeds.into_iter();
        let prior = crate::prior::load_prior(&config)?;
        let mut robots = Vec::new();
        for index in 0..config.run.robots {
            // Lockstep runs must reproduce bit for bit, so the session number comes from the seed.
            let session = (config.run.seed as u32)
                .wrapping_mul(2_654_435_761)
                .wrapping_add(index);
            robots.push(build_host_fed(
                &config,
                registry,
                RobotId(index),
                session,
                HostClock::scan_time(),
                Some(run_scope.clone()),
                feeds.next(),
            )?);
            if let (Some(prior), Some(host)) = (&prior, robots.last_mut()) {
                host.take_prior(prior, &config.slot(Slot::Descriptor).plugin)?;
            }
        }
        let network = robots
            .iter()
            .find_map(|robot| robot.transport()?.simulated_network());
        Ok(Self {
            config,
            robots,
            network,
            observers: Observers::default(),
            prior,
        })
    }
}
