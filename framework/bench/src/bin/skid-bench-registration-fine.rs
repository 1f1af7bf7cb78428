//! `cargo xtask bench registration-fine`: the `gicp` fine-registration plugin on the real HDL-32E scan pair
//! (`lidar_scan_pair_fast_gicp`), every variant, 1 and 2 threads, small_gicp's settings (0.25 m
//! downsampling, 1.0 m maximum correspondence distance, 10 neighbours), from the identity.
//!
//! Per row: end-to-end time (raw points to pose: both `prepare` calls and `refine`), preprocessing time,
//! align-only time (`refine` on prepared clouds), each the median of `--repeats` runs; linearisations,
//! inliers, the pose, and its distance to small_gicp's own result on this machine
//! (`T_target_source_small_gicp_computed.txt`: ~68 ms end to end and ~16 ms align-only on one thread,
//! 3 linearisations, 5,803 inliers). Every variant runs at its defaults, which include the coarse-to-fine
//! stage (small_gicp runs the fine stage alone); `coarse_iterations` counts the coarse stage's
//! linearisations, which `iterations` includes. `recovered_1m_10deg` counts, of six guesses 1 m and 10°
//! off the variant's own result, those that converge back to within 5 cm and 0.5° of it.

use anyhow::{Context, Result};
use clap::Parser;
use nalgebra::{Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;
use skid_bench::stats::time_ms;
use skid_bench::{BenchArgs, Report, Timing};
use skid_core::slots::FineRegistration;
use skid_core::{CloudView, PluginContext, Pose};
use skid_fine_gicp::{GicpConfig, GicpRegistration, Variant};
use skid_io::{CloudReadOptions, pcd};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: BenchArgs,
    /// Thread counts to run, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// Timed repetitions per measurement (the median is reported).
    #[arg(long, default_value_t = 10)]
    repeats: usize,
}

#[derive(Serialize)]
struct Row {
    variant: String,
    threads: usize,
    end_to_end_ms: f64,
    preprocess_ms: f64,
    align_ms: f64,
    iterations: usize,
    coarse_iterations: usize,
    inliers: usize,
    source_points: usize,
    converged: bool,
    tx_m: f64,
    ty_m: f64,
    tz_m: f64,
    roll_deg: f64,
    pitch_deg: f64,
    yaw_deg: f64,
    vs_small_gicp_mm: f64,
    vs_small_gicp_deg: f64,
    recovered_1m_10deg: String,
}

/// Six guesses 1 m and 10° away, in several directions and about several axes.
fn perturbations() -> Vec<Pose> {
    let directions = [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(-0.6, 0.8, 0.0),
        Vector3::new(0.0, -0.7, 0.7),
    ];
    let axes = [
        Vector3::new(0.1, -0.2, 1.0),
        Vector3::new(0.0, 0.0, -1.0),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.3, 1.0, 0.2),
    ];
    (0..6)
        .map(|i| {
            Pose::new(
                directions[i % 3],
                axes[(i % 3 + i / 3) % 4].normalize() * 10f64.to_radians(),
            )
        })
        .collect()
}

fn read_pose(path: &std::path::Path) -> Result<Pose> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let values = text
        .split_whitespace()
        .map(str::parse::<f64>)
        .collect::<Result<Vec<_>, _>>()?;
    anyhow::ensure!(values.len() == 16, "{}: expected a 4x4 matrix", path.display());
    let m = Matrix4::from_row_slice(&values);
    let rotation = Rotation3::from_matrix(&m.fixed_view::<3, 3>(0, 0).into_owned());
    Ok(Pose::from_parts(
        Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

fn main() -> Result<()> {
    let args = Args::parse();
    let folder = skid_io::data_path("lidar_scan_pair_fast_gicp")?;
    let target = pcd::read_pcd(folder.join("251370668.pcd"), CloudReadOptions::VALID_ONLY)?.points;
    let source = pcd::read_pcd(folder.join("251371071.pcd"), CloudReadOptions::VALID_ONLY)?.points;
    let small_gicp = read_pose(&folder.join("T_target_source_small_gicp_computed.txt"))?;
    let repeats = args.repeats.max(1);
    let mut report = Report::new("registration-fine");
    for &threads in &args.threads {
        for variant in Variant::ALL {
            let context = PluginContext {
                threads: threads.max(1),
                ..PluginContext::default()
            };
            let mut registration = GicpRegistration::new(GicpConfig::with_variant(variant), &context)?;
            let (mut end_to_end, mut preprocess, mut align) = (Vec::new(), Vec::new(), Vec::new());
            let mut last = None;
            // One untimed warm-up, then the timed runs.
            for run in 0..=repeats {
                let started = std::time::Instant::now();
                let prepared_target = registration.prepare(CloudView::new(&target))?;
                let prepared_source = registration.prepare(CloudView::new(&source))?;
                let prep_ms = started.elapsed().as_secs_f64() * 1e3;
                let alignment =
                    registration.refine_report(&prepared_target, &prepared_source, &Pose::identity())?;
                let total_ms = started.elapsed().as_secs_f64() * 1e3;
                if run > 0 {
                    end_to_end.push(total_ms);
                    preprocess.push(prep_ms);
                }
                last = Some((prepared_target, prepared_source, alignment));
            }
            let Some((prepared_target, prepared_source, alignment)) = last else {
                continue;
            };
            for _ in 0..repeats {
                let (result, ms) =
                    time_ms(|| registration.refine(&prepared_target, &prepared_source, &Pose::identity()));
                result?;
                align.push(ms);
            }
            let pose = alignment.alignment.target_from_source;
            let mut recovered = 0;
            for perturbation in perturbations() {
                let result =
                    registration.refine(&prepared_target, &prepared_source, &(pose * perturbation))?;
                let delta = pose.inverse() * result.target_from_source;
                if result.converged
                    && delta.translation.vector.norm() < 0.05
                    && delta.rotation.angle().to_degrees() < 0.5
                {
                    recovered += 1;
                }
            }
            let (roll, pitch, yaw) = pose.rotation.euler_angles();
            let delta = small_gicp.inverse() * pose;
            let row = Row {
                variant: variant.key().to_owned(),
                threads,
                end_to_end_ms: Timing::from_ms(&end_to_end).median_ms,
                preprocess_ms: Timing::from_ms(&preprocess).median_ms,
                align_ms: Timing::from_ms(&align).median_ms,
                iterations: alignment.alignment.iterations,
                coarse_iterations: alignment.coarse_iterations,
                inliers: alignment.alignment.inlier_count,
                source_points: prepared_source.cloud.len(),
                converged: alignment.alignment.converged,
                tx_m: pose.translation.x,
                ty_m: pose.translation.y,
                tz_m: pose.translation.z,
                roll_deg: roll.to_degrees(),
                pitch_deg: pitch.to_degrees(),
                yaw_deg: yaw.to_degrees(),
                vs_small_gicp_mm: delta.translation.vector.norm() * 1e3,
                vs_small_gicp_deg: delta.rotation.angle().to_degrees(),
                recovered_1m_10deg: format!("{recovered}/6"),
            };
            report.push(&row)?;
        }
    }
    report.write(&args.common.out)
}
