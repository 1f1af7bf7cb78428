//! The relocalisation benchmark: a robot placing itself in a prior map.
//!
//! One run maps a world (the default mission, its session saved as every run saves it). Then each trial
//! is a one-robot run in the same world that starts at a junction of the road graph and wanders from it
//! (`source.sim.mission = "wander"`), with the prior given (`[prior] path`), another LiDAR than the
//! map's and the world in another season (rocks moved or gone). Trials start at junctions the mapping
//! robots passed ("on the mapped routes" when the trial's first 20 m stay within 5 m of the mapped
//! ground-truth path, "leaves the routes" otherwise) and at junctions far from anything mapped ("off the
//! map" when the whole trial stays 30 m or more from it). Per trial it reports the first fix (whether,
//! after how many metres and seconds), a **false fix** (the placement more than 2 m or 5° from the
//! truth, the definition every SKiD benchmark uses), the error of the placement along the keyframes
//! since the fix, and the loop-closure and back-end milliseconds per scan against the same trial
//! without the prior (full SLAM alone). Trials are the real runtime in lockstep, built from
//! `configs/default.toml` and the profile's overrides; the judgement is the runtime's own
//! `summary.json` `localisation`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use skid_core::Registry;
use skid_sim::{World, WorldKind};

use crate::aliasing::{FALSE_MERGE_DEG, FALSE_MERGE_M};
use crate::slam::build_fleet;

/// Parameters of the benchmark.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RelocaliseSettings {
    pub world: String,
    pub seed: u64,
    /// `--set`-style overrides of the mapping run.
    pub map_sets: Vec<String>,
    /// Trials starting at junctions the map passed through, and at junctions far from it.
    pub trials_on_map: usize,
    pub trials_off_map: usize,
    /// Junctions at least this far from every mapped position start the off-map trials, metres.
    pub off_map_start_m: f64,
    /// Scans per trial (10 Hz).
    pub trial_max_scans: u64,
    /// `--set`-style overrides of every trial (sensor, season, speed, route length).
    pub trial_sets: Vec<String>,
    /// Trials also run without the prior, for the cost of full SLAM alone.
    pub cost_baseline_trials: usize,
    /// Trials of a whole fleet of `fleet_robots`, starting together at a junction the map passed, each
    /// robot on its own road out of it: some drive mapped roads, others must be placed through them.
    pub fleet_trials: usize,
    pub fleet_robots: u32,
    /// Drive the mapping mission again (with the trials' sensor and season) with the prior and without
    /// it, for what localising costs beside full SLAM on the same routes.
    pub mission_comparison: bool,
    /// Sessions of the mapping mission on other days (the trials' sensor and season, route seeds 1, 2,
    /// …: other noise), each merged with the map.
    pub merge_other_days: usize,
    /// Sessions of one robot wandering (`trial_max_scans`) from junctions far from the map, each merged
    /// with the map: none may be placed.
    pub merge_far_sessions: usize,
}

impl Default for RelocaliseSettings {
    fn default() -> Self {
        Self {
            world: "planetary".to_owned(),
            seed: 7,
            map_sets: Vec::new(),
            trials_on_map: 40,
            trials_off_map: 15,
            off_map_start_m: 80.0,
            trial_max_scans: 400,
            trial_sets: vec![
                "source.sim.sensor=os1-32".to_owned(),
                "source.sim.season=1".to_owned(),
                "source.sim.route_length_m=70.0".to_owned(),
            ],
            cost_baseline_trials: 8,
            fleet_trials: 4,
            fleet_robots: 3,
            mission_comparison: true,
            merge_other_days: 3,
            merge_far_sessions: 3,
        }
    }
}

