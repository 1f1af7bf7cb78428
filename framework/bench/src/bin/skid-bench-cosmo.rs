//! `cargo xtask bench cosmo`: every COSMO-Bench problem of the shared data (McGann, Potokar & Kaess,
//! "COSMO-Bench", 2025: real 3-robot LiDAR problems with labelled wrong loops, in the JSON Robot Log
//! format) through SKiD's configured verifier and back-end (`skid_replay`, the plugins `skid run` builds),
//! batch and distributed-incremental, beside GTSAM 4.3 measured in the same run
//! (`python/cosmo_gtsam.py`: LM on every factor, LM on the labelled inliers, GNC-TLS). Per problem and
//! mode: each robot's ATE without alignment, the labelled outliers kept, the true loops dropped, the
//! time against GTSAM GNC's and the p95 update time; and a top-down plot of each problem (ground truth
//! dashed, the batch estimate, the loops kept coloured by label). Parameters in `configs/bench/cosmo.toml`.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use skid_bench::python_peers;
use skid_config::ConfigSources;
use skid_core::Registry;
use skid_eval::plot::{Chart, PlotOptions, Series, SeriesStyle, draw_chart};
use skid_replay::{ConfiguredPlugins, ReplayMode, ReplayOutcome, ReplayProblem, ReplayReport, problem::Item};

/// The profile's parameters.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct CosmoSettings {
    /// Problems to run by file stem; empty runs every `.jrl` file of `<data>/cosmo_bench/`.
    datasets: Vec<String>,
    /// `section.key=value` settings applied to SKiD's configuration in both modes (as `skid replay --set`).
    sets: Vec<String>,
}

/// GTSAM's figures on one problem (`cosmo_gtsam.py`).
#[derive(Debug, Deserialize)]
struct Gtsam {
    lm_all: GtsamSolve,
    lm_inliers: GtsamSolve,
    gnc_tls: GtsamGnc,
}

#[derive(Debug, Deserialize)]
struct GtsamSolve {
    ate_m: BTreeMap<String, f64>,
    s: f64,
}

#[derive(Debug, Deserialize)]
struct GtsamGnc {
    ate_m: BTreeMap<String, f64>,
    s: f64,
    outliers_kept: usize,
    inliers_dropped: usize,
}

/// One row of the table: a problem in one mode.
#[derive(Debug, Serialize)]
struct Row {
    dataset: String,
    mode: &'static str,
    /// SKiD's ATE per robot and GTSAM GNC-TLS's, `a / b / c`, metres.
    ate_m: String,
    gtsam_gnc_ate_m: String,
    /// The largest of SKiD's per-robot ATE over GTSAM GNC's.
    worst_ate_ratio: f64,
    outliers_kept: usize,
    gtsam_outliers_kept: usize,
    inliers_dropped: usize,
    gtsam_inliers_dropped: usize,
    time_s: f64,
    gtsam_gnc_s: f64,
    time_ratio: f64,
    p95_update_ms: f64,
    max_update_ms: f64,
    /// The slowest robot's share of an update (incremental mode; each robot runs on its own computer).
    p95_slowest_robot_update_ms: f64,
    /// GTSAM LM on every factor and on the labelled inliers, ATE per robot.
    gtsam_lm_all_ate_m: String,
    gtsam_lm_inliers_ate_m: String,
    gtsam_lm_all_s: f64,
}

fn per_robot(values: impl IntoIterator<Item = f64>) -> String {
    values
        .into_iter()
        .map(|v| format!("{v:.2}"))
        .collect::<Vec<_>>()
        .join(" / ")
}

