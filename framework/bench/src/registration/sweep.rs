//! The yaw sweep of the SKiD-SLAM paper's "success rate vs yaw" figure: each method's success
//! (translation < 2 m and rotation < 5°) and time per pair at every yaw of a full turn, and the success
//! rate per yaw plotted, on two kinds of pairs:
//! - the real HDL-32E pair (`lidar_scan_pair_fast_gicp`): the target yawed and moved `offset_m` metres in
//!   `directions` directions per yaw;
//! - simulated pairs in each of `sim_worlds` (the paper's figure is on planetary terrain): a scan every
//!   45 m along a route and a second real scan `sim_gap_m` further on with the sensor turned by the yaw
//!   (see [`super::pairs`]).

use std::path::Path;

use anyhow::{Context, Result, anyhow};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use skid_core::{Cloud, Pose};
use skid_eval::plot::{PlotOptions, Series, line_plot};
use skid_sim::WorldKind;

use super::pairs::{PairKind, RouteSampler};
use super::{FreeSpaceJudge, Methods, Row, check_methods, mean, percent, pose_errors};
use crate::Report;

/// Parameters of the sweep.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SweepSettings {
    /// Threads every plugin may use.
    pub threads: usize,
    /// Yaw step, degrees (the sweep covers [0°, 360°)).
    pub yaw_step_deg: f64,
    /// Distance the real pair's target is moved, metres.
    pub offset_m: f64,
    /// Offset directions per yaw for the real pair, evenly spread.
    pub directions: usize,
    pub methods: Vec<String>,
    /// Simulated worlds swept too (empty: the real pair only).
    pub sim_worlds: Vec<String>,
    pub sim_sensor: String,
    /// Simulated pairs per yaw (targets 45 m apart along one route).
    pub sim_pairs_per_yaw: usize,
    /// Distance along the route between a simulated pair's scans, metres.
    pub sim_gap_m: f64,
    pub seed: u64,
}

impl Default for SweepSettings {
    fn default() -> Self {
        Self {
            threads: 2,
            yaw_step_deg: 15.0,
            offset_m: 10.0,
            directions: 4,
            methods: [
                "KISS-Matcher",
                "KISS-Matcher + GICP",
                "RANSAC",
                "RANSAC + GICP",
                "GICP (identity)",
            ]
            .map(str::to_owned)
            .to_vec(),
            sim_worlds: Vec::new(),
            sim_sensor: "os1-64".to_owned(),
            sim_pairs_per_yaw: 4,
            sim_gap_m: 6.0,
            seed: 7,
        }
    }
}

/// One pair of one method in the sweep.
#[derive(Clone, Serialize)]
pub struct SweepEntry {
    /// `real pair` or `sim <world>`.
    pub case: String,
    pub yaw_deg: f64,
    /// The offset direction (real pair) or the pair's place along the route (simulated).
    pub variant: usize,
    pub method: String,
    pub translation_error_m: Option<f64>,
    pub rotation_error_deg: Option<f64>,
    pub success: bool,
    pub valid: bool,
    /// A coarse result the runtime would refuse as ambiguous (its rival alignment nearly as strong).
    pub ambiguous: bool,
    /// A result the verifier's free-space check refuses (its defaults, the clouds at the keyframes'
    /// 0.25 m voxels): the clouds it aligns see through each other.
    pub free_space_refused: bool,
    /// Whether the method is a coarse one (reports inliers and a rival).
    pub coarse: bool,
    pub time_ms: f64,
    pub cpu_ms: Option<f64>,
}

/// The real pair: target, source and the reference `target_from_source`.
pub fn read_real_pair() -> Result<(Cloud, Cloud, Pose)> {
    let pair = skid_io::scan_pair::read_scan_pair().context("reading the real scan pair")?;
    Ok((
        Cloud::new(pair.target),
        Cloud::new(pair.source),
        pair.target_from_source,
    ))
}

fn success_rate(entries: &[&SweepEntry]) -> f64 {
    100.0 * entries.iter().filter(|e| e.success).count() as f64 / entries.len().max(1) as f64
}

/// What the sweep produced.
pub struct SweepOutcome {
    pub entries: Vec<SweepEntry>,
    /// The per-yaw success tables and the plots, as Markdown.
    pub markdown: String,
}

/// A pair of a sweep: target, source, the true `target_from_source`, and where the target cloud was
/// moved from its sensor's frame (`moved_from_sensor`; the identity when it was not).
type SweepPair = (Cloud, Cloud, Pose, Pose);

