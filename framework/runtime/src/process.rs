//! The `processes` executor: each robot's front-end (source + odometry) runs in its own child process
//! (`skid stage front-end`) and hands every scan's output — the odometry pose, the ground truth and, for
//! keyframes, the deskewed cloud — to the host over iceoryx2 shared memory ([`FrontEndScans`]: written
//! once by the child, read in place by the host, lossless with back-pressure).
//!
//! A front-end process that dies is detected (its exit status, and iceoryx2's dead-node cleanup reclaims
//! its shared memory), restarted, and told how many outputs the host already has: it replays its
//! deterministic source and odometry up to there without publishing and goes on from the last keyframe,
//! while the host's graph, which lives in the host process, stays intact. The result is the same as with
//! `threads` or `lockstep`. Every output carries its index; a gap (an output that never arrived, seen
//! once on a cold, loaded CI machine) is handled the same way: the front-end is restarted from the
//! host's count.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use skid_config::ResolvedConfig;
use skid_core::msgs::PoseWire;
use skid_core::pose::pose_to_wire;
use skid_core::{Cloud, Keyframe, KeyframeId, PluginError, Pose, Registry, RobotId, Slot};
use skid_ipc::{
    FRONT_END_DEGENERATE, FrontEndHeader, FrontEndScans, FrontEndStatus, ProcessNode, TopicPublisher,
    TopicSubscriber, ipc,
};

use crate::error::{RuntimeError, output_error};
use crate::fleet::{Fleet, build, plugin_context};
use crate::frontend::{FrontEnd, FrontEndError, FrontEndFeed, FrontEndOutput, OdometryOutcome};
use crate::run_folder::STAGES_FOLDER;

/// Environment variable naming the executable that runs stages (default: this executable).
pub const STAGE_EXE_VAR: &str = "SKID_STAGE_EXE";
/// Environment variable for fault-injection tests: the front-end process of the robot given as
/// `ROBOT:N` aborts right after publishing its `N`-th output, once (not after a restart).
pub const CRASH_AFTER_VAR: &str = "SKID_FRONT_END_CRASH_AFTER";
/// Restarts of one front-end allowed before the run fails.
const MAX_RESTARTS: u32 = 5;
/// How long a front-end process may take to connect before it is declared dead.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(60);

fn stage_error(robot: RobotId, message: impl ToString) -> RuntimeError {
    RuntimeError::Plugin {
        robot,
        slot: Slot::Source,
        plugin: "front-end process".into(),
        source: PluginError::Failed {
            plugin: "front-end process".into(),
            message: message.to_string(),
        },
    }
}

/// The iceoryx2 namespace of one robot's front-end in one run.
fn namespace(base: &str, robot: RobotId) -> String {
    format!("{base}/robot{}", robot.0)
}

/// Starts a front-end process per robot and hands each host its feed.
pub(crate) fn start_process_feeds(fleet: &mut Fleet) -> Result<(), RuntimeError> {
    let folder = crate::run_folder::begin(&fleet.config)?
        .path()
        .join(STAGES_FOLDER);
    std::fs::create_dir_all(&folder).map_err(|e| output_error(&folder, e))?;
    let config_path = folder.join("config.toml");
    std::fs::write(&config_path, fleet.config.to_toml_string()).map_err(|e| output_error(&config_path, e))?;
    let exe = match std::env::var_os(STAGE_EXE_VAR) {
        Some(path) => PathBuf::from(path),
        None => std::env::current_exe().map_err(|e| stage_error(RobotId(0), e))?,
    };
    static RUNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let base = format!(
        "skid{}x{}",
        std::process::id(),
        RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    );
    for robot in &mut fleet.robots {
        // The host's own source and odometry are not used: the child builds its own.
        drop(robot.detach_front_end());
        let feed = ProcessFeed::start(StageCommand {
            exe: exe.clone(),
            config_path: config_path.clone(),
            robot: robot.robot(),
            namespace: namespace(&base, robot.robot()),
        })?;
        robot.feed = Some(Box::new(feed));
    }
    Ok(())
}

/// How to start one robot's front-end process.
#[derive(Clone, Debug)]
struct StageCommand {
    exe: PathBuf,
    config_path: PathBuf,
    robot: RobotId,
    namespace: String,
}

