//! Writes simulated robots as KITTI odometry folders, so other tools can run on the same data.
//!
//! Layout of one robot's folder:
//! - `velodyne/NNNNNN.bin`: each scan in the LiDAR frame as little-endian f32 records (x, y, z,
//!   intensity), 16 bytes per point, motion-distorted exactly as the sensor saw it;
//! - `times.txt`: scan start times in seconds;
//! - `poses.txt`: 12 numbers per line, the row-major 3×4 matrix of `first_from_current` in the LiDAR
//!   frame (KITTI's convention of poses relative to the first scan, so line 1 is the identity);
//! - `calib.txt`: `P0`–`P3` placeholders and `Tr` = identity, so readers that convert camera-frame poses
//!   with `Tr` get the LiDAR-frame poses unchanged;
//! - `world_from_first.txt`: the first scan's pose in the shared simulation world frame (same 12-number
//!   form), which puts all robots of a fleet in one frame for multi-robot evaluation;
//! - `imu.txt`: `stamp_s ax ay az gx gy gz` per sample (sensor frame, m/s² and rad/s).

use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use skid_core::Pose;

use crate::SimError;
use crate::source::{SimConfig, SimSource};

/// What an export wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSummary {
    pub dir: PathBuf,
    pub scans: usize,
    pub points: usize,
}

fn pose_line(pose: &Pose) -> String {
    let m = pose.to_homogeneous();
    let mut line = String::new();
    for row in 0..3 {
        for col in 0..4 {
            let _ = write!(
                line,
                "{}{:.9e}",
                if row + col == 0 { "" } else { " " },
                m[(row, col)]
            );
        }
    }
    line
}

fn write_file(path: &Path, contents: &[u8]) -> Result<(), SimError> {
    fs::write(path, contents).map_err(|e| SimError::io(path, e))
}

/// Drains `source` into a KITTI folder at `dir` (created if missing).
pub fn export_kitti(dir: impl AsRef<Path>, source: &mut SimSource) -> Result<ExportSummary, SimError> {
    let dir = dir.as_ref();
    let velodyne = dir.join("velodyne");
    fs::create_dir_all(&velodyne).map_err(|e| SimError::io(&velodyne, e))?;
    let (mut times, mut poses, mut imu) = (String::new(), String::new(), String::new());
    let mut first: Option<Pose> = None;
    let (mut scans, mut points) = (0, 0);
    for scan in source.by_ref() {
        let path = velodyne.join(format!("{:06}.bin", scan.sequence));
        let mut bytes = Vec::with_capacity(scan.points.len() * 16);
        for p in &scan.points {
            for value in [p.x, p.y, p.z, p.intensity] {
                bytes.extend_from_slice(&value.to_le_bytes());
            }
        }
        write_file(&path, &bytes)?;
        let pose = scan.ground_truth_world_from_sensor.unwrap_or_else(Pose::identity);
        let first_pose = *first.get_or_insert(pose);
        let _ = writeln!(times, "{:.6e}", scan.stamp_nanos as f64 * 1e-9);
        let _ = writeln!(poses, "{}", pose_line(&(first_pose.inverse() * pose)));
        for sample in &scan.imu {
            let [ax, ay, az] = sample.accel_mps2;
            let [gx, gy, gz] = sample.gyro_radps;
            let _ = writeln!(
                imu,
                "{:.9} {ax:.9e} {ay:.9e} {az:.9e} {gx:.9e} {gy:.9e} {gz:.9e}",
                sample.stamp_nanos as f64 * 1e-9
            );
        }
        scans += 1;
        points += scan.points.len();
    }
    write_file(&dir.join("times.txt"), times.as_bytes())?;
    write_file(&dir.join("poses.txt"), poses.as_bytes())?;
    write_file(&dir.join("imu.txt"), imu.as_bytes())?;
    let identity = pose_line(&Pose::identity());
    let calib = format!("P0: {identity}\nP1: {identity}\nP2: {identity}\nP3: {identity}\nTr: {identity}\n");
    write_file(&dir.join("calib.txt"), calib.as_bytes())?;
    let world_from_first = format!("{}\n", pose_line(&first.unwrap_or_else(Pose::identity)));
    write_file(&dir.join("world_from_first.txt"), world_from_first.as_bytes())?;
    Ok(ExportSummary {
        dir: dir.to_owned(),
        scans,
        points,
    })
}

/// Exports every robot of the fleet in `config` into `dir/robotN/`, and writes `dir/README.txt`
/// describing the run.
pub fn export_fleet_kitti(
    dir: impl AsRef<Path>,
    config: &SimConfig,
    threads: usize,
) -> Result<Vec<ExportSummary>, SimError> {
    let dir = dir.as_ref();
    config.validate()?;
    fs::create_dir_all(dir).map_err(|e| SimError::io(dir, e))?;
    let mut summaries = Vec::new();
    for robot in 0..config.robots {
        let mut source = SimSource::new(config, robot, threads)?;
        summaries.push(export_kitti(dir.join(format!("robot{robot}")), &mut source)?);
    }
    let mut readme = String::from(
        "SKiD simulator export (KITTI odometry layout per robot; see world_from_first.txt for the shared frame)\n",
    );
    let _ = writeln!(
        readme,
        "world = {}\nseed = {}\nsensor = {}\nrobots = {}",
        config.world, config.seed, config.sensor, config.robots
    );
    let path = dir.join("README.txt");
    fs::File::create(&path)
        .and_then(|mut f| f.write_all(readme.as_bytes()))
        .map_err(|e| SimError::io(&path, e))?;
    Ok(summaries)
}