/// One trial.
#[derive(Clone, Debug, Serialize)]
pub struct TrialRow {
    pub trial: usize,
    pub start_junction: usize,
    /// `on the mapped routes`, `leaves the routes`, `off the map` or `reaches the map`.
    pub kind: &'static str,
    pub localised: bool,
    pub first_fix_distance_m: Option<f64>,
    pub first_fix_s: Option<f64>,
    pub error_m: Option<f64>,
    pub error_deg: Option<f64>,
    pub false_fix: bool,
    /// Loop-closure and back-end milliseconds per scan (everything but the source and the odometry).
    pub loop_ms_per_scan: f64,
    /// The same trial without the prior, when it was run.
    pub slam_loop_ms_per_scan: Option<f64>,
    pub run_wall_s: f64,
}

/// The mapping mission driven again, with the prior (`localise`) or without it (`full SLAM`).
#[derive(Clone, Debug, Serialize)]
pub struct MissionRow {
    pub mode: &'static str,
    /// Loop-closure and back-end milliseconds per robot-scan (everything but the source and odometry).
    pub loop_ms_per_scan: f64,
    pub robots: usize,
    pub localised: usize,
    pub false_fixes: usize,
    /// The largest error after a fix, metres and degrees.
    pub worst_error: Option<(f64, f64)>,
    pub wall_s: f64,
}

/// One robot of a fleet trial.
#[derive(Clone, Debug, Serialize)]
pub struct FleetRow {
    pub trial: usize,
    pub robot: usize,
    pub start_junction: usize,
    pub kind: &'static str,
    pub localised: bool,
    /// The fleet robot whose reported frames placed it, when it holds no loop with the prior.
    pub via_robot: Option<u32>,
    pub error_m: Option<f64>,
    pub error_deg: Option<f64>,
    pub false_fix: bool,
}

/// Ground-truth positions (x, y) of the map's keyframes.
pub(crate) fn mapped_positions(session_dir: &Path) -> Result<Vec<[f64; 2]>> {
    let session = skid_session::read_session(session_dir)?;
    Ok(session
        .robots
        .iter()
        .filter(|robot| robot.map_from_robot.is_some())
        .flat_map(|robot| &robot.keyframes)
        .filter_map(|k| k.ground_truth.map(|t| [t.translation.x, t.translation.y]))
        .collect())
}

fn distance_to(mapped: &[[f64; 2]], x: f64, y: f64) -> f64 {
    mapped
        .iter()
        .map(|p| (p[0] - x).hypot(p[1] - y))
        .fold(f64::INFINITY, f64::min)
}

/// Junctions the map passed within 5 m of, and junctions farther than `off_m` from all of it.
pub(crate) fn start_junctions(world: &World, mapped: &[[f64; 2]], off_m: f64) -> (Vec<usize>, Vec<usize>) {
    let nodes = &world.graph().nodes;
    let on: Vec<usize> = (0..nodes.len())
        .filter(|&j| distance_to(mapped, nodes[j][0], nodes[j][1]) < 5.0)
        .collect();
    let off: Vec<usize> = (0..nodes.len())
        .filter(|&j| distance_to(mapped, nodes[j][0], nodes[j][1]) > off_m)
        .collect();
    (on, off)
}

/// Milliseconds per robot-scan of everything but the source and the odometry, over every robot.
fn loop_ms_per_scan(summary: &skid_runtime::RunSummary) -> f64 {
    let (ms, scans) = summary.robots.iter().fold((0.0, 0usize), |(ms, scans), robot| {
        let loop_ms: f64 = robot
            .stage_ms
            .iter()
            .filter(|(stage, _)| !matches!(stage.as_str(), "source" | "odometry"))
            .map(|(_, ms)| ms)
            .sum();
        (ms + loop_ms, scans + robot.scans)
    });
    ms / scans.max(1) as f64
}

/// The settings of the mapping mission driven again: the map's, then the trials' sensor and season (their
/// route length left out: the mission's own routes are driven), in the same world.
pub(crate) fn mission_again_sets(settings: &RelocaliseSettings) -> Vec<String> {
    let mut sets = settings.map_sets.clone();
    sets.extend(
        settings
            .trial_sets
            .iter()
            .filter(|set| !set.starts_with("source.sim.route_length_m"))
            .cloned(),
    );
    sets.extend([
        format!("run.seed={}", settings.seed),
        format!("source.sim.seed={}", settings.seed),
        format!("source.sim.world={}", settings.world),
    ]);
    sets
}