impl StageCommand {
    fn spawn(&self, skip: u64, crash_allowed: bool) -> Result<Child, RuntimeError> {
        let mut command = Command::new(&self.exe);
        command
            .args(["-q", "stage", "front-end", "--config-file"])
            .arg(&self.config_path)
            .args(["--robot", &self.robot.0.to_string()])
            .args(["--namespace", &self.namespace])
            .args(["--skip", &skip.to_string()])
            .arg("--exit-with-host")
            // The child watches this pipe: when the host dies, however it dies, the pipe closes and
            // the child exits (see `exit_when_host_exits`).
            .stdin(Stdio::piped());
        if !crash_allowed {
            command.env_remove(CRASH_AFTER_VAR);
        }
        command
            .spawn()
            .map_err(|e| stage_error(self.robot, format!("starting {}: {e}", self.exe.display())))
    }
}

/// The host's end of one robot's front-end process.
pub struct ProcessFeed {
    command: StageCommand,
    node: ProcessNode,
    subscriber: TopicSubscriber<ipc::Service, FrontEndScans>,
    child: Child,
    started: Instant,
    connected: bool,
    /// Outputs taken so far; a restarted process skips this many.
    consumed: u64,
    restarts: u32,
    ended: bool,
}

impl ProcessFeed {
    fn start(command: StageCommand) -> Result<Self, RuntimeError> {
        let robot = command.robot;
        let node = ProcessNode::new(&format!("host-{}", robot.0), &command.namespace)
            .map_err(|e| stage_error(robot, e))?;
        let subscriber = node
            .subscriber::<FrontEndScans>()
            .map_err(|e| stage_error(robot, e))?;
        let child = command.spawn(0, true)?;
        Ok(Self {
            command,
            node,
            subscriber,
            child,
            started: Instant::now(),
            connected: false,
            consumed: 0,
            restarts: 0,
            ended: false,
        })
    }

    /// Restarts a front-end process that died, resuming after the outputs already taken.
    fn restart(&mut self, why: &str) -> Result<(), FrontEndError> {
        let robot = self.command.robot;
        if let Some(signal) = crate::stop::stop_requested() {
            return Err(failed(format!("stopped by signal {signal}")));
        }
        if self.restarts >= MAX_RESTARTS {
            return Err(failed(format!(
                "the front-end process of {robot} died {} times; last: {why}",
                self.restarts + 1
            )));
        }
        self.restarts += 1;
        tracing::warn!(%robot, why, resume_after = self.consumed, "front-end process died; restarting");
        // Stop the old process and drop what it published after the host's count: the new one
        // publishes those outputs again.
        let _ = self.child.kill();
        let _ = self.child.wait();
        while let Ok(Some(_)) = self.subscriber.try_receive() {}
        let report = self.node.cleanup_dead_nodes();
        tracing::debug!(%robot, cleaned = report.cleaned, failed = report.failed, "dead iceoryx2 nodes cleaned");
        self.child = self
            .command
            .spawn(self.consumed, false)
            .map_err(|e| failed(e.to_string()))?;
        self.started = Instant::now();
        self.connected = false;
        Ok(())
    }

    /// How many times the process was restarted.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }
}

fn failed(message: String) -> FrontEndError {
    FrontEndError {
        slot: Slot::Source,
        source: PluginError::Failed {
            plugin: "front-end process".into(),
            message,
        },
    }
}

impl FrontEndFeed for ProcessFeed {
    fn next(&mut self) -> Result<Option<FrontEndOutput>, FrontEndError> {
        if self.ended {
            return Ok(None);
        }
        loop {
            let received = self
                .subscriber
                .receive(Duration::from_millis(100))
                .map_err(|e| failed(e.to_string()))?;
            if let Some(sample) = received {
                self.connected = true;
                let header = *sample.header();
                // Outputs a dead incarnation published after the host's count are sent again.
                if header.output_index < self.consumed {
                    continue;
                }
                // A gap means an output never arrived: restart the front-end from the host's count
                // (it replays deterministically), so nothing is lost.
                if header.output_index > self.consumed {
                    drop(sample);
                    let why = format!(
                        "output {} arrived while {} was expected",
                        header.output_index, self.consumed
                    );
                    self.restart(&why)?;
                    continue;
                }
                self.consumed += 1;
                let decoded = decode(&header, sample.items());
                if !matches!(decoded, Ok(Some(_))) {
                    self.ended = true;
                }
                return decoded;
            }
            self.subscriber.take_publisher_events();
            if let Some(signal) = crate::stop::stop_requested() {
                return Err(failed(format!("stopped by signal {signal}")));
            }
            match self.child.try_wait() {
                Ok(Some(status)) => self.restart(&format!("exited with {status}"))?,
                Ok(None) if !self.connected && self.started.elapsed() > CONNECT_TIMEOUT => {
                    let _ = self.child.kill();
                    let _ = self.child.wait();
                    self.restart("did not connect in time")?;
                }
                Ok(None) => {}
                Err(error) => return Err(failed(format!("waiting for the front-end process: {error}"))),
            }
        }
    }
}

