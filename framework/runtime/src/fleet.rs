//! The fleet: one [`RobotHost`] per robot, each owning its plugin instances, stepped in lockstep.

use std::time::Instant;

use serde::Serialize;
use skid_config::ResolvedConfig;
use skid_core::slots::{
    Backend, CoarseRegistration, Descriptor, FineRegistration, Odometry, Source, Transport, Verifier,
};
use skid_core::{PluginContext, PluginError, Pose, Registry, RobotId, Slot};

use crate::RuntimeError;

/// One robot's plugins and what it has produced so far.
pub struct RobotHost {
    pub robot: RobotId,
    pub source: Box<dyn Source>,
    pub odometry: Option<Box<dyn Odometry>>,
    pub descriptor: Option<Box<dyn Descriptor>>,
    pub coarse: Option<Box<dyn CoarseRegistration>>,
    pub fine: Option<Box<dyn FineRegistration>>,
    pub verifier: Option<Box<dyn Verifier>>,
    pub backend: Option<Box<dyn Backend>>,
    pub transport: Option<Box<dyn Transport>>,
    /// Odometry estimate per scan: stamp in nanoseconds and `world_from_sensor`.
    pub trajectory: Vec<(u64, Pose)>,
    /// Ground truth per scan, when the source provides it.
    pub ground_truth: Vec<(u64, Pose)>,
    pub keyframes: usize,
    pub scans: usize,
    pub points: usize,
    odometry_ms: Vec<f64>,
    finished: bool,
}

/// What one robot did, for the run's summary JSON.
#[derive(Clone, Debug, Serialize)]
pub struct RobotSummary {
    pub robot: u32,
    pub scans: usize,
    pub keyframes: usize,
    pub mean_points_per_scan: f64,
    pub odometry_ms_median: f64,
    pub odometry_ms_p90: f64,
    pub path_length_m: f64,
    /// RMSE of position after aligning the first poses, when ground truth exists.
    pub ate_first_pose_aligned_m: Option<f64>,
}

/// The summary of a whole run.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub name: String,
    pub robots: Vec<RobotSummary>,
    pub wall_s: f64,
    pub slots: Vec<(String, String)>,
}

/// Every robot of the run.
pub struct Fleet {
    pub config: ResolvedConfig,
    pub robots: Vec<RobotHost>,
}

fn build<T: ?Sized + 'static>(
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

impl Fleet {
    /// Builds every robot's plugins. `threads` is the whole host's budget, shared among robots.
    pub fn build(config: ResolvedConfig, registry: &Registry) -> Result<Self, RuntimeError> {
        let robots_total = config.run.robots;
        let threads = if config.run.threads == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            config.run.threads
        };
        let mut robots = Vec::new();
        for index in 0..robots_total {
            let robot = RobotId(index);
            let context = PluginContext {
                robot,
                fleet_size: robots_total,
                threads: threads.max(1),
                seed: config.run.seed.wrapping_add(u64::from(index)),
                output_dir: Some(config.run.output_dir.join(&config.run.name)),
            };
            let source = build(&registry.source, &config, &context)?.ok_or_else(|| RuntimeError::Plugin {
                robot,
                slot: Slot::Source,
                plugin: "none".into(),
                source: PluginError::InvalidInput("a source is required".into()),
            })?;
            robots.push(RobotHost {
                robot,
                source,
                odometry: build(&registry.odometry, &config, &context)?,
                descriptor: build(&registry.descriptor, &config, &context)?,
                coarse: build(&registry.coarse, &config, &context)?,
                fine: build(&registry.fine, &config, &context)?,
                verifier: build(&registry.verifier, &config, &context)?,
                backend: build(&registry.backend, &config, &context)?,
                transport: build(&registry.transport, &config, &context)?,
                trajectory: Vec::new(),
                ground_truth: Vec::new(),
                keyframes: 0,
                scans: 0,
                points: 0,
                odometry_ms: Vec::new(),
                finished: false,
            });
        }
        Ok(Self { config, robots })
    }

    /// Runs every robot in lockstep until all sources end (or `max_scans` per robot), calling
    /// `progress(total_scans_done)` after each round.
    pub fn run_lockstep(&mut self, mut progress: impl FnMut(usize)) -> Result<RunSummary, RuntimeError> {
        let started = Instant::now();
        let max_scans = self.config.run.max_scans as usize;
        let mut done = 0;
        while self.robots.iter().any(|robot| !robot.finished) {
            for robot in self.robots.iter_mut().filter(|robot| !robot.finished) {
                if max_scans > 0 && robot.scans >= max_scans {
                    robot.finished = true;
                    continue;
                }
                robot.finished = !robot.step(&self.config)?;
                done += usize::from(!robot.finished);
            }
            progress(done);
        }
        Ok(self.summary(started.elapsed().as_secs_f64()))
    }

    fn summary(&self, wall_s: f64) -> RunSummary {
        RunSummary {
            name: self.config.run.name.clone(),
            robots: self.robots.iter().map(RobotHost::summary).collect(),
            wall_s,
            slots: Slot::ALL
                .iter()
                .map(|&slot| (slot.key().to_owned(), self.config.slot(slot).plugin.clone()))
                .collect(),
        }
    }
}