/// Drives the mapping mission again, with the trials' sensor and season, with the prior and without.
pub fn run_mission_comparison(
    settings: &RelocaliseSettings,
    session_dir: &Path,
    registry: &Registry,
    out: &Path,
) -> Result<Vec<MissionRow>> {
    let mut rows = Vec::new();
    for (mode, prior) in [("localise", Some(session_dir)), ("full SLAM", None)] {
        let name = format!("mission-{}", mode.replace(' ', "-"));
        let mut sets = mission_again_sets(settings);
        sets.extend([
            format!("run.name={name}"),
            "output.record=false".to_owned(),
            "output.session=false".to_owned(),
            format!("run.output_dir=\"{}\"", out.join("runs").display()),
        ]);
        if let Some(prior) = prior {
            sets.push(format!("prior.path=\"{}\"", prior.display()));
        }
        let mut fleet = build_fleet(&name, None, sets, registry)?;
        let summary = fleet
            .run_lockstep(|_| {})
            .with_context(|| format!("running {name}"))?;
        let fixes: Vec<(f64, f64)> = summary
            .robots
            .iter()
            .filter_map(|r| r.localisation.as_ref())
            .filter_map(|l| l.error_m.zip(l.error_deg))
            .collect();
        rows.push(MissionRow {
            mode,
            loop_ms_per_scan: loop_ms_per_scan(&summary),
            robots: summary.robots.len(),
            localised: summary
                .robots
                .iter()
                .filter(|r| r.localisation.as_ref().is_some_and(|l| l.localised))
                .count(),
            false_fixes: fixes
                .iter()
                .filter(|(m, deg)| is_false_fix(Some(*m), Some(*deg)))
                .count(),
            worst_error: fixes.iter().copied().reduce(|a, b| (a.0.max(b.0), a.1.max(b.1))),
            wall_s: summary.wall_s,
        });
    }
    Ok(rows)
}

/// The mission comparison in a sentence.
pub fn mission_markdown(rows: &[MissionRow]) -> String {
    let of = |mode: &str| rows.iter().find(|r| r.mode == mode);
    let (Some(localise), Some(slam)) = (of("localise"), of("full SLAM")) else {
        return String::new();
    };
    format!(
        "The mapping mission driven again with the trials' sensor and season: localising in the map costs \
         {:.1} ms of loop closure and back-end per robot-scan, full SLAM on the same routes {:.1} ms ({:.0} %); \
         {} of {} robots localised, {} false fixes, worst error after a fix {}.\n",
        localise.loop_ms_per_scan,
        slam.loop_ms_per_scan,
        100.0 * localise.loop_ms_per_scan / slam.loop_ms_per_scan.max(1e-9),
        localise.localised,
        localise.robots,
        localise.false_fixes,
        localise
            .worst_error
            .map_or("–".to_owned(), |(m, deg)| format!("{m:.3} m / {deg:.2}°")),
    )
}

/// Maps the world; returns the session folder.
pub fn map_world(settings: &RelocaliseSettings, registry: &Registry, out: &Path) -> Result<PathBuf> {
    let mut sets = settings.map_sets.clone();
    sets.extend([
        "run.name=map".to_owned(),
        format!("run.seed={}", settings.seed),
        format!("source.sim.seed={}", settings.seed),
        format!("source.sim.world={}", settings.world),
        format!("run.output_dir=\"{}\"", out.join("runs").display()),
    ]);
    let mut fleet = build_fleet("map", None, sets, registry)?;
    let summary = fleet.run_lockstep(|_| {}).context("running the mapping run")?;
    let (folder, _) = skid_runtime::write_outputs(&fleet, &summary)?;
    Ok(folder.join("session"))
}

/// One trial run: where its robots start, and whether they have the prior.
struct Trial<'a> {
    name: String,
    junction: usize,
    route_seed: usize,
    robots: u32,
    prior: Option<&'a Path>,
}

