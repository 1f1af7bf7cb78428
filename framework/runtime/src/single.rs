//! One robot of the fleet in its own process (`[deploy] robot = N`): the distributed setting of the
//! SKiD-SLAM paper (Sec. III), where each robot runs its own front-end, place recognition, registration
//! and back-end and talks to its peers over a real network (the `zenoh` transport).
//!
//! The robot is built exactly as in the lockstep fleet (robot N of `run.robots`, so the `sim` source
//! simulates that robot of the shared world) and its scans are played at their stamps' pace
//! (`deploy.playback_speed`). Between scans the robot polls its transport and answers its peers. Because
//! peers start, stop and restart on their own, the runner also:
//! - sends a heartbeat every [`HEARTBEAT_PERIOD`], so idle robots are still noticed;
//! - replays its chain, descriptors and loops to a peer whose new protocol session it sees (a late
//!   joiner or a restarted process; see the `catchup` module), and drops the repeats it receives itself;
//! - re-sends cloud requests that stay unanswered for [`CLOUD_RETRY_PERIOD`] (lost, or the peer was
//!   down), doubling the wait with each retry;
//! - keeps answering for up to `deploy.linger_s` after its source ends, so its peers' late requests
//!   succeed; it stops sooner once every robot of the fleet has said in its heartbeat that it is
//!   settled (its source ended, nothing waited for) for [`SETTLED_GRACE`] without a break.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use skid_config::ResolvedConfig;
use skid_core::slots::Destination;
use skid_core::{Registry, RobotId};
use skid_protocol::{Arrival, Capabilities, Message, PeerStatus};

use crate::catchup::CatchUp;
use crate::clock::{CLOUD_RETRY_NANOS, HostClock};
use crate::delivery::{deliver_filtered, send_all, send_to};
use crate::error::RuntimeError;
use crate::fleet::{Fleet, build_host};
use crate::host::RobotHost;
use crate::observer::Observers;
use crate::summary::RunSummary;

/// How often an idle robot says it is alive.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);
/// How long every robot of the fleet must have said it is settled before a lingering robot stops: a few
/// heartbeats, so a status sent just before the last descriptors arrived does not end the run.
pub const SETTLED_GRACE: Duration = Duration::from_secs(3);
/// Longest sleep between transport polls while waiting for the next scan.
const POLL_SLEEP: Duration = Duration::from_millis(5);

/// Why a single-robot run cannot start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum SingleRobotError {
    /// The configuration does not describe a single-robot run.
    #[error("{0}")]
    Config(String),
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
}

/// One robot of the fleet, run in real time in this process.
pub struct SingleRobot {
    /// A fleet holding only this robot, so the run's outputs are written as for any fleet.
    fleet: Fleet,
    catch_up: CatchUp,
    /// Whether each peer's latest `Hello` or `Heartbeat` said it is settled.
    peers_settled: BTreeMap<RobotId, bool>,
}

impl SingleRobot {
    /// Builds robot `deploy.robot` of the fleet. Its outputs go to `<output_dir>/<name>-robot<N>/`, so
    /// the processes of one fleet sharing a folder do not overwrite each other.
    pub fn build(mut config: ResolvedConfig, registry: &Registry) -> Result<Self, SingleRobotError> {
        config
            .deploy
            .validate(config.run.robots)
            .map_err(|error| SingleRobotError::Config(error.to_string()))?;
        let Some(index) = config.deploy.robot else {
            return Err(SingleRobotError::Config(
                "deploy.robot is not set: a single-robot run needs the robot's index".into(),
            ));
        };
        config.run.name = format!("{}-robot{index}", config.run.name);
        // Peers start, stop and restart on their own and this robot lingers after its scans end, so
        // its cloud requests are timed by the wall clock.
        let mut host = build_host(
            &config,
            registry,
            RobotId(index),
            fresh_session(index),
            HostClock::wall(),
            None,
        )?;
        let prior = crate::prior::load_prior(&config)?;
        if let Some(prior) = &prior {
            host.take_prior(prior, &config.slot(skid_core::Slot::Descriptor).plugin)?;
        }
        Ok(Self {
            fleet: Fleet {
                config,
                robots: vec![host],
                network: None,
                observers: Observers::default(),
                prior,
            },
            catch_up: CatchUp::default(),
            peers_settled: BTreeMap::new(),
        })
    }