fn main() -> Result<()> {
    skid_bench::run_profile("cosmo", |settings: &CosmoSettings, report, out| {
        let registry = skid_builtin::registry().context("registering the built-in plugins")?;
        let python = python_peers::python();
        let folder = skid_io::data_dir().join("cosmo_bench");
        let mut files = skid_bench::files::files_with_extension(&folder, "jrl")?;
        files.retain(|file| {
            let stem = file
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            settings.datasets.is_empty() || settings.datasets.contains(&stem)
        });
        anyhow::ensure!(
            !files.is_empty(),
            "no COSMO-Bench problem (.jrl) in {}",
            folder.display()
        );
        let mut rows = Vec::new();
        let mut plots = String::new();
        for file in &files {
            let gtsam: Option<Gtsam> = match &python {
                Some(python) => {
                    let stdout = python_peers::script_stdout(python, "cosmo_gtsam.py", &[file.as_os_str()])?;
                    Some(serde_json::from_slice(&stdout).context("reading cosmo_gtsam.py's output")?)
                }
                None => None,
            };
            let dataset = skid_io::jrl::read_jrl(file)?;
            let problem = ReplayProblem::from_dataset(&dataset)
                .with_context(|| format!("replaying {}", file.display()))?;
            for mode in [ReplayMode::Batch, ReplayMode::Incremental] {
                let outcome = replay(&registry, settings, &problem, mode)
                    .with_context(|| format!("replaying {}", file.display()))?;
                let replayed = ReplayReport::new(&problem, &outcome);
                let row = row_of(&replayed, gtsam.as_ref());
                eprintln!(
                    "{} {}: ATE {} m (GTSAM GNC {} m), outliers kept {}, true loops dropped {}, {:.2} s (GTSAM GNC {:.1} s), p95 update {:.1} ms",
                    row.dataset,
                    row.mode,
                    row.ate_m,
                    row.gtsam_gnc_ate_m,
                    row.outliers_kept,
                    row.inliers_dropped,
                    row.time_s,
                    row.gtsam_gnc_s,
                    row.p95_update_ms
                );
                report.push(&row)?;
                rows.push(row);
                if mode == ReplayMode::Batch {
                    let path = out.join(format!("{}.png", problem.name));
                    let plotted = plot(&path, &problem, &outcome)?;
                    plots.push_str(&plotted.markdown());
                    plots.push('\n');
                }
            }
        }
        Ok(markdown(&rows, &plots))
    })
}

fn replay(
    registry: &Registry,
    settings: &CosmoSettings,
    problem: &ReplayProblem,
    mode: ReplayMode,
) -> Result<ReplayOutcome> {
    let sources = ConfigSources {
        sets: settings.sets.clone(),
        ..ConfigSources::default()
    };
    let config = skid_replay::load_config(sources, mode, registry)?;
    let plugins = ConfiguredPlugins {
        registry,
        config: &config,
    };
    Ok(skid_replay::replay(problem, mode, &plugins, plugins.budget())?)
}

fn row_of(replayed: &ReplayReport, gtsam: Option<&Gtsam>) -> Row {
    let letters: Vec<String> = replayed.robots.iter().map(|r| r.robot.to_string()).collect();
    let reference = |map: &BTreeMap<String, f64>| -> Vec<f64> {
        letters
            .iter()
            .map(|l| map.get(l).copied().unwrap_or(f64::NAN))
            .collect()
    };
    let ours: Vec<f64> = replayed.robots.iter().map(|r| r.ate_m).collect();
    let gnc = gtsam.map(|g| reference(&g.gnc_tls.ate_m)).unwrap_or_default();
    let worst_ate_ratio = ours
        .iter()
        .zip(&gnc)
        .map(|(ours, theirs)| ours / theirs)
        .fold(f64::NAN, f64::max);
    let gnc_s = gtsam.map_or(f64::NAN, |g| g.gnc_tls.s);
    Row {
        dataset: replayed.dataset.clone(),
        mode: replayed.mode,
        ate_m: per_robot(ours.iter().copied()),
        gtsam_gnc_ate_m: per_robot(gnc.iter().copied()),
        worst_ate_ratio,
        outliers_kept: replayed.outliers_kept(),
        gtsam_outliers_kept: gtsam.map_or(0, |g| g.gnc_tls.outliers_kept),
        inliers_dropped: replayed.intra.inliers_dropped + replayed.inter.inliers_dropped,
        gtsam_inliers_dropped: gtsam.map_or(0, |g| g.gnc_tls.inliers_dropped),
        time_s: replayed.total_s,
        gtsam_gnc_s: gnc_s,
        time_ratio: replayed.total_s / gnc_s,
        p95_update_ms: replayed.updates.p95_ms,
        max_update_ms: replayed.updates.max_ms,
        p95_slowest_robot_update_ms: replayed.slowest_robot_updates.p95_ms,
        gtsam_lm_all_ate_m: gtsam
            .map(|g| per_robot(reference(&g.lm_all.ate_m)))
            .unwrap_or_default(),
        gtsam_lm_inliers_ate_m: gtsam
            .map(|g| per_robot(reference(&g.lm_inliers.ate_m)))
            .unwrap_or_default(),
        gtsam_lm_all_s: gtsam.map_or(f64::NAN, |g| g.lm_all.s),
    }
}