fn run_trial(
    settings: &RelocaliseSettings,
    trial: &Trial<'_>,
    registry: &Registry,
    out: &Path,
) -> Result<(skid_runtime::RunSummary, Vec<Vec<[f64; 2]>>)> {
    let Trial {
        name,
        junction,
        route_seed,
        robots,
        prior,
    } = trial;
    let mut sets = settings.trial_sets.clone();
    sets.extend([
        format!("run.name={name}"),
        format!("run.robots={robots}"),
        format!("run.max_scans={}", settings.trial_max_scans),
        format!("run.seed={}", settings.seed),
        format!("source.sim.seed={}", settings.seed),
        format!("source.sim.world={}", settings.world),
        "source.sim.mission=wander".to_owned(),
        format!("source.sim.start_junction={junction}"),
        format!("source.sim.route_seed={route_seed}"),
        "output.record=false".to_owned(),
        "output.session=false".to_owned(),
        format!("run.output_dir=\"{}\"", out.join("runs").display()),
    ]);
    if let Some(prior) = prior {
        sets.push(format!("prior.path=\"{}\"", prior.display()));
    }
    let mut fleet = build_fleet(name, None, sets, registry)?;
    let summary = fleet
        .run_lockstep(|_| {})
        .with_context(|| format!("running {name}"))?;
    let paths = fleet
        .robots
        .iter()
        .map(|robot| {
            robot
                .scans()
                .iter()
                .filter_map(|s| s.ground_truth.map(|t| [t.translation.x, t.translation.y]))
                .collect()
        })
        .collect();
    Ok((summary, paths))
}

/// What a trial's ground-truth path was, against the map.
fn classify(mapped: &[[f64; 2]], path: &[[f64; 2]], started_on_map: bool) -> &'static str {
    let nearest: Vec<f64> = path.iter().map(|p| distance_to(mapped, p[0], p[1])).collect();
    if !started_on_map {
        return if nearest.iter().all(|&d| d >= 30.0) {
            "off the map"
        } else {
            "reaches the map"
        };
    }
    let mut travelled = 0.0;
    for (i, d) in nearest.iter().enumerate() {
        if *d > 5.0 {
            return "leaves the routes";
        }
        if i > 0 {
            travelled += (path[i][0] - path[i - 1][0]).hypot(path[i][1] - path[i - 1][1]);
        }
        if travelled > 20.0 {
            break;
        }
    }
    "on the mapped routes"
}

/// Runs every trial against the map in `session_dir`.
pub fn run_trials(
    settings: &RelocaliseSettings,
    session_dir: &Path,
    registry: &Registry,
    out: &Path,
    mut on_row: impl FnMut(&TrialRow) -> Result<()>,
) -> Result<Vec<TrialRow>> {
    let mapped = mapped_positions(session_dir)?;
    anyhow::ensure!(
        !mapped.is_empty(),
        "the map's session has no ground truth to choose trials by"
    );
    let kind: WorldKind = settings.world.parse()?;
    let world = World::shared(kind, settings.seed);
    let (on, off) = start_junctions(&world, &mapped, settings.off_map_start_m);
    anyhow::ensure!(
        !on.is_empty(),
        "no junction of the world lies on the mapped routes"
    );
    let starts = (0..settings.trials_on_map)
        .map(|i| (on[i % on.len()], true))
        .chain(
            (0..settings.trials_off_map)
                .filter(|_| !off.is_empty())
                .map(|i| (off[(i * 7) % off.len()], false)),
        );
    let mut rows = Vec::new();
    for (trial, (junction, on_map)) in starts.enumerate() {
        let name = format!("trial{trial:03}");
        let run = Trial {
            name: name.clone(),
            junction,
            route_seed: trial,
            robots: 1,
            prior: Some(session_dir),
        };
        let (summary, paths) = run_trial(settings, &run, registry, out)?;
        let path = paths.into_iter().next().unwrap_or_default();
        let localisation = summary.robots.first().and_then(|r| r.localisation.clone());
        let slam_loop_ms_per_scan = if trial < settings.cost_baseline_trials {
            let alone_run = Trial {
                name: format!("{name}-slam"),
                prior: None,
                ..run
            };
            let (alone, _) = run_trial(settings, &alone_run, registry, out)?;
            Some(loop_ms_per_scan(&alone))
        } else {
            None
        };
        let (error_m, error_deg) = localisation
            .as_ref()
            .map_or((None, None), |l| (l.error_m, l.error_deg));
        let row = TrialRow {
            trial,
            start_junction: junction,
            kind: classify(&mapped, &path, on_map),
            localised: localisation.as_ref().is_some_and(|l| l.localised),
            first_fix_distance_m: localisation.as_ref().and_then(|l| l.first_fix_distance_m),
            first_fix_s: localisation.as_ref().and_then(|l| l.first_fix_s),
            error_m,
            error_deg,
            false_fix: is_false_fix(error_m, error_deg),
            loop_ms_per_scan: loop_ms_per_scan(&summary),
            slam_loop_ms_per_scan,
            run_wall_s: summary.wall_s,
        };
        on_row(&row)?;
        rows.push(row);
    }
    Ok(rows)
}