impl Drop for ProcessFeed {
    fn drop(&mut self) {
        // A finished front-end exits by itself once the host's subscriber is gone; one still running
        // (the run stopped early) is stopped.
        if !self.ended {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
    }
}

/// The pose the child encoded, bit for bit: its quaternion was unit when written, so it is taken as it
/// is (re-normalising would change the last bits and the run would no longer match `threads`).
fn pose_of(wire: &PoseWire) -> Pose {
    let [x, y, z, w] = wire.rotation_xyzw;
    let [tx, ty, tz] = wire.translation_m;
    Pose::from_parts(
        nalgebra::Translation3::new(tx, ty, tz),
        nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(w, x, y, z)),
    )
}

/// The host's view of one published output.
fn decode(
    header: &FrontEndHeader,
    points: &[skid_core::Point],
) -> Result<Option<FrontEndOutput>, FrontEndError> {
    let robot = RobotId(header.robot_id);
    let odometry = match header.status() {
        Some(FrontEndStatus::Ended) => return Ok(None),
        Some(FrontEndStatus::Failed) => {
            let message = header.message();
            let slot = if message.starts_with("source:") {
                Slot::Source
            } else {
                Slot::Odometry
            };
            return Err(FrontEndError {
                slot,
                source: PluginError::Failed {
                    plugin: "front-end process".into(),
                    message,
                },
            });
        }
        Some(FrontEndStatus::NoOdometry) => None,
        Some(FrontEndStatus::Skipped) => Some(OdometryOutcome::Skipped {
            reason: header.message(),
        }),
        Some(FrontEndStatus::Registered) => Some(OdometryOutcome::Registered {
            world_from_sensor: pose_of(&header.world_from_sensor),
            keyframe: (header.keyframe_index != u32::MAX).then(|| Keyframe {
                id: KeyframeId {
                    robot,
                    index: header.keyframe_index,
                },
                stamp_nanos: header.keyframe_stamp_nanos,
                world_from_sensor: pose_of(&header.keyframe_world_from_sensor),
                cloud: Cloud::new(points.to_vec()),
            }),
            degenerate: header.flags & FRONT_END_DEGENERATE != 0,
        }),
        None => return Err(failed(format!("unknown front-end status code {}", header.status))),
    };
    Ok(Some(FrontEndOutput {
        sequence: header.sequence,
        stamp_nanos: header.stamp_nanos,
        points: header.points as usize,
        ground_truth: (header.has_ground_truth != 0).then(|| pose_of(&header.ground_truth)),
        source_ms: header.source_ms,
        odometry_ms: header.odometry_ms,
        odometry,
    }))
}

/// Fills a header from one front-end result; returns it with the keyframe points to publish.
fn encode(
    robot: RobotId,
    output_index: u64,
    result: &Result<Option<FrontEndOutput>, FrontEndError>,
) -> (FrontEndHeader, &[skid_core::Point]) {
    let mut header = FrontEndHeader {
        robot_id: robot.0,
        output_index,
        ..FrontEndHeader::default()
    };
    let mut points: &[skid_core::Point] = &[];
    match result {
        Ok(None) => header.status = FrontEndStatus::Ended as u32,
        Err(error) => {
            header.status = FrontEndStatus::Failed as u32;
            let prefix = if error.slot == Slot::Source {
                "source"
            } else {
                "odometry"
            };
            header.set_message(&format!("{prefix}: {}", error.source));
        }
        Ok(Some(output)) => {
            header.stamp_nanos = output.stamp_nanos;
            header.sequence = output.sequence;
            header.points = output.points as u32;
            header.source_ms = output.source_ms;
            header.odometry_ms = output.odometry_ms;
            if let Some(truth) = output.ground_truth {
                header.has_ground_truth = 1;
                header.ground_truth = pose_to_wire(&truth);
            }
            match &output.odometry {
                None => header.status = FrontEndStatus::NoOdometry as u32,
                Some(OdometryOutcome::Skipped { reason }) => {
                    header.status = FrontEndStatus::Skipped as u32;
                    header.set_message(reason);
                }
                Some(OdometryOutcome::Registered {
                    world_from_sensor,
                    keyframe,
                    degenerate,
                }) => {
                    header.status = FrontEndStatus::Registered as u32;
                    if *degenerate {
                        header.flags |= FRONT_END_DEGENERATE;
                    }
                    header.world_from_sensor = pose_to_wire(world_from_sensor);
                    if let Some(keyframe) = keyframe {
                        header.keyframe_index = keyframe.id.index;
                        header.keyframe_stamp_nanos = keyframe.stamp_nanos;
                        header.keyframe_world_from_sensor = pose_to_wire(&keyframe.world_from_sensor);
                        points = &keyframe.cloud.points;
                    }
                }
            }
        }
    }
    (header, points)
}