    /// The one-robot fleet (for writing the run's outputs).
    pub fn fleet(&self) -> &Fleet {
        &self.fleet
    }

    /// The one-robot fleet, to attach observers to its robot.
    pub fn fleet_mut(&mut self) -> &mut Fleet {
        &mut self.fleet
    }

    /// Runs until the source ends (or `run.max_scans`), then lingers for up to `deploy.linger_s`
    /// answering peers (less once the whole fleet is settled); calls `progress(scans_done)` after each
    /// scan.
    pub fn run(&mut self, mut progress: impl FnMut(usize)) -> Result<RunSummary, RuntimeError> {
        let started = Instant::now();
        let speed = self.fleet.config.deploy.playback_speed;
        let linger = Duration::from_secs_f64(self.fleet.config.deploy.linger_s);
        // Wall time and stamp of the first scan: later scans are due at their stamp's offset.
        let mut first: Option<(Instant, u64)> = None;
        let mut linger_until = None;
        let mut next_heartbeat = started;
        let mut fleet_settled_since: Option<Instant> = None;
        crate::run_folder::begin(&self.fleet.config)?;
        self.say(Message::Hello(self.status()));
        loop {
            crate::stop::check()?;
            let deadline = match linger_until {
                Some(until) => until,
                None => {
                    let (finished, stamp) = self.step()?;
                    progress(self.robot().scans().len());
                    if finished {
                        tracing::info!(robot = %self.robot().robot(), linger_s = linger.as_secs_f64(), "source ended; answering peers");
                        *linger_until.insert(Instant::now() + linger)
                    } else {
                        let (at, first_stamp) = *first.get_or_insert((Instant::now(), stamp));
                        if speed > 0.0 {
                            at + Duration::from_secs_f64((stamp - first_stamp) as f64 * 1e-9 / speed)
                        } else {
                            Instant::now()
                        }
                    }
                }
            };
            // Serve the network at least once per scan, then until the next scan is due.
            loop {
                if Instant::now() >= next_heartbeat {
                    self.say(Message::Heartbeat(self.status()));
                    self.loop_upkeep()?;
                    next_heartbeat = Instant::now() + HEARTBEAT_PERIOD;
                }
                self.deliver()?;
                crate::stop::check()?;
                let now = Instant::now();
                if now >= deadline {
                    break;
                }
                if self.fleet_settled() {
                    let since = *fleet_settled_since.get_or_insert(now);
                    if now - since >= SETTLED_GRACE {
                        tracing::info!(robot = %self.robot().robot(), "every robot of the fleet is settled; ending the linger");
                        break;
                    }
                } else {
                    fleet_settled_since = None;
                }
                std::thread::sleep((deadline - now).min(POLL_SLEEP));
            }
            if linger_until.is_some() {
                break;
            }
        }
        let config = &self.fleet.config;
        self.fleet.robots[0].optimize(config)?;
        self.fleet.observers.finished(&self.fleet.robots);
        Ok(RunSummary::of(&self.fleet, started.elapsed().as_secs_f64()))
    }

    fn robot(&self) -> &RobotHost {
        &self.fleet.robots[0]
    }