/// Whether a placement's error (a fix's, a merge's) makes it false.
pub(crate) fn is_false_fix(error_m: Option<f64>, error_deg: Option<f64>) -> bool {
    error_m
        .zip(error_deg)
        .is_some_and(|(m, deg)| m > FALSE_MERGE_M || deg > FALSE_MERGE_DEG)
}

/// Runs the fleet trials against the map in `session_dir`: one row per robot.
pub fn run_fleet_trials(
    settings: &RelocaliseSettings,
    session_dir: &Path,
    registry: &Registry,
    out: &Path,
    mut on_row: impl FnMut(&FleetRow) -> Result<()>,
) -> Result<Vec<FleetRow>> {
    let mapped = mapped_positions(session_dir)?;
    let kind: WorldKind = settings.world.parse()?;
    let world = World::shared(kind, settings.seed);
    let (on, _) = start_junctions(&world, &mapped, settings.off_map_start_m);
    let mut rows = Vec::new();
    for trial in 0..settings.fleet_trials {
        let Some(&junction) = on.get((trial * 3) % on.len().max(1)) else {
            break;
        };
        let run = Trial {
            name: format!("fleet{trial:03}"),
            junction,
            route_seed: 1000 + trial,
            robots: settings.fleet_robots,
            prior: Some(session_dir),
        };
        let (summary, paths) = run_trial(settings, &run, registry, out)?;
        for (robot, (summary, path)) in summary.robots.iter().zip(&paths).enumerate() {
            let localisation = summary.localisation.as_ref();
            let (error_m, error_deg) = localisation.map_or((None, None), |l| (l.error_m, l.error_deg));
            let row = FleetRow {
                trial,
                robot,
                start_junction: junction,
                kind: classify(&mapped, path, true),
                localised: localisation.is_some_and(|l| l.localised),
                via_robot: localisation.and_then(|l| l.via_robot),
                error_m,
                error_deg,
                false_fix: is_false_fix(error_m, error_deg),
            };
            on_row(&row)?;
            rows.push(row);
        }
    }
    Ok(rows)
}

/// The fleet trials in a few sentences.
pub fn fleet_markdown(rows: &[FleetRow]) -> String {
    let count = |keep: &dyn Fn(&FleetRow) -> bool| rows.iter().filter(|r| keep(r)).count();
    let worst = rows
        .iter()
        .filter_map(|r| r.error_m.zip(r.error_deg))
        .fold((0.0_f64, 0.0_f64), |(m, d), (em, ed)| (m.max(em), d.max(ed)));
    format!(
        "Fleet trials: {} robots in {} trials, starting together at a mapped junction, each on its own \
         road: {} localised by their own loops with the prior, {} through a fleet peer, {} not localised; \
         {} false fixes; worst error after a fix {:.3} m / {:.2}°. Of the robots whose own first 20 m \
         stayed on the mapped routes, {} of {} were localised.\n",
        rows.len(),
        rows.iter().map(|r| r.trial).max().map_or(0, |t| t + 1),
        count(&|r| r.localised && r.via_robot.is_none()),
        count(&|r| r.localised && r.via_robot.is_some()),
        count(&|r| !r.localised),
        count(&|r| r.false_fix),
        worst.0,
        worst.1,
        count(&|r| r.localised && r.kind == "on the mapped routes"),
        count(&|r| r.kind == "on the mapped routes"),
    )
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}