/// Top-down view of one problem: each robot's ground truth dashed and its estimate, and the loops the
/// back-end kept, green when the file labels them true and red when it labels them wrong.
fn plot(
    path: &Path,
    problem: &ReplayProblem,
    outcome: &ReplayOutcome,
) -> Result<skid_eval::plot::PlotOutput> {
    const COLOURS: [[u8; 3]; 3] = [[31, 119, 180], [255, 127, 14], [148, 103, 189]];
    let mut series = Vec::new();
    for (index, (robot, estimate)) in problem.robots.iter().zip(&outcome.estimates).enumerate() {
        let colour = COLOURS[index % COLOURS.len()];
        let xy = |pose: &skid_core::Pose| (pose.translation.x, pose.translation.y);
        series.push(Series {
            name: Some(format!("{} ground truth", robot.letter)),
            points: robot.ground_truth.values().map(xy).collect(),
            color: Some(colour.map(|c| c / 2 + 100)),
            style: SeriesStyle::DashedLine,
        });
        series.push(Series {
            name: Some(format!("{} SKiD batch", robot.letter)),
            points: estimate.values().map(xy).collect(),
            color: Some(colour),
            style: SeriesStyle::Line,
        });
    }
    let mut true_kept = Vec::new();
    let mut wrong_kept = Vec::new();
    let position = |id: skid_core::KeyframeId| {
        outcome
            .estimates
            .get(id.robot.0 as usize)
            .and_then(|estimate| estimate.get(&id.index))
            .map(|pose| (pose.translation.x, pose.translation.y))
    };
    for event in &problem.events {
        for item in &event.items {
            let Item::Loop { closure, label } = item else {
                continue;
            };
            let kept = outcome.loops.get(&closure.id).is_some_and(|fate| fate.kept());
            if let (true, Some(a), Some(b)) = (kept, position(closure.target), position(closure.source)) {
                let list = if label.outlier {
                    &mut wrong_kept
                } else {
                    &mut true_kept
                };
                list.extend([a, b]);
            }
        }
    }
    series.push(Series {
        name: Some("true loops kept".into()),
        points: true_kept,
        color: Some([44, 160, 44]),
        style: SeriesStyle::Segments,
    });
    series.push(Series {
        name: Some("wrong loops kept".into()),
        points: wrong_kept,
        color: Some([214, 39, 40]),
        style: SeriesStyle::Segments,
    });
    let chart = Chart {
        title: format!("{}: SKiD batch", problem.name),
        x_label: "x (m)".into(),
        y_label: "y (m)".into(),
        series,
        equal_aspect: true,
        ..Chart::default()
    };
    Ok(draw_chart(path, &chart, &PlotOptions::default())?)
}

fn markdown(rows: &[Row], plots: &str) -> String {
    let header: Vec<String> = [
        "problem",
        "mode",
        "ATE a / b / c (m)",
        "GTSAM GNC-TLS",
        "worst ratio",
        "outliers kept (GTSAM)",
        "true loops dropped (GTSAM)",
        "time s (GTSAM GNC)",
        "time ratio",
        "p95 / max update ms",
        "p95 slowest robot's share ms",
        "GTSAM LM all / LM inliers",
    ]
    .map(String::from)
    .to_vec();
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.dataset.clone(),
                r.mode.to_owned(),
                r.ate_m.clone(),
                r.gtsam_gnc_ate_m.clone(),
                format!("{:.2}", r.worst_ate_ratio),
                format!("{} ({})", r.outliers_kept, r.gtsam_outliers_kept),
                format!("{} ({})", r.inliers_dropped, r.gtsam_inliers_dropped),
                format!("{:.2} ({:.1})", r.time_s, r.gtsam_gnc_s),
                format!("{:.3}", r.time_ratio),
                format!("{:.1} / {:.1}", r.p95_update_ms, r.max_update_ms),
                format!("{:.1}", r.p95_slowest_robot_update_ms),
                format!("{} / {}", r.gtsam_lm_all_ate_m, r.gtsam_lm_inliers_ate_m),
            ]
        })
        .collect();
    format!(
        "# COSMO-Bench: SKiD's verifier and back-end against GTSAM 4.3\n\nATE without alignment (each robot's prior \
         fixes its frame). Batch: one graph of all robots; incremental: one back-end per robot, measurements in \
         stamp order; an update is one event, every robot's work for it summed, and the slowest robot's share \
         is what the robot that spent the most on it spent in its own verifiers and back-end: the update's \
         latency, as each robot runs on its own computer. GTSAM: batch, from the file's initialisation, measured in the same run.\n\n{}\n{}",
        skid_bench::markdown_table(&header, &body),
        plots
    )
}
