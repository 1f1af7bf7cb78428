//! How SKiD's cost grows with the fleet and with the mission (issue #18): the default pipeline on the
//! simulator with N robots (shorter routes as N grows, so every fleet reads about the same number of
//! scans), and long missions whose back-end and verifier time per keyframe is read at chosen minutes
//! of robot time. Every run is the real runtime (`skid_runtime::Fleet`, the `threads` executor) built
//! from `configs/default.toml` and the profile's overrides; a [`Timeline`] observer samples each host's
//! stage clocks after every scan.

use std::path::Path;
use std::sync::{Arc, Mutex, PoisonError};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use skid_core::{Registry, RobotId};
use skid_runtime::{HostObserver, RobotHost, RunMetrics, RunSummary};

/// One fleet size of the sweep.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FleetCase {
    pub robots: u32,
    /// Scans per robot (10 Hz).
    pub max_scans: u64,
    pub route_length_m: f64,
    /// More `--set` overrides for this fleet only, after the profile's own.
    #[serde(default)]
    pub sets: Vec<String>,
}

/// A long mission.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LongMission {
    /// Names the mission in the report and its plot's file.
    pub name: String,
    pub robots: u32,
    /// Robot time, minutes (10 Hz scans).
    pub minutes: u32,
    /// Minutes at which the per-keyframe cost is read (each over the minute before it).
    pub checkpoints_min: Vec<u32>,
    /// `--set`-style overrides for this run, after the profile's common ones.
    pub sets: Vec<String>,
}

impl Default for LongMission {
    fn default() -> Self {
        Self {
            name: "long".to_owned(),
            robots: 3,
            minutes: 20,
            checkpoints_min: vec![1, 5, 10, 20],
            sets: Vec::new(),
        }
    }
}

/// Parameters of the profile.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScaleSettings {
    pub fleets: Vec<FleetCase>,
    /// `--set`-style overrides applied to every run.
    pub sets: Vec<String>,
    /// The long missions, run after the fleets (`[[long]]` in the profile).
    pub long: Vec<LongMission>,
}

impl Default for ScaleSettings {
    fn default() -> Self {
        let case = |robots, max_scans, route_length_m| FleetCase {
            robots,
            max_scans,
            route_length_m,
            sets: Vec::new(),
        };
        Self {
            fleets: vec![
                case(2, 1200, 180.0),
                case(4, 600, 90.0),
                case(8, 400, 60.0),
                case(16, 300, 45.0),
            ],
            sets: Vec::new(),
            long: vec![LongMission::default()],
        }
    }
}

/// One host's stage clocks after one of its scans.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Sample {
    pub robot: u32,
    /// Robot time since its first scan, seconds.
    pub time_s: f64,
    pub keyframes: usize,
    pub backend_ms: f64,
    pub verifier_ms: f64,
    /// Loop candidates the verifier has judged (every loop this robot registered).
    pub verified: usize,
    /// Loops the back-end's graph has gained or lost: the loops in it, plus twice those removed.
    pub loop_changes: usize,
}

/// Records a [`Sample`] after every scan of the robot it watches.
pub struct Timeline {
    samples: Arc<Mutex<Vec<Sample>>>,
    first_stamp_nanos: Option<u64>,
}

impl HostObserver for Timeline {
    fn scan(&mut self, host: &RobotHost) {
        let Some(stamp) = host.scans().last().map(|scan| scan.stamp_nanos) else {
            return;
        };
        let first = *self.first_stamp_nanos.get_or_insert(stamp);
        let stage = |name: &str| host.stage_ms().get(name).copied().unwrap_or(0.0);
        let sample = Sample {
            robot: host.robot().0,
            time_s: stamp.saturating_sub(first) as f64 * 1e-9,
            keyframes: host.keyframes().len(),
            backend_ms: stage("backend"),
            verifier_ms: stage("verifier"),
            verified: host.standing_loops().count(),
            loop_changes: host.accepted_loops().len() + 2 * host.loop_stats().retracted,
        };
        self.samples
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(sample);
    }
}

/// A finished run: its summary, metrics, every host's samples, and what the process used.
pub struct ScaleRun {
    pub summary: RunSummary,
    pub metrics: RunMetrics,
    pub samples: Vec<Sample>,
    pub cpu_s: f64,
    pub peak_rss_mb: f64,
}

