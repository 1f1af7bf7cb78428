//! The yaw sweep of the SKiD-SLAM paper's "success rate vs yaw" figure, on the real HDL-32E pair
//! (`lidar_scan_pair_fast_gicp`): the target is yawed through a full turn and moved `offset_m` metres in
//! `directions` directions per yaw; each method's success (translation < 2 m and rotation < 5°) and time
//! per pair are recorded, and the success rate per yaw is plotted.

use std::path::Path;

use anyhow::{Context, Result, anyhow};
use nalgebra::{Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use skid_core::{Cloud, Pose};
use skid_eval::plot::{PlotOptions, Series, line_plot};

use super::{Methods, Row, check_methods, mean, pose_errors};
use crate::Report;

/// Parameters of the sweep.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SweepSettings {
    /// Threads every plugin may use.
    pub threads: usize,
    /// Yaw step, degrees (the sweep covers [0°, 360°)).
    pub yaw_step_deg: f64,
    /// Distance the target is moved, metres.
    pub offset_m: f64,
    /// Offset directions per yaw, evenly spread.
    pub directions: usize,
    pub methods: Vec<String>,
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
        }
    }
}

/// One pair of one method in the sweep.
#[derive(Clone, Serialize)]
pub struct SweepEntry {
    pub yaw_deg: f64,
    pub direction_deg: f64,
    pub method: String,
    pub translation_error_m: Option<f64>,
    pub rotation_error_deg: Option<f64>,
    pub success: bool,
    pub valid: bool,
    pub time_ms: f64,
    pub cpu_ms: Option<f64>,
}

/// The real pair: target, source and the reference `target_from_source`.
pub fn read_real_pair() -> Result<(Cloud, Cloud, Pose)> {
    let dir = skid_io::data_path("lidar_scan_pair_fast_gicp")?;
    let read = |name: &str| -> Result<Cloud> {
        let cloud = skid_io::pcd::read_pcd(dir.join(name), skid_io::CloudReadOptions::VALID_ONLY)
            .with_context(|| format!("reading {name}"))?;
        Ok(Cloud::new(cloud.points))
    };
    let text = std::fs::read_to_string(dir.join("relative_fast_gicp.txt"))?;
    let values = text
        .split_whitespace()
        .map(str::parse::<f64>)
        .collect::<Result<Vec<f64>, _>>()?;
    if values.len() != 16 {
        return Err(anyhow!(
            "relative_fast_gicp.txt: {} numbers, 16 expected",
            values.len()
        ));
    }
    let matrix = Matrix4::from_row_slice(&values);
    let rotation = Rotation3::from_matrix(&matrix.fixed_view::<3, 3>(0, 0).into_owned());
    let truth = Pose::from_parts(
        Translation3::new(matrix[(0, 3)], matrix[(1, 3)], matrix[(2, 3)]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    );
    Ok((read("251370668.pcd")?, read("251371071.pcd")?, truth))
}

fn success_rate(entries: &[&SweepEntry]) -> f64 {
    100.0 * entries.iter().filter(|e| e.success).count() as f64 / entries.len().max(1) as f64
}

/// What the sweep produced.
pub struct SweepOutcome {
    pub entries: Vec<SweepEntry>,
    /// The per-yaw success table and the plot, as Markdown.
    pub markdown: String,
}

/// Runs the sweep, pushes one summary row per method into `report`, writes `yaw_sweep.json` and
/// `success_vs_yaw.png` into `out`.
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
    let (target, source, reference) = read_real_pair()?;
    let steps = (360.0 / settings.yaw_step_deg).round().max(1.0) as usize;
    let yaws: Vec<f64> = (0..steps).map(|s| s as f64 * settings.yaw_step_deg).collect();
    let directions = settings.directions.max(1);
    let mut entries: Vec<SweepEntry> = Vec::new();
    for &yaw_deg in &yaws {
        for d in 0..directions {
            let direction_deg = 360.0 * d as f64 / directions as f64;
            let direction = direction_deg.to_radians();
            let motion = Pose::new(
                Vector3::new(
                    settings.offset_m * direction.cos(),
                    settings.offset_m * direction.sin(),
                    0.0,
                ),
                Vector3::z() * yaw_deg.to_radians(),
            );
            let moved = target.view().transformed(&motion);
            let truth = motion * reference;
            for method in &settings.methods {
                let outcome = methods.run(method, &moved, &source, &Pose::identity())?;
                let (translation_error_m, rotation_error_deg, success) =
                    pose_errors(&outcome.estimate, &truth);
                entries.push(SweepEntry {
                    yaw_deg,
                    direction_deg,
                    method: method.clone(),
                    translation_error_m,
                    rotation_error_deg,
                    success,
                    valid: outcome.valid,
                    time_ms: outcome.time_ms,
                    cpu_ms: outcome.cpu_ms,
                });
            }
        }
        eprintln!("yaw {yaw_deg:>5.1}° done");
    }
    let mut table = format!(
        "\n## Real pair: success rate [%] per yaw ({directions} offset directions of {} m each)\n\n| yaw [°] |",
        settings.offset_m
    );
    for method in &settings.methods {
        table.push_str(&format!(" {method} |"));
    }
    table.push_str(&format!("\n|---|{}\n", "---|".repeat(settings.methods.len())));
    for &yaw_deg in &yaws {
        table.push_str(&format!("| {yaw_deg:.0} |"));
        for method in &settings.methods {
            let at: Vec<&SweepEntry> = entries
                .iter()
                .filter(|e| &e.method == method && e.yaw_deg == yaw_deg)
                .collect();
            table.push_str(&format!(" {:.0} |", success_rate(&at)));
        }
        table.push('\n');
    }
    let mut series = Vec::new();
    for method in &settings.methods {
        let mine: Vec<&SweepEntry> = entries.iter().filter(|e| &e.method == method).collect();
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
            data: "real pair, yaw sweep".into(),
            method: method.clone(),
            pairs: mine.len(),
            success_rate_percent: success_rate(&mine),
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
    std::fs::create_dir_all(out)?;
    std::fs::write(
        out.join("yaw_sweep.json"),
        serde_json::to_string_pretty(&entries)?,
    )?;
    let plot = line_plot(
        &out.join("success_vs_yaw.png"),
        &format!(
            "Success rate vs yaw (real HDL-32E pair, {} m offset)",
            settings.offset_m
        ),
        "yaw [deg]",
        "success rate [%]",
        series,
        &PlotOptions::default(),
    )?;
    table.push_str(&format!("\n{}\n", plot.markdown()));
    Ok(SweepOutcome {
        entries,
        markdown: table,
    })
}
