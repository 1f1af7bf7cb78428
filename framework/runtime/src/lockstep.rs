//! The executor for a whole fleet in one process: every robot stepped in turn on one thread (bit-for-bit
//! reproducible), with messages delivered between steps. Under `deploy.mode = "threads"` or
//! `"processes"` the robots' front-ends run ahead on threads or in child processes and the hosts
//! consume their outputs in the same order, so the result is the same. The hosts run in scan time.

use std::time::Instant;

use skid_config::DeployMode;
use skid_core::{PluginError, Slot};

use crate::clock::CLOUD_RETRY_NANOS;
use crate::delivery::{deliver_to, send_all};
use crate::error::RuntimeError;
use crate::fleet::Fleet;
use crate::frontend::ThreadFeed;
use crate::summary::RunSummary;

/// Rounds of message delivery after each step, so a request and its reply complete within one step.
const DELIVERY_ROUNDS: usize = 4;

/// Most delivery rounds after the sources end, while requested clouds are still missing or loops and
/// frames are still being stated again.
const DRAIN_ROUNDS: usize = 20;

impl Fleet {
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
                if max_scans > 0 && robot.scans_read() >= max_scans {
                    robot.finished = true;
                    continue;
                }
                let mut outbox = Vec::new();
                let (scans, optimizations) = (robot.scans().len(), robot.optimizations());
                robot.finished = !robot
                    .step(&self.config, &mut outbox)
                    .map_err(crate::stop::or_interrupted)?;
                self.observers.after_step(robot, scans, optimizations);
                done += usize::from(!robot.finished);
                outbox.extend(robot.loop_upkeep(&self.config, CLOUD_RETRY_NANOS)?);
                send_all(robot, outbox);
            }
            self.sync_hub();
            self.deliver()?;
            progress(done);
        }
        // Let the last messages arrive: advance the simulated clock past the link latency, asking again
        // for clouds still missing and stating loops and frames again (over a lossy link, for up to
        // `DRAIN_ROUNDS` retry periods).
        for round in 0..DRAIN_ROUNDS {
            let waiting = self
                .robots
                .iter()
                .any(|robot| robot.awaits_clouds() || robot.restating());
            if round >= DELIVERY_ROUNDS && !waiting {
                break;
            }
            if let Some(hub) = &self.network {
                hub.advance_to(hub.now_nanos() + CLOUD_RETRY_NANOS);
                for robot in &mut self.robots {
                    robot.advance_clock_to(hub.now_nanos());
                    let again = robot.loop_upkeep(&self.config, CLOUD_RETRY_NANOS)?;
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
                    let feed = ThreadFeed::spawn(robot.robot(), front_end, max_scans).map_err(|e| {
                        RuntimeError::Plugin {
                            robot: robot.robot(),
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
        let Some(hub) = &self.network else { return };
        let newest = self
            .robots
            .iter()
            .filter_map(|r| r.scans().last().map(|s| s.stamp_nanos))
            .max()
            .unwrap_or(0);
        if newest > hub.now_nanos() {
            hub.advance_to(newest);
        }
        for robot in &self.robots {
            if let Some(truth) = robot.scans().last().and_then(|s| s.ground_truth) {
                let t = truth.translation.vector;
                hub.set_position(robot.robot(), [t.x, t.y, t.z]);
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