/// The body of `skid stage front-end`: builds robot `robot`'s source and odometry from the host's
/// effective configuration, replays `skip` outputs silently, then publishes every output until the
/// source ends (or `run.max_scans`), and waits for the host to let go.
pub fn run_front_end_stage(
    config: &ResolvedConfig,
    registry: &Registry,
    robot: RobotId,
    namespace: &str,
    skip: u64,
) -> Result<(), RuntimeError> {
    let context = plugin_context(config, robot);
    let source = build(&registry.source, config, &context)?
        .ok_or_else(|| stage_error(robot, "a source is required"))?;
    let context = context.after_source(source.as_ref());
    let mut front_end = FrontEnd {
        source,
        odometry: build(&registry.odometry, config, &context)?,
    };
    let node =
        ProcessNode::new(&format!("front-end-{}", robot.0), namespace).map_err(|e| stage_error(robot, e))?;
    let publisher: TopicPublisher<ipc::Service, FrontEndScans> =
        node.publisher().map_err(|e| stage_error(robot, e))?;
    if !publisher
        .wait_for_subscribers(1, CONNECT_TIMEOUT)
        .map_err(|e| stage_error(robot, e))?
    {
        return Err(stage_error(robot, "the host did not subscribe"));
    }
    let crash_after = crash_after(robot);
    let max_scans = config.run.max_scans;
    let mut index = 0u64;
    loop {
        let result = if max_scans > 0 && index >= max_scans {
            Ok(None)
        } else {
            front_end.next_output()
        };
        let last = !matches!(result, Ok(Some(_)));
        if index >= skip || last {
            let (header, points) = encode(robot, index.max(skip), &result);
            publisher
                .send_slice(header, points)
                .map_err(|e| stage_error(robot, e))?;
        }
        if crash_after == Some(index) && skip == 0 {
            tracing::warn!(%robot, index, "fault injection: front-end aborting");
            std::process::abort();
        }
        index += 1;
        if last {
            break;
        }
    }
    // Stay until the host has taken the last sample and let go of the topic.
    let deadline = Instant::now() + Duration::from_secs(30);
    while publisher.subscriber_count() > 0 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(())
}

/// For a front-end process: exits this process as soon as its standard input closes, which happens
/// when the host that started it (and holds the pipe's other end) exits or is killed — so no
/// front-end outlives its run.
pub fn exit_when_host_exits() {
    let spawned = std::thread::Builder::new().name("host-watch".into()).spawn(|| {
        use std::io::Read;
        let mut stdin = std::io::stdin();
        let mut buffer = [0u8; 64];
        // The host never writes; any read that ends (EOF or error) means it is gone.
        while matches!(stdin.read(&mut buffer), Ok(n) if n > 0) {}
        tracing::debug!("the host closed the pipe; the front-end process exits");
        std::process::exit(0);
    });
    if let Err(error) = spawned {
        tracing::warn!(%error, "could not watch the host; this front-end may outlive an interrupted run");
    }
}

fn crash_after(robot: RobotId) -> Option<u64> {
    let value = std::env::var(CRASH_AFTER_VAR).ok()?;
    let (who, after) = value.split_once(':')?;
    (who.parse::<u32>().ok()? == robot.0).then(|| after.parse().ok())?
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A registered output as a front-end process publishes it and the host reads it back.
    fn round_trip(degenerate: bool) -> FrontEndOutput {
        let output = FrontEndOutput {
            sequence: 7,
            stamp_nanos: 123,
            points: 1000,
            ground_truth: None,
            source_ms: 1.0,
            odometry_ms: 2.0,
            odometry: Some(OdometryOutcome::Registered {
                world_from_sensor: Pose::identity(),
                keyframe: None,
                degenerate,
            }),
        };
        let published = Ok(Some(output));
        let (header, points) = encode(RobotId(2), 7, &published);
        decode(&header, points).unwrap().unwrap()
    }

    #[test]
    fn the_degenerate_flag_crosses_the_process_boundary() {
        for degenerate in [false, true] {
            let output = round_trip(degenerate);
            assert!(
                matches!(output.odometry, Some(OdometryOutcome::Registered { degenerate: d, .. }) if d == degenerate),
                "{output:?}"
            );
            assert_eq!((output.sequence, output.points), (7, 1000));
        }
    }
}
