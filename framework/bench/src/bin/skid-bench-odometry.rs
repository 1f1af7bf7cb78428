//! `cargo xtask bench odometry`: the `lio` odometry (FAST-LIO2-style filter) beside `kiss_icp` (KISS-ICP,
//! Vizzo et al., RA-L 2023) and the reference KISS-ICP (Python package `kiss-icp`, C++ core, run by
//! `framework/bench/python/kiss_icp_run.py` with `$SKID_PYTHON` in the same run) on the same scans:
//! the 16 real KITTI 00 frames of the shared data (no IMU: `lio` runs LiDAR-only there), and simulated
//! sequences of `--frames` scans with the simulator's noisy 200 Hz IMU — planetary, cave and urban
//! ground robots at 2 m/s, a trotting quadruped, a base swinging its heading at up to 132°/s and a
//! handheld sensor.
//!
//! Per row: milliseconds per frame (median, p90; `register` only, scan generation excluded), ATE after
//! SE(3) alignment and end-point drift as a percentage of the path length.

use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, bail};
use clap::Parser;
use serde::Serialize;
use skid_bench::{BenchArgs, Report, Timing};
use skid_core::slots::Odometry;
use skid_core::{PluginContext, Pose, RawPoint, Scan};
use skid_io::{CloudReadOptions, kitti, trajectory};
use skid_odometry_kiss::{KissIcpConfig, KissIcpOdometry, trajectory_errors};
use skid_odometry_lio::{LioConfig, LioOdometry};
use skid_sim::{Profile, SimConfig, SimSource};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: BenchArgs,
    /// Threads of each odometry's pool.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Simulated scans per sequence.
    #[arg(long, default_value_t = 300)]
    frames: u32,
    /// Only the sequences whose name contains one of these (comma separated); all by default.
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
}

/// One simulated sequence.
struct Sequence {
    name: &'static str,
    world: &'static str,
    sensor: &'static str,
    profile: Profile,
    speed_mps: f64,
}

const SEQUENCES: [Sequence; 6] = [
    Sequence {
        name: "planetary 2 m/s",
        world: "planetary",
        sensor: "os1-64",
        profile: Profile::Ground,
        speed_mps: 2.0,
    },
    Sequence {
        name: "cave 2 m/s",
        world: "cave",
        sensor: "os1-64",
        profile: Profile::Ground,
        speed_mps: 2.0,
    },
    Sequence {
        name: "urban 2 m/s",
        world: "urban",
        sensor: "os1-64",
        profile: Profile::Ground,
        speed_mps: 2.0,
    },
    Sequence {
        name: "legged gait (planetary)",
        world: "planetary",
        sensor: "os1-32",
        profile: Profile::Legged,
        speed_mps: 1.0,
    },
    Sequence {
        name: "fast turns (urban)",
        world: "urban",
        sensor: "os1-64",
        profile: Profile::FastTurn,
        speed_mps: 1.5,
    },
    Sequence {
        name: "handheld (cave)",
        world: "cave",
        sensor: "os1-32",
        profile: Profile::Handheld,
        speed_mps: 1.4,
    },
];

#[derive(Serialize)]
struct Row {
    sequence: String,
    odometry: String,
    frames: usize,
    median_ms: f64,
    p90_ms: f64,
    path_m: f64,
    ate_m: f64,
    drift_percent: f64,
}

/// One odometry's estimate and timing over a sequence.
struct Track {
    name: &'static str,
    odometry: Box<dyn Odometry>,
    estimate: Vec<Pose>,
    times_ms: Vec<f64>,
}

fn row(sequence: &str, odometry: &str, estimate: &[Pose], truth: &[Pose], times_ms: &[f64]) -> Result<Row> {
    if estimate.len() != truth.len() {
        bail!(
            "{sequence}/{odometry}: {} poses for {} scans",
            estimate.len(),
            truth.len()
        );
    }
    let timing = Timing::from_ms(times_ms);
    let errors = trajectory_errors(estimate, truth).context("trajectory errors")?;
    let row = Row {
        sequence: sequence.to_owned(),
        odometry: odometry.to_owned(),
        frames: estimate.len(),
        median_ms: timing.median_ms,
        p90_ms: timing.p90_ms,
        path_m: errors.path_length_m,
        ate_m: errors.ate_rmse_m,
        drift_percent: errors.drift_percent,
    };
    eprintln!(
        "{sequence} / {odometry}: {:.1} ms median, ATE {:.3} m, drift {:.2}% over {:.1} m",
        row.median_ms, row.ate_m, row.drift_percent, row.path_m
    );
    Ok(row)
}