impl RobotHost {
    /// Reads and processes one scan; false when the source has ended.
    fn step(&mut self, config: &ResolvedConfig) -> Result<bool, RuntimeError> {
        let plugin_error = |slot: Slot, source: PluginError| RuntimeError::Plugin {
            robot: self.robot,
            slot,
            plugin: config.slot(slot).plugin.clone(),
            source,
        };
        let scan = match self.source.next_scan() {
            Ok(Some(scan)) => scan,
            Ok(None) => return Ok(false),
            Err(error) => return Err(plugin_error(Slot::Source, error)),
        };
        self.scans += 1;
        self.points += scan.points.len();
        if let Some(truth) = scan.ground_truth_world_from_sensor {
            self.ground_truth.push((scan.stamp_nanos, truth));
        }
        if let Some(odometry) = self.odometry.as_mut() {
            let started = Instant::now();
            let update = odometry
                .register(&scan)
                .map_err(|error| plugin_error(Slot::Odometry, error))?;
            self.odometry_ms.push(started.elapsed().as_secs_f64() * 1e3);
            self.trajectory
                .push((update.stamp_nanos, update.world_from_sensor));
            self.keyframes += usize::from(update.keyframe.is_some());
        }
        Ok(true)
    }

    fn summary(&self) -> RobotSummary {
        let mut sorted = self.odometry_ms.clone();
        sorted.sort_by(f64::total_cmp);
        let quantile = |q: f64| {
            if sorted.is_empty() {
                0.0
            } else {
                sorted[((sorted.len() - 1) as f64 * q).round() as usize]
            }
        };
        let path_length_m = self
            .trajectory
            .windows(2)
            .map(|pair| (pair[1].1.translation.vector - pair[0].1.translation.vector).norm())
            .sum();
        RobotSummary {
            robot: self.robot.0,
            scans: self.scans,
            keyframes: self.keyframes,
            mean_points_per_scan: if self.scans == 0 {
                0.0
            } else {
                self.points as f64 / self.scans as f64
            },
            odometry_ms_median: quantile(0.5),
            odometry_ms_p90: quantile(0.9),
            path_length_m,
            ate_first_pose_aligned_m: self.ate_first_pose_aligned(),
        }
    }

    fn ate_first_pose_aligned(&self) -> Option<f64> {
        if self.ground_truth.len() != self.trajectory.len() || self.trajectory.is_empty() {
            return None;
        }
        let truth_from_estimate = self.ground_truth[0].1 * self.trajectory[0].1.inverse();
        let sum_sq: f64 = self
            .trajectory
            .iter()
            .zip(&self.ground_truth)
            .map(|((_, estimate), (_, truth))| {
                ((truth_from_estimate * estimate).translation.vector - truth.translation.vector)
                    .norm_squared()
            })
            .sum();
        Some((sum_sq / self.trajectory.len() as f64).sqrt())
    }
}
