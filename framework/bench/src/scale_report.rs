//! The rows, tables and plots of `cargo xtask bench scale`, from the runs [`crate::scale`] makes.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Result;
use serde::Serialize;
use serde_json::Value;
use skid_eval::plot::{PlotOptions, Series, line_plot};
use skid_runtime::{FALSE_MERGE_DEG, FALSE_MERGE_M};

use crate::report::markdown_table;
use crate::scale::{ScaleRun, window};

/// The stages whose CPU time per robot-scan the sweep reports, in pipeline order.
pub const STAGES: [&str; 9] = [
    "source",
    "odometry",
    "descriptor",
    "retrieval",
    "coarse",
    "fine_prepare",
    "fine",
    "verifier",
    "backend",
];

/// The message kinds whose bytes per robot-minute the sweep reports.
pub const KINDS: [&str; 5] = ["descriptors", "odom_chain", "cloud_request", "cloud", "loops"];

/// One fleet size.
#[derive(Clone, Debug, Serialize)]
pub struct FleetRow {
    pub robots: usize,
    pub scans_per_robot: usize,
    pub keyframes: usize,
    pub wall_s: f64,
    /// Process CPU time (every thread) per robot-scan.
    pub cpu_ms_per_robot_scan: f64,
    /// Each stage's time per robot-scan, as the hosts clock it.
    pub stage_ms_per_robot_scan: BTreeMap<String, f64>,
    pub peak_rss_mb: f64,
    /// Bytes each robot sent per minute of robot time, by message kind.
    pub sent_bytes_per_robot_min: BTreeMap<String, f64>,
    pub inter_robot_loops: usize,
    pub intra_robot_loops: usize,
    /// False loops over every robot's graph (`RunMetrics::false_loops_in_graphs`).
    pub false_loops_in_graphs: usize,
    pub ate_alpha_m: Option<f64>,
    /// The α/β metric over every robot β that α placed.
    pub ate_beta_mean_m: Option<f64>,
    pub ate_beta_max_m: Option<f64>,
    pub betas_placed: usize,
    /// Robots α placed more than 2 m or 5° from where they are (false merges).
    pub betas_placed_falsely: usize,
    /// The largest frame error of a placed robot, metres and degrees.
    pub frame_error_max: Option<(f64, f64)>,
    /// Inter-robot candidates over the fleet: raised, admitted by the budget, expired, and still
    /// waiting (queued or for a cloud) at the end.
    pub candidates: [usize; 4],
    /// Keyframe-cloud bytes sent per accepted inter-robot loop.
    pub cloud_bytes_per_inter_loop: Option<f64>,
}

/// The fleet row of a finished run.
pub fn fleet_row(run: &ScaleRun) -> FleetRow {
    let robots = &run.summary.robots;
    let robot_scans: usize = robots.iter().map(|r| r.scans).sum::<usize>().max(1);
    let mut stage_ms_per_robot_scan = BTreeMap::new();
    for stage in STAGES {
        let total: f64 = robots.iter().filter_map(|r| r.stage_ms.get(stage)).sum();
        stage_ms_per_robot_scan.insert(stage.to_owned(), total / robot_scans as f64);
    }
    let robot_minutes = robot_scans as f64 / 600.0;
    let mut sent_bytes_per_robot_min = BTreeMap::new();
    for kind in KINDS {
        let bytes: f64 = robots
            .iter()
            .map(|r| {
                let messages = serde_json::to_value(&r.messages).unwrap_or(Value::Null);
                messages["sent"][kind]["bytes"].as_f64().unwrap_or(0.0)
            })
            .sum();
        sent_bytes_per_robot_min.insert(kind.to_owned(), bytes / robot_minutes);
    }
    let betas: Vec<f64> = run
        .metrics
        .robots
        .iter()
        .skip(1)
        .filter_map(|r| r.alignment.as_ref().map(|a| a.beta_in_alpha_ate_m.rmse))
        .collect();
    let frame_errors: Vec<(f64, f64)> = run
        .metrics
        .robots
        .iter()
        .skip(1)
        .filter_map(|r| {
            r.alignment.as_ref().map(|a| {
                (
                    a.beta_alignment_error.translation_m,
                    a.beta_alignment_error.rotation_deg,
                )
            })
        })
        .collect();
    FleetRow {
        robots: robots.len(),
        scans_per_robot: robots.first().map_or(0, |r| r.scans),
        keyframes: robots.iter().map(|r| r.keyframes).sum(),
        wall_s: run.summary.wall_s,
        cpu_ms_per_robot_scan: run.cpu_s * 1e3 / robot_scans as f64,
        stage_ms_per_robot_scan,
        peak_rss_mb: run.peak_rss_mb,
        sent_bytes_per_robot_min,
        inter_robot_loops: run.metrics.inter_robot_loops_accepted,
        intra_robot_loops: robots.iter().map(|r| r.loops.accepted_intra).sum(),
        false_loops_in_graphs: run.metrics.false_loops_in_graphs,
        ate_alpha_m: run
            .metrics
            .robots
            .first()
            .and_then(|r| r.trajectory.as_ref().map(|t| t.ate_m.rmse)),
        ate_beta_mean_m: (!betas.is_empty()).then(|| betas.iter().sum::<f64>() / betas.len() as f64),
        ate_beta_max_m: betas.iter().copied().reduce(f64::max),
        betas_placed: betas.len(),
        betas_placed_falsely: frame_errors
            .iter()
            .filter(|(m, deg)| *m > FALSE_MERGE_M || *deg > FALSE_MERGE_DEG)
            .count(),
        frame_error_max: frame_errors
            .iter()
            .copied()
            .reduce(|a, b| (a.0.max(b.0), a.1.max(b.1))),
        candidates: robots.iter().fold([0; 4], |sum, r| {
            let loops = &r.loops;
            [
                sum[0] + loops.candidates_inter,
                sum[1] + loops.inter_admitted,
                sum[2] + loops.expired,
                sum[3] + loops.queued + loops.awaiting_cloud,
            ]
        }),
        cloud_bytes_per_inter_loop: run.metrics.cloud_bytes_per_inter_loop,
    }
}

