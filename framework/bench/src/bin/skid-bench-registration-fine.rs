//! `cargo xtask bench registration-fine`: the `gicp` fine-registration plugin on the real HDL-32E scan pair
//! (`lidar_scan_pair_fast_gicp`), every variant, 1 and 2 threads, small_gicp's settings (0.25 m
//! downsampling, 1.0 m maximum correspondence distance, 10 neighbours), from the identity.
//!
//! Per row: end-to-end time (raw points to pose: both `prepare` calls and `refine`), preprocessing time,
//! align-only time (`refine` on prepared clouds), each the median of `--repeats` runs; linearisations,
//! inliers, the pose, and its distance to small_gicp's own result on this machine
//! (`T_target_source_small_gicp_computed.txt`: ~68 ms end to end and ~16 ms align-only on one thread,
//! 3 linearisations, 5,803 inliers).

use anyhow::{Context, Result};
use clap::Parser;
use nalgebra::{Matrix4, Rotation3, Translation3, UnitQuaternion};
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
                let alignment = registration.refine(&prepared_target, &prepared_source, &Pose::identity())?;
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
            let pose = alignment.target_from_source;
            let (roll, pitch, yaw) = pose.rotation.euler_angles();
            let delta = small_gicp.inverse() * pose;
            let row = Row {
                variant: variant.key().to_owned(),
                threads,
                end_to_end_ms: Timing::from_ms(&end_to_end).median_ms,
                preprocess_ms: Timing::from_ms(&preprocess).median_ms,
                align_ms: Timing::from_ms(&align).median_ms,
                iterations: alignment.iterations,
                inliers: alignment.inlier_count,
                source_points: prepared_source.cloud.len(),
                converged: alignment.converged,
                tx_m: pose.translation.x,
                ty_m: pose.translation.y,
                tz_m: pose.translation.z,
                roll_deg: roll.to_degrees(),
                pitch_deg: pitch.to_degrees(),
                yaw_deg: yaw.to_degrees(),
                vs_small_gicp_mm: delta.translation.vector.norm() * 1e3,
                vs_small_gicp_deg: delta.rotation.angle().to_degrees(),
            };
            report.push(&row)?;
        }
    }
    report.write(&args.common.out)
}