/// Runs every method on the pairs `pairs_at(yaw)` gives at every yaw, appending to `entries`.
fn sweep_case(
    methods: &mut Methods,
    settings: &SweepSettings,
    case: &str,
    yaws: &[f64],
    pairs_at: &mut dyn FnMut(f64) -> Result<Vec<SweepPair>>,
    entries: &mut Vec<SweepEntry>,
) -> Result<()> {
    for &yaw_deg in yaws {
        for (variant, (target, source, truth, moved_from_sensor)) in pairs_at(yaw_deg)?.iter().enumerate() {
            // The verifier sees the clouds in their sensors' frames.
            let sensor_target = target.view().transformed(&moved_from_sensor.inverse());
            let free_space = FreeSpaceJudge::new(&sensor_target, source);
            for method in &settings.methods {
                let outcome = methods.run(method, target, source, &Pose::identity())?;
                let in_sensor_frames = outcome
                    .estimate
                    .map(|estimate| moved_from_sensor.inverse() * estimate);
                let free_space_refused = free_space.refuses(in_sensor_frames.as_ref());
                let (translation_error_m, rotation_error_deg, success) =
                    pose_errors(&outcome.estimate, truth);
                entries.push(SweepEntry {
                    case: case.to_owned(),
                    yaw_deg,
                    variant,
                    method: method.clone(),
                    translation_error_m,
                    rotation_error_deg,
                    success,
                    valid: outcome.valid,
                    ambiguous: outcome.ambiguous(),
                    free_space_refused,
                    coarse: outcome.inliers.is_some(),
                    time_ms: outcome.time_ms,
                    cpu_ms: outcome.cpu_ms,
                });
            }
        }
        eprintln!("{case}: yaw {yaw_deg:>5.1}° done");
    }
    Ok(())
}

/// The real pair's yawed and moved copies at `yaw_deg`.
fn real_pairs(settings: &SweepSettings, pair: &(Cloud, Cloud, Pose), yaw_deg: f64) -> Vec<SweepPair> {
    let (target, source, reference) = pair;
    let directions = settings.directions.max(1);
    (0..directions)
        .map(|d| {
            let direction = std::f64::consts::TAU * d as f64 / directions as f64;
            let motion = Pose::new(
                Vector3::new(
                    settings.offset_m * direction.cos(),
                    settings.offset_m * direction.sin(),
                    0.0,
                ),
                Vector3::z() * yaw_deg.to_radians(),
            );
            (
                target.view().transformed(&motion),
                source.clone(),
                motion * reference,
                motion,
            )
        })
        .collect()
}

/// The per-yaw table, the plot and the summary rows of one case.
fn case_results(
    settings: &SweepSettings,
    case: &str,
    title: &str,
    yaws: &[f64],
    entries: &[SweepEntry],
    report: &mut Report,
    plot_path: &Path,
) -> Result<String> {
    let entries: Vec<&SweepEntry> = entries.iter().filter(|e| e.case == case).collect();
    let mut table = format!("\n## {title}: success rate [%] per yaw\n\n| yaw [°] |");
    for method in &settings.methods {
        table.push_str(&format!(" {method} |"));
    }
    table.push_str(&format!("\n|---|{}\n", "---|".repeat(settings.methods.len())));
    for &yaw_deg in yaws {
        table.push_str(&format!("| {yaw_deg:.0} |"));
        for method in &settings.methods {
            let at: Vec<&SweepEntry> = entries
                .iter()
                .copied()
                .filter(|e| &e.method == method && e.yaw_deg == yaw_deg)
                .collect();
            table.push_str(&format!(" {:.0} |", success_rate(&at)));
        }
        table.push('\n');
    }
    let mut series = Vec::new();
    for method in &settings.methods {
        let mine: Vec<&SweepEntry> = entries.iter().copied().filter(|e| &e.method == method).collect();
        let points = yaws
            .iter()
            .map(|&yaw_deg| {
                let at: Vec<&SweepEntry> = mine.iter().copied().filter(|e| e.yaw_deg == yaw_deg).collect();
                (yaw_deg, success_rate(&at))
            })
            .collect();
        series.push(Series::line(method, points));
        let times: Vec<f64> = mine.iter().map(|e| e.time_ms).collect();
        let successes: Vec<&&SweepEntry> = mine.iter().filter(|e| e.success).collect();
        report.push(&Row {
            data: format!("{case}, yaw sweep"),
            method: method.clone(),
            pairs: mine.len(),
            success_rate_percent: success_rate(&mine),
            unambiguous_success_percent: mine.iter().any(|e| e.coarse).then(|| {
                percent(
                    mine.iter().filter(|e| e.success && !e.ambiguous).count(),
                    mine.len(),
                )
            }),
            free_space_success_percent: Some(percent(
                mine.iter().filter(|e| e.success && !e.free_space_refused).count(),
                mine.len(),
            )),
            rte_cm: mean(
                &successes
                    .iter()
                    .filter_map(|e| e.translation_error_m)
                    .map(|t| t * 100.0)
                    .collect::<Vec<_>>(),
            ),
            rre_deg: mean(
                &successes
                    .iter()
                    .filter_map(|e| e.rotation_error_deg)
                    .collect::<Vec<_>>(),
            ),
            mean_time_ms: times.iter().sum::<f64>() / times.len().max(1) as f64,
            max_time_ms: times.iter().copied().fold(0.0, f64::max),
            mean_cpu_ms: mean(&mine.iter().filter_map(|e| e.cpu_ms).collect::<Vec<_>>()),
        })?;
    }
    let plot = line_plot(
        plot_path,
        &format!("Success rate vs yaw ({title})"),
        "yaw [deg]",
        "success rate [%]",
        series,
        &PlotOptions::default(),
    )?;
    table.push_str(&format!("\n{}\n", plot.markdown()));
    Ok(table)
}