/// The per-keyframe cost of the long mission over one minute of robot time, and the work behind it.
#[derive(Clone, Debug, Serialize)]
pub struct MinuteRow {
    pub minute: u32,
    pub keyframes: usize,
    pub backend_ms_per_keyframe: Option<f64>,
    pub verifier_ms_per_keyframe: Option<f64>,
    /// Loop candidates the verifiers judged, and their time per candidate.
    pub verified: usize,
    pub verifier_ms_per_candidate: Option<f64>,
    /// Loops the back-ends' graphs gained or lost, and the back-end time per such change.
    pub loop_changes: usize,
    pub backend_ms_per_loop_change: Option<f64>,
}

/// Every minute's row of the long mission, `1..=minutes` (minute m covers `[m-1, m)`).
pub fn minute_rows(run: &ScaleRun, minutes: u32) -> Vec<MinuteRow> {
    (1..=minutes)
        .map(|minute| {
            let window = window(
                &run.samples,
                f64::from(minute - 1) * 60.0,
                f64::from(minute) * 60.0,
            );
            MinuteRow {
                minute,
                keyframes: window.map_or(0, |w| w.keyframes),
                backend_ms_per_keyframe: window.map(|w| w.backend_ms_per_keyframe()),
                verifier_ms_per_keyframe: window.map(|w| w.verifier_ms_per_keyframe()),
                verified: window.map_or(0, |w| w.verified),
                verifier_ms_per_candidate: window.and_then(|w| w.verifier_ms_per_candidate()),
                loop_changes: window.map_or(0, |w| w.loop_changes),
                backend_ms_per_loop_change: window.and_then(|w| w.backend_ms_per_loop_change()),
            }
        })
        .collect()
}

fn cell(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "–".to_owned(), |v| format!("{v:.digits$}"))
}