    /// Processes one scan; returns whether the source has ended and the newest scan's stamp.
    fn step(&mut self) -> Result<(bool, u64), RuntimeError> {
        let config = &self.fleet.config;
        let max_scans = config.run.max_scans as usize;
        let robot = &mut self.fleet.robots[0];
        if max_scans > 0 && robot.scans().len() >= max_scans {
            robot.finished = true;
        } else {
            let mut outbox = Vec::new();
            let (scans, optimizations) = (robot.scans().len(), robot.optimizations());
            robot.finished = !robot.step(config, &mut outbox)?;
            self.fleet.observers.after_step(robot, scans, optimizations);
            self.catch_up.record(robot.robot(), &outbox, robot.loops_to_fleet);
            send_all(robot, outbox);
        }
        let stamp = robot.scans().last().map_or(0, |scan| scan.stamp_nanos);
        Ok((robot.finished, stamp))
    }

    /// Handles everything that arrived, then brings peers that started a new session up to date.
    fn deliver(&mut self) -> Result<(), RuntimeError> {
        let config = &self.fleet.config;
        let robot = &mut self.fleet.robots[0];
        let catch_up = &mut self.catch_up;
        let peers_settled = &mut self.peers_settled;
        let mut new_sessions = Vec::new();
        deliver_filtered(robot, config, |received| {
            if let Arrival::First { restarted } = received.arrival {
                tracing::info!(robot = %received.envelope.robot, restarted, "peer session started");
                new_sessions.push(received.envelope.robot);
            }
            match &mut received.message {
                Message::Descriptors(batch) => catch_up.keep_new_descriptors(batch),
                Message::Hello(status) | Message::Heartbeat(status) => {
                    peers_settled.insert(received.envelope.robot, status.settled);
                    true
                }
                _ => true,
            }
        })?;
        for peer in new_sessions {
            let replay = self.catch_up.replay_for(peer);
            tracing::debug!(to = %peer, messages = replay.len(), "catching a peer up");
            let robot = &mut self.fleet.robots[0];
            for message in replay {
                send_to(robot, Destination::Robot(peer), message);
            }
        }
        Ok(())
    }

    /// The loop budget's upkeep ([`RobotHost::loop_upkeep`]): expired waits, admissions, and cloud
    /// requests sent again after staying unanswered too long.
    fn loop_upkeep(&mut self) -> Result<(), RuntimeError> {
        let robot = &mut self.fleet.robots[0];
        let messages = robot.loop_upkeep(&self.fleet.config, CLOUD_RETRY_NANOS)?;
        send_all(robot, messages);
        Ok(())
    }

    /// This robot is settled: its source has ended and it waits for no candidate or cloud.
    fn settled(&self) -> bool {
        let robot = self.robot();
        robot.finished && !robot.candidates_waiting()
    }

    /// This robot and every other robot of the fleet (`run.robots`) are settled, as their latest
    /// statuses say; a robot never heard from is not.
    fn fleet_settled(&self) -> bool {
        let me = self.robot().robot();
        self.settled()
            && (0..self.fleet.config.run.robots)
                .map(RobotId)
                .filter(|&robot| robot != me)
                .all(|robot| self.peers_settled.get(&robot) == Some(&true))
    }

    /// This robot's status for `Hello` and `Heartbeat`.
    fn status(&self) -> PeerStatus {
        let robot = self.robot();
        PeerStatus {
            robot: robot.robot(),
            latest_keyframe: robot.keyframes().keys().next_back().copied(),
            capabilities: Capabilities {
                descriptor_kind: robot.descriptor_kind().unwrap_or_default(),
                descriptor_len: 0,
                serves_clouds: true,
                max_message_bytes: robot.protocol().config().max_message_bytes,
            },
            settled: self.settled(),
        }
    }

    fn say(&mut self, message: Message) {
        send_to(&mut self.fleet.robots[0], Destination::AllPeers, message);
    }
}

/// A protocol session number that differs between runs of this robot's process (the wall clock and the
/// process id), so peers tell a restarted robot from the one before.
fn fresh_session(robot: u32) -> u32 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |elapsed| elapsed.as_nanos() as u64);
    let mixed =
        (nanos ^ u64::from(std::process::id()) << 20 ^ u64::from(robot)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    (mixed >> 32) as u32
}