pub(crate) fn figure(value: Option<f64>, digits: usize) -> String {
    value.map_or("–".to_owned(), |v| format!("{v:.digits$}"))
}

/// The summary table: per kind of trial, fixes, false fixes, distance and time to the first fix, error
/// after it; and the cost beside full SLAM.
pub fn relocalise_markdown(settings: &RelocaliseSettings, rows: &[TrialRow]) -> String {
    let header: Vec<String> = [
        "trials",
        "count",
        "fixed",
        "fixed within 20 m ↑",
        "false fixes ↓",
        "median distance to fix [m]",
        "median time to fix [s]",
        "median error after fix [m / °]",
        "worst error after fix [m / °]",
    ]
    .map(str::to_owned)
    .to_vec();
    let mut table = Vec::new();
    for kind in [
        "on the mapped routes",
        "leaves the routes",
        "reaches the map",
        "off the map",
    ] {
        let of_kind: Vec<&TrialRow> = rows.iter().filter(|r| r.kind == kind).collect();
        if of_kind.is_empty() {
            continue;
        }
        let fixed: Vec<&&TrialRow> = of_kind.iter().filter(|r| r.localised).collect();
        let within = fixed
            .iter()
            .filter(|r| r.first_fix_distance_m.is_some_and(|d| d <= 20.0))
            .count();
        let worst = fixed
            .iter()
            .filter_map(|r| r.error_m.zip(r.error_deg))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        table.push(vec![
            kind.to_owned(),
            of_kind.len().to_string(),
            fixed.len().to_string(),
            format!("{within} ({:.0} %)", 100.0 * within as f64 / of_kind.len() as f64),
            of_kind.iter().filter(|r| r.false_fix).count().to_string(),
            figure(
                median(fixed.iter().filter_map(|r| r.first_fix_distance_m).collect()),
                1,
            ),
            figure(median(fixed.iter().filter_map(|r| r.first_fix_s).collect()), 1),
            format!(
                "{} / {}",
                figure(median(fixed.iter().filter_map(|r| r.error_m).collect()), 3),
                figure(median(fixed.iter().filter_map(|r| r.error_deg).collect()), 2)
            ),
            worst.map_or("–".to_owned(), |(m, deg)| format!("{m:.3} / {deg:.2}")),
        ]);
    }
    let costed: Vec<&TrialRow> = rows
        .iter()
        .filter(|r| r.slam_loop_ms_per_scan.is_some())
        .collect();
    let cost = if costed.is_empty() {
        String::new()
    } else {
        let mean = |values: Vec<f64>| values.iter().sum::<f64>() / values.len().max(1) as f64;
        let localise_ms = mean(costed.iter().map(|r| r.loop_ms_per_scan).collect());
        let slam_ms = mean(costed.iter().filter_map(|r| r.slam_loop_ms_per_scan).collect());
        format!(
            "Loop closure and back-end per scan (everything beyond the source and the odometry), over the {} \
             trials also run without the prior: {localise_ms:.1} ms with the prior, {slam_ms:.1} ms for full \
             SLAM alone.\n",
            costed.len()
        )
    };
    format!(
        "World `{}` (seed {}) mapped by the default run; trials: {} scans each with {}.\n\n{}\n{cost}",
        settings.world,
        settings.seed,
        settings.trial_max_scans,
        settings.trial_sets.join(", "),
        crate::markdown_table(&header, &table),
    )
}