/// The sweep's table and plots (written into `out`).
pub fn fleet_markdown(rows: &[FleetRow], out: &Path) -> Result<String> {
    let header: Vec<String> = [
        "robots",
        "scans/robot",
        "wall s",
        "CPU ms/robot-scan",
        "source+odometry ms¹",
        "loops ms¹ (coarse+fine+prepare)",
        "verifier ms¹",
        "backend ms¹",
        "peak MB",
        "KB/robot/min (descr, chain, cloud)",
        "loops inter/intra (false³)",
        "ATE α m",
        "α/β mean / max m",
        "in α's frame (false²)",
        "largest frame error m / °",
        "inter cand. raised/verified/expired/waiting",
        "cloud KB per inter loop",
    ]
    .map(str::to_owned)
    .to_vec();
    let stage = |row: &FleetRow, names: &[&str]| -> f64 {
        // `+ 0.0` turns the empty sum's -0.0 into 0.
        names
            .iter()
            .filter_map(|n| row.stage_ms_per_robot_scan.get(*n))
            .sum::<f64>()
            + 0.0
    };
    let kb =
        |row: &FleetRow, kind: &str| row.sent_bytes_per_robot_min.get(kind).copied().unwrap_or(0.0) / 1e3;
    let table_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|row| {
            vec![
                row.robots.to_string(),
                row.scans_per_robot.to_string(),
                format!("{:.0}", row.wall_s),
                format!("{:.1}", row.cpu_ms_per_robot_scan),
                format!("{:.1}", stage(row, &["source", "odometry"])),
                format!("{:.1}", stage(row, &["coarse", "fine", "fine_prepare"])),
                format!("{:.3}", stage(row, &["verifier"])),
                format!("{:.3}", stage(row, &["backend"])),
                format!("{:.0}", row.peak_rss_mb),
                format!(
                    "{:.1}, {:.1}, {:.0}",
                    kb(row, "descriptors"),
                    kb(row, "odom_chain"),
                    kb(row, "cloud")
                ),
                format!(
                    "{} / {} ({})",
                    row.inter_robot_loops, row.intra_robot_loops, row.false_loops_in_graphs
                ),
                cell(row.ate_alpha_m, 3),
                format!(
                    "{} / {} ({} placed)",
                    cell(row.ate_beta_mean_m, 3),
                    cell(row.ate_beta_max_m, 3),
                    row.betas_placed
                ),
                format!(
                    "{} of {} ({})",
                    row.betas_placed,
                    row.robots.saturating_sub(1),
                    row.betas_placed_falsely
                ),
                row.frame_error_max
                    .map_or_else(|| "–".to_owned(), |(m, deg)| format!("{m:.2} / {deg:.2}")),
                format!(
                    "{}/{}/{}/{}",
                    row.candidates[0], row.candidates[1], row.candidates[2], row.candidates[3]
                ),
                cell(row.cloud_bytes_per_inter_loop.map(|bytes| bytes / 1e3), 1),
            ]
        })
        .collect();
    let mut text = markdown_table(&header, &table_rows);
    text.push_str(
        "\n¹ Per robot-scan, as the hosts clock each stage (wall time inside the stage; with the `threads` \
         executor the robots' front-ends share the machine's cores, so a stage's time includes waiting for \
         one). The CPU column is the process's own CPU time (every thread) per robot-scan.\n\
         ² Placed more than 2 m or 5° from the truth: a false merge.\n\
         ³ Loops in the robots' graphs at the end more than 2 m or 5° from the keyframes' true relative pose, \
         over every graph (a loop two graphs hold counts twice).\n",
    );
    let per_n = |value: &dyn Fn(&FleetRow) -> f64| -> Vec<(f64, f64)> {
        rows.iter().map(|row| (row.robots as f64, value(row))).collect()
    };
    let stage_series: Vec<Series> = STAGES
        .iter()
        .map(|name| Series::line(*name, per_n(&|row| stage(row, &[name]))))
        .collect();
    let plot = line_plot(
        &out.join("scale_stages.png"),
        "CPU time per robot-scan by stage",
        "robots",
        "ms per robot-scan",
        stage_series,
        &PlotOptions::default(),
    )?;
    text.push_str(&format!("\n{}\n", plot.markdown()));
    let byte_series: Vec<Series> = KINDS
        .iter()
        .map(|kind| Series::line(*kind, per_n(&|row| kb(row, kind))))
        .collect();
    let plot = line_plot(
        &out.join("scale_bytes.png"),
        "Bytes each robot sends per minute, by message kind",
        "robots",
        "KB per robot per minute",
        byte_series,
        &PlotOptions::default(),
    )?;
    text.push_str(&format!("\n{}\n", plot.markdown()));
    Ok(text)
}

/// A long mission's checkpoint table and its per-minute plot (written to `plot_path`).
pub fn long_markdown(rows: &[MinuteRow], checkpoints: &[u32], plot_path: &Path) -> Result<String> {
    let header: Vec<String> = [
        "minute",
        "back-end ms/keyframe",
        "verifier ms/keyframe",
        "sum",
        "× minute 1",
        "keyframes",
        "candidates verified",
        "verifier ms/candidate",
        "loop changes",
        "back-end ms/loop change",
    ]
    .map(str::to_owned)
    .to_vec();
    let total = |row: &MinuteRow| match (row.backend_ms_per_keyframe, row.verifier_ms_per_keyframe) {
        (Some(b), Some(v)) => Some(b + v),
        _ => None,
    };
    let first = rows.first().and_then(total);
    let table_rows: Vec<Vec<String>> = rows
        .iter()
        .filter(|row| checkpoints.contains(&row.minute))
        .map(|row| {
            let sum = total(row);
            vec![
                row.minute.to_string(),
                cell(row.backend_ms_per_keyframe, 2),
                cell(row.verifier_ms_per_keyframe, 2),
                cell(sum, 2),
                cell(sum.zip(first).map(|(s, f)| s / f), 2),
                row.keyframes.to_string(),
                row.verified.to_string(),
                cell(row.verifier_ms_per_candidate, 2),
                row.loop_changes.to_string(),
                cell(row.backend_ms_per_loop_change, 2),
            ]
        })
        .collect();
    let mut text = markdown_table(&header, &table_rows);
    let series = |name: &str, value: &dyn Fn(&MinuteRow) -> Option<f64>| {
        Series::line(
            name,
            rows.iter()
                .filter_map(|row| value(row).map(|v| (f64::from(row.minute), v)))
                .collect(),
        )
    };
    let plot = line_plot(
        plot_path,
        "Back-end and verifier time per keyframe over a long mission",
        "minute of robot time",
        "ms per keyframe",
        vec![
            series("back-end", &|row| row.backend_ms_per_keyframe),
            series("verifier", &|row| row.verifier_ms_per_keyframe),
            series("sum", &total),
        ],
        &PlotOptions::default(),
    )?;
    text.push_str(&format!("\n{}\n", plot.markdown()));
    Ok(text)
}
