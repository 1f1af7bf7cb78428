//! The front-end stage of a robot (source → odometry → keyframes) and the feeds that carry its output
//! to the rest of the host: inline (lockstep), from a thread (`threads`), or from a separate process over
//! iceoryx2 (`processes`, in [`crate::process`]).
//!
//! Every feed yields the same [`FrontEndOutput`]s in the same order, and the host consumes them in the
//! same order, so the three executors give the same result; `threads` and `processes` only let each
//! robot's front-end (the heavy ray casting and ICP) run ahead on its own core.

use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::time::Instant;

use skid_core::slots::{Odometry, Source};
use skid_core::{Keyframe, PluginError, Pose, RobotId, Slot};

/// What the odometry made of one scan.
#[derive(Clone, Debug)]
pub enum OdometryOutcome {
    /// The scan was registered; `keyframe` is set when the keyframe policy fired.
    Registered {
        world_from_sensor: Pose,
        keyframe: Option<Keyframe>,
        /// The odometry found the scan degenerate (see `OdometryUpdate::degenerate`).
        degenerate: bool,
    },
    /// The odometry refused the scan (too few points, stamp going backwards, …); the run goes on.
    Skipped { reason: String },
}

/// One scan through the front-end.
#[derive(Clone, Debug)]
pub struct FrontEndOutput {
    pub sequence: u32,
    pub stamp_nanos: u64,
    pub points: usize,
    pub ground_truth: Option<Pose>,
    pub source_ms: f64,
    pub odometry_ms: f64,
    /// `None` when the robot runs without an odometry plugin.
    pub odometry: Option<OdometryOutcome>,
}

/// A front-end failure, with the slot whose plugin failed.
#[derive(Debug)]
pub struct FrontEndError {
    pub slot: Slot,
    pub source: PluginError,
}

/// The source and odometry of one robot.
pub struct FrontEnd {
    pub source: Box<dyn Source>,
    pub odometry: Option<Box<dyn Odometry>>,
}

impl FrontEnd {
    /// Reads and registers the next scan; `None` once the source has ended.
    pub fn next_output(&mut self) -> Result<Option<FrontEndOutput>, FrontEndError> {
        let started = Instant::now();
        let scan = match self.source.next_scan() {
            Ok(Some(scan)) => scan,
            Ok(None) => return Ok(None),
            Err(source) => {
                return Err(FrontEndError {
                    slot: Slot::Source,
                    source,
                });
            }
        };
        let source_ms = started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        let odometry = match self.odometry.as_mut().map(|odometry| odometry.register(&scan)) {
            None => None,
            Some(Ok(update)) => Some(OdometryOutcome::Registered {
                world_from_sensor: update.world_from_sensor,
                keyframe: update.keyframe,
                degenerate: update.degenerate,
            }),
            Some(Err(PluginError::InvalidInput(reason))) => Some(OdometryOutcome::Skipped { reason }),
            Some(Err(source)) => {
                return Err(FrontEndError {
                    slot: Slot::Odometry,
                    source,
                });
            }
        };
        Ok(Some(FrontEndOutput {
            sequence: scan.sequence,
            stamp_nanos: scan.stamp_nanos,
            points: scan.points.len(),
            ground_truth: scan.ground_truth_world_from_sensor,
            source_ms,
            odometry_ms: started.elapsed().as_secs_f64() * 1e3,
            odometry,
        }))
    }
}

/// Where a host gets its front-end output from when the front-end does not run inline. Not `Send`:
/// iceoryx2 ports belong to the thread that made them, so a feed stays with its host.
pub trait FrontEndFeed {
    /// The next output, `None` when the front-end has ended.
    fn next(&mut self) -> Result<Option<FrontEndOutput>, FrontEndError>;
}

/// Scans a front-end thread may run ahead of the host.
const THREAD_QUEUE: usize = 8;

/// A front-end running on its own thread, handing its outputs over a bounded channel.
pub struct ThreadFeed {
    receiver: Receiver<Result<Option<FrontEndOutput>, FrontEndError>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl ThreadFeed {
    /// Starts `front_end` on a thread named after the robot; it stops after `max_scans` scans (0: when
    /// the source ends).
    pub fn spawn(robot: RobotId, mut front_end: FrontEnd, max_scans: usize) -> std::io::Result<Self> {
        let (sender, receiver): (SyncSender<_>, _) = sync_channel(THREAD_QUEUE);
        let thread = std::thread::Builder::new()
            .name(format!("{robot}-front-end"))
            .spawn(move || {
                let mut read = 0;
                loop {
                    let output = if max_scans > 0 && read >= max_scans {
                        Ok(None)
                    } else {
                        front_end.next_output()
                    };
                    read += 1;
                    let last = !matches!(output, Ok(Some(_)));
                    // The host has gone (run ended or failed): stop quietly.
                    if sender.send(output).is_err() || last {
                        break;
                    }
                }
            })?;
        Ok(Self {
            receiver,
            thread: Some(thread),
        })
    }
}

impl FrontEndFeed for ThreadFeed {
    fn next(&mut self) -> Result<Option<FrontEndOutput>, FrontEndError> {
        match self.receiver.recv() {
            Ok(output) => output,
            // The thread ended after its last output (or panicked inside a plugin).
            Err(_) => match self.thread.take().map(std::thread::JoinHandle::join) {
                Some(Err(_)) => Err(FrontEndError {
                    slot: Slot::Odometry,
                    source: PluginError::Panicked {
                        plugin: "front-end thread".into(),
                        message: "the source or odometry panicked".into(),
                    },
                }),
                _ => Ok(None),
            },
        }
    }
}

/// A source that has nothing: stands in for the real one once a feed owns it.
pub struct DetachedSource;

impl Source for DetachedSource {
    fn next_scan(&mut self) -> skid_core::PluginResult<Option<skid_core::Scan>> {
        Ok(None)
    }
}
