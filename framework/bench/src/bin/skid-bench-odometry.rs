//! `cargo xtask bench odometry`: the `kiss_icp` odometry (KISS-ICP, Vizzo et al., RA-L 2023) with its
//! reference parameters on (a) the 16 real KITTI 00 frames of the shared data and (b) a simulated 64-beam
//! (HDL-64E) sequence of `--frames` scans in each world of `skid-sim`.
//!
//! Per row: milliseconds per frame (median, p90; `register` only, scan generation excluded), frames per
//! second, the process's peak resident memory so far, ATE after SE(3) alignment and end-point drift as a
//! percentage of the path length. For comparison, the reference KISS-ICP (C++ core) took about 100-136 ms
//! per frame on ~113k-point 64-beam scans on a busy single core of this kind of machine.

use anyhow::{Context, Result};
use clap::Parser;
use serde::Serialize;
use skid_bench::{BenchArgs, Report, Timing};
use skid_core::slots::Odometry;
use skid_core::{PluginContext, RawPoint, Scan};
use skid_io::{CloudReadOptions, kitti, trajectory};
use skid_odometry_kiss::{KissIcpConfig, KissIcpOdometry, trajectory_errors};
use skid_sim::{SimConfig, SimSource};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: BenchArgs,
    /// Threads of the odometry's pool.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Simulated scans per world (at least 500 for the reported figures).
    #[arg(long, default_value_t = 500)]
    frames: u32,
    /// Simulated worlds, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "urban,planetary,cave")]
    worlds: Vec<String>,
    /// Cruise speed of the simulated robot.
    #[arg(long, default_value_t = 2.0)]
    speed_mps: f64,
}

#[derive(Serialize)]
struct Row {
    sequence: String,
    frames: usize,
    points_per_scan: usize,
    threads: usize,
    median_ms: f64,
    p90_ms: f64,
    fps: f64,
    peak_rss_mb: f64,
    path_m: f64,
    ate_m: f64,
    drift_percent: f64,
}

/// Peak resident set size of this process so far (Linux `VmHWM`), in MB; 0 where unavailable.
fn peak_rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|line| line.strip_prefix("VmHWM:"))
        .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

/// Runs a fresh odometry over `scans` (streamed: a 500-scan 64-beam sequence would not fit in memory)
/// and summarises it against their ground truth.
fn run(name: &str, scans: impl Iterator<Item = Scan>, threads: usize) -> Result<Row> {
    let context = PluginContext {
        threads,
        ..PluginContext::default()
    };
    let mut odometry = KissIcpOdometry::new(KissIcpConfig::default(), &context)?;
    let (mut estimate, mut truth, mut times_ms, mut points) = (Vec::new(), Vec::new(), Vec::new(), 0usize);
    for scan in scans {
        let started = std::time::Instant::now();
        let update = odometry
            .register(&scan)
            .with_context(|| format!("{name}: scan {}", scan.sequence))?;
        times_ms.push(started.elapsed().as_secs_f64() * 1e3);
        estimate.push(update.world_from_sensor);
        truth.push(
            scan.ground_truth_world_from_sensor
                .context("a scan without ground truth")?,
        );
        points += scan.points.len();
    }
    let timing = Timing::from_ms(&times_ms);
    let errors = trajectory_errors(&estimate, &truth).context("trajectory errors")?;
    let row = Row {
        sequence: name.to_owned(),
        frames: estimate.len(),
        points_per_scan: points / estimate.len().max(1),
        threads,
        median_ms: timing.median_ms,
        p90_ms: timing.p90_ms,
        fps: if timing.mean_ms > 0.0 {
            1e3 / timing.mean_ms
        } else {
            0.0
        },
        peak_rss_mb: peak_rss_mb(),
        path_m: errors.path_length_m,
        ate_m: errors.ate_rmse_m,
        drift_percent: errors.drift_percent,
    };
    eprintln!(
        "{name}: {:.1} ms median, {:.1} ms p90, ATE {:.3} m, drift {:.2}% over {:.1} m",
        row.median_ms, row.p90_ms, row.ate_m, row.drift_percent, row.path_m
    );
    Ok(row)
}

fn kitti_scans() -> Result<Vec<Scan>> {
    let folder = skid_io::data_dir().join("kitti_00_lidar_frames_0000_0015");
    let truth = trajectory::read_kitti_poses(folder.join("poses_velodyne.txt"))?;
    let times_s = kitti::read_kitti_times(folder.join("times.txt"))?;
    let mut scans = Vec::new();
    for (index, stamp_s) in times_s.iter().enumerate().take(truth.len()) {
        let cloud = kitti::read_kitti_bin(
            folder.join(format!("velodyne/{index:06}.bin")),
            CloudReadOptions::default(),
        )?;
        scans.push(Scan {
            sequence: index as u32,
            stamp_nanos: (stamp_s * 1e9).round() as u64,
            points: cloud
                .points
                .iter()
                .map(|p| RawPoint::new(p.x, p.y, p.z, p.intensity, 0.0, RawPoint::UNKNOWN_RING))
                .collect(),
            ground_truth_world_from_sensor: Some(truth[index]),
            ..Scan::default()
        });
    }
    Ok(scans)
}

fn main() -> Result<()> {
    let args = Args::parse();
    let mut report = Report::new("odometry");
    let scans = kitti_scans().context("reading the KITTI frames (set SKID_DATA_DIR)")?;
    report.push(&run(
        "kitti-00 frames 0-15 (real)",
        scans.into_iter(),
        args.threads,
    )?)?;
    for world in &args.worlds {
        let config = SimConfig {
            world: world.clone(),
            sensor: "hdl64e".to_owned(),
            robots: 1,
            frames: args.frames,
            speed_mps: args.speed_mps,
            imu: false,
            ..SimConfig::default()
        };
        let source = SimSource::new(
            &config,
            0,
            std::thread::available_parallelism().map_or(1, |n| n.get()),
        )?;
        report.push(&run(
            &format!("sim {world} hdl64e {} m/s", args.speed_mps),
            source,
            args.threads,
        )?)?;
    }
    report.write(&args.common.out)
}