/// Runs the sweep on the real pair and on every simulated world, pushes one summary row per case and
/// method into `report`, and writes `yaw_sweep.json` and one `success_vs_yaw*.png` per case into `out`.
pub fn yaw_sweep(
    methods: &mut Methods,
    settings: &SweepSettings,
    report: &mut Report,
    out: &Path,
) -> Result<SweepOutcome> {
    check_methods(&settings.methods)?;
    if !(settings.yaw_step_deg > 0.0 && settings.yaw_step_deg <= 360.0) {
        return Err(anyhow!(
            "yaw_step_deg must be in (0, 360], got {}",
            settings.yaw_step_deg
        ));
    }
    std::fs::create_dir_all(out)?;
    let steps = (360.0 / settings.yaw_step_deg).round().max(1.0) as usize;
    let yaws: Vec<f64> = (0..steps).map(|s| s as f64 * settings.yaw_step_deg).collect();
    let mut entries: Vec<SweepEntry> = Vec::new();
    let real = read_real_pair()?;
    sweep_case(
        methods,
        settings,
        "real pair",
        &yaws,
        &mut |yaw| Ok(real_pairs(settings, &real, yaw)),
        &mut entries,
    )?;
    let mut markdown = case_results(
        settings,
        "real pair",
        &format!(
            "real HDL-32E pair, {} offset directions of {} m",
            settings.directions.max(1),
            settings.offset_m
        ),
        &yaws,
        &entries,
        report,
        &out.join("success_vs_yaw.png"),
    )?;
    for world in &settings.sim_worlds {
        let kind: WorldKind = world.parse()?;
        let count = settings.sim_pairs_per_yaw.max(1);
        let sampler = RouteSampler::new(
            kind,
            &settings.sim_sensor,
            45.0 * count as f64 + settings.sim_gap_m + 60.0,
            settings.seed,
        )?;
        let anchors: Vec<(usize, Pose, Cloud)> = (0..count)
            .filter_map(|k| {
                let index = 20 + 45 * k;
                let pose = sampler.target_pose(index)?;
                Some((index, pose, sampler.scan(pose, settings.seed ^ ((k as u64) << 8))))
            })
            .collect();
        let case = format!("sim {kind}");
        sweep_case(
            methods,
            settings,
            &case,
            &yaws,
            &mut |yaw_deg| {
                Ok(anchors
                    .iter()
                    .filter_map(|(index, pose, target)| {
                        let source_pose = sampler.source_pose(
                            PairKind::RandomYaw,
                            *index,
                            settings.sim_gap_m,
                            yaw_deg.to_radians(),
                        )?;
                        let key = settings.seed ^ ((*index as u64) << 16) ^ (yaw_deg as u64);
                        Some((
                            target.clone(),
                            sampler.scan(source_pose, key),
                            pose.inverse() * source_pose,
                            Pose::identity(),
                        ))
                    })
                    .collect())
            },
            &mut entries,
        )?;
        markdown.push_str(&case_results(
            settings,
            &case,
            &format!(
                "simulated {kind}, {count} pairs {} m apart along a route, the second sensor turned",
                settings.sim_gap_m
            ),
            &yaws,
            &entries,
            report,
            &out.join(format!("success_vs_yaw_{kind}.png")),
        )?);
    }
    std::fs::write(
        out.join("yaw_sweep.json"),
        serde_json::to_string_pretty(&entries)?,
    )
    .context("writing yaw_sweep.json")?;
    Ok(SweepOutcome { entries, markdown })
}