/// Writes a scan for the Python peer: float32 x, y, z, time offset per point.
fn write_xyzt(path: &Path, points: &[RawPoint]) -> Result<()> {
    let mut bytes = Vec::with_capacity(points.len() * 16);
    for point in points.iter().filter(|p| p.is_finite()) {
        for value in [point.x, point.y, point.z, point.time_offset_s] {
            bytes.extend_from_slice(&value.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

/// The reference KISS-ICP on the scans in `folder`, when `$SKID_PYTHON` is set.
fn python_kiss_icp(folder: &Path, threads: usize) -> Result<Option<(Vec<Pose>, Vec<f64>)>> {
    let Some(python) = std::env::var_os("SKID_PYTHON") else {
        eprintln!(
            "bench odometry: SKID_PYTHON is not set (cargo xtask bench sets it); the kiss-icp peer is skipped"
        );
        return Ok(None);
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/kiss_icp_run.py");
    let output = Command::new(python)
        .arg(script)
        .arg(folder)
        .arg("100")
        .arg(threads.to_string())
        .output()
        .context("running kiss_icp_run.py")?;
    if !output.status.success() {
        bail!(
            "kiss_icp_run.py failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let result: serde_json::Value =
        serde_json::from_slice(&output.stdout).context("kiss_icp_run.py output")?;
    let poses = result["poses"]
        .as_array()
        .context("poses")?
        .iter()
        .map(|row| {
            let v: Vec<f64> = row
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|x| x.as_f64())
                .collect();
            let matrix = nalgebra::Matrix4::from_row_slice(&v);
            let rotation = nalgebra::Rotation3::from_matrix(&matrix.fixed_view::<3, 3>(0, 0).into_owned());
            Pose::from_parts(
                nalgebra::Translation3::new(matrix[(0, 3)], matrix[(1, 3)], matrix[(2, 3)]),
                nalgebra::UnitQuaternion::from_rotation_matrix(&rotation),
            )
        })
        .collect();
    let times = result["ms"]
        .as_array()
        .context("ms")?
        .iter()
        .filter_map(|x| x.as_f64())
        .collect();
    Ok(Some((poses, times)))
}

/// Runs every track over `scans`, writing them for the peer into `peer_folder`.
fn run_tracks(
    sequence: &str,
    scans: impl Iterator<Item = Scan>,
    tracks: &mut [Track],
    peer_folder: &Path,
) -> Result<Vec<Pose>> {
    let mut truth = Vec::new();
    for scan in scans {
        for track in tracks.iter_mut() {
            let started = std::time::Instant::now();
            let update = track
                .odometry
                .register(&scan)
                .with_context(|| format!("{sequence} / {}: scan {}", track.name, scan.sequence))?;
            track.times_ms.push(started.elapsed().as_secs_f64() * 1e3);
            track.estimate.push(update.world_from_sensor);
        }
        write_xyzt(
            &peer_folder.join(format!("{:06}.xyzt", scan.sequence)),
            &scan.points,
        )?;
        truth.push(
            scan.ground_truth_world_from_sensor
                .context("a scan without ground truth")?,
        );
    }
    Ok(truth)
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
    let context = PluginContext {
        threads: args.threads,
        ..PluginContext::default()
    };
    let selected = |name: &str| args.only.is_empty() || args.only.iter().any(|o| name.contains(o.as_str()));
    let peer_root = args.common.out.join("peer-scans");
    let mut inputs: Vec<(String, Box<dyn Iterator<Item = Scan>>)> = Vec::new();
    if selected("kitti") {
        let scans = kitti_scans().context("reading the KITTI frames (set SKID_DATA_DIR)")?;
        inputs.push((
            "kitti-00 frames 0-15 (real, no IMU)".to_owned(),
            Box::new(scans.into_iter()),
        ));
    }
    for sequence in SEQUENCES.iter().filter(|s| selected(s.name)) {
        let config = SimConfig {
            world: sequence.world.to_owned(),
            sensor: sequence.sensor.to_owned(),
            profile: sequence.profile,
            speed_mps: sequence.speed_mps,
            robots: 1,
            frames: args.frames,
            ..SimConfig::default()
        };
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        inputs.push((
            format!("sim {}", sequence.name),
            Box::new(SimSource::new(&config, 0, threads)?),
        ));
    }
    for (name, scans) in inputs {
        let folder = peer_root.join(name.replace([' ', '/'], "_"));
        std::fs::create_dir_all(&folder).with_context(|| format!("creating {}", folder.display()))?;
        let mut tracks = vec![
            Track {
                name: "lio",
                odometry: Box::new(LioOdometry::new(LioConfig::default(), &context)?),
                estimate: Vec::new(),
                times_ms: Vec::new(),
            },
            Track {
                name: "kiss_icp",
                odometry: Box::new(KissIcpOdometry::new(KissIcpConfig::default(), &context)?),
                estimate: Vec::new(),
                times_ms: Vec::new(),
            },
        ];
        let truth = run_tracks(&name, scans, &mut tracks, &folder)?;
        for track in &tracks {
            report.push(&row(&name, track.name, &track.estimate, &truth, &track.times_ms)?)?;
        }
        if let Some((poses, times)) = python_kiss_icp(&folder, args.threads)? {
            report.push(&row(
                &name,
                "kiss-icp (Python, reference)",
                &poses,
                &truth,
                &times,
            )?)?;
        }
        // The raw scans are large (a 64-beam sequence is hundreds of MB): drop them once measured.
        std::fs::remove_dir_all(&folder).with_context(|| format!("removing {}", folder.display()))?;
    }
    report.write(&args.common.out)
}