/// Runs the default pipeline with `sets` (after the profile's common ones) under the name `name`.
pub fn run_fleet(name: &str, sets: Vec<String>, registry: &Registry, out: &Path) -> Result<ScaleRun> {
    let mut all_sets = vec![
        format!("run.name={name}"),
        format!("run.output_dir=\"{}\"", out.join("runs").display()),
        "deploy.mode=threads".to_owned(),
    ];
    all_sets.extend(sets);
    let mut fleet = crate::slam::build_fleet(name, None, all_sets, registry)?;
    let robots = fleet.config.run.robots;
    let samples = Arc::new(Mutex::new(Vec::new()));
    for robot in 0..robots {
        let timeline = Timeline {
            samples: Arc::clone(&samples),
            first_stamp_nanos: None,
        };
        fleet.observers.attach(RobotId(robot), Box::new(timeline));
    }
    crate::usage::reset_peak_rss();
    let cpu_before = crate::usage::cpu_seconds();
    let mut last = std::time::Instant::now();
    let summary = fleet
        .run_lockstep(|scans| {
            if last.elapsed().as_secs_f64() > 30.0 {
                eprintln!("{name}: {scans} robot-scans");
                last = std::time::Instant::now();
            }
        })
        .with_context(|| format!("running {name}"))?;
    let cpu_s = crate::usage::cpu_seconds() - cpu_before;
    let peak_rss_mb = crate::usage::peak_rss_mb();
    let (_, metrics) = skid_runtime::write_outputs(&fleet, &summary)?;
    let samples = std::mem::take(&mut *samples.lock().unwrap_or_else(PoisonError::into_inner));
    Ok(ScaleRun {
        summary,
        metrics,
        samples,
        cpu_s,
        peak_rss_mb,
    })
}

/// The work and the back-end and verifier time of every robot over a window of robot time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Window {
    pub keyframes: usize,
    pub backend_ms: f64,
    pub verifier_ms: f64,
    pub verified: usize,
    pub loop_changes: usize,
}

impl Window {
    pub fn backend_ms_per_keyframe(&self) -> f64 {
        self.backend_ms / self.keyframes as f64
    }

    pub fn verifier_ms_per_keyframe(&self) -> f64 {
        self.verifier_ms / self.keyframes as f64
    }

    /// Verifier milliseconds per candidate it judged; `None` when it judged none.
    pub fn verifier_ms_per_candidate(&self) -> Option<f64> {
        (self.verified > 0).then(|| self.verifier_ms / self.verified as f64)
    }

    /// Back-end milliseconds per loop its graph gained or lost; `None` when none did.
    pub fn backend_ms_per_loop_change(&self) -> Option<f64> {
        (self.loop_changes > 0).then(|| self.backend_ms / self.loop_changes as f64)
    }
}

/// The window of robot time `[from_s, to_s)`, summed over every robot (each robot's clocks and counts
/// between its last sample before `from_s` and its last before `to_s`); `None` when no keyframe was made
/// then.
pub fn window(samples: &[Sample], from_s: f64, to_s: f64) -> Option<Window> {
    let robots: std::collections::BTreeSet<u32> = samples.iter().map(|s| s.robot).collect();
    let mut total = Window::default();
    for robot in robots {
        let of_robot = || samples.iter().filter(move |s| s.robot == robot);
        let before = |limit: f64| of_robot().rfind(|s| s.time_s < limit).copied();
        let start = before(from_s).unwrap_or(Sample {
            robot,
            time_s: 0.0,
            keyframes: 0,
            backend_ms: 0.0,
            verifier_ms: 0.0,
            verified: 0,
            loop_changes: 0,
        });
        let Some(end) = before(to_s) else { continue };
        total.keyframes += end.keyframes.saturating_sub(start.keyframes);
        total.backend_ms += end.backend_ms - start.backend_ms;
        total.verifier_ms += end.verifier_ms - start.verifier_ms;
        total.verified += end.verified.saturating_sub(start.verified);
        total.loop_changes += end.loop_changes.saturating_sub(start.loop_changes);
    }
    (total.keyframes > 0).then_some(total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cost_is_read_per_new_keyframe_over_the_window() {
        let sample = |robot, time_s, keyframes, backend_ms| Sample {
            robot,
            time_s,
            keyframes,
            backend_ms,
            verifier_ms: 1.0,
            verified: keyframes / 2,
            loop_changes: keyframes,
        };
        let samples = [
            sample(0, 0.0, 1, 0.0),
            sample(0, 50.0, 5, 10.0),
            sample(0, 110.0, 9, 50.0),
            sample(1, 0.0, 1, 0.0),
            sample(1, 110.0, 3, 20.0),
        ];
        // Robot 0: 4 keyframes and 40 ms from its 50 s sample to its 110 s one; robot 1: 2 and 20 ms
        // from its 0 s sample.
        let window = window(&samples, 60.0, 120.0).unwrap();
        assert_eq!(
            (window.keyframes, window.loop_changes, window.verified),
            (6, 6, 3)
        );
        assert!((window.backend_ms_per_keyframe() - 10.0).abs() < 1e-12);
        assert!(window.verifier_ms_per_keyframe().abs() < 1e-12);
        assert_eq!(window.backend_ms_per_loop_change(), Some(10.0));
        assert_eq!(window.verifier_ms_per_candidate(), Some(0.0));
        assert_eq!(super::window(&samples, 200.0, 260.0), None);
    }
}
