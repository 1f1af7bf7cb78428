//! `skid sim export --format ros1|mcap`: each simulated robot recorded as a bag on the topics a real
//! robot would publish (`/points` PointCloud2 with per-point times, `/imu`, `/ground_truth` Odometry in
//! the fleet's shared world frame), so ROS tools, `rosbags` and SKiD's own `bag` source replay it.

use std::path::Path;

use anyhow::{Context, Result};
use skid_bag::write::{BagFormat, RobotBagWriter};
use skid_sim::{SimConfig, SimSource};

/// Writes `robotN.bag` (ROS 1) or `robotN/` (ROS 2 MCAP) for every robot into `out`; one JSON line per
/// robot naming the bag as it will be under `final_out` (where `out` is renamed once complete).
pub fn export_fleet_bags(
    config: &SimConfig,
    format: BagFormat,
    out: &Path,
    final_out: &Path,
    threads: usize,
) -> Result<()> {
    for robot in 0..config.robots {
        let path = match format {
            BagFormat::Ros1 => out.join(format!("robot{robot}.bag")),
            BagFormat::Mcap => out.join(format!("robot{robot}")),
        };
        let mut source = SimSource::new(config, robot, threads)?;
        let mut writer = RobotBagWriter::create(&path, format)?;
        let (mut scans, mut points) = (0usize, 0usize);
        for scan in source.by_ref() {
            for sample in &scan.imu {
                writer.write_imu(sample)?;
            }
            writer.write_scan(scan.stamp_nanos, &scan.points)?;
            if let Some(pose) = scan.ground_truth_world_from_sensor {
                let q = pose.rotation.quaternion();
                let t = pose.translation.vector;
                writer.write_ground_truth(scan.stamp_nanos, [t.x, t.y, t.z], [q.i, q.j, q.k, q.w])?;
            }
            scans += 1;
            points += scan.points.len();
        }
        let written = writer
            .finish()
            .with_context(|| format!("finishing {}", path.display()))?;
        let shown = written
            .strip_prefix(out)
            .map_or_else(|_| written.clone(), |relative| final_out.join(relative));
        println!(
            "{}",
            serde_json::json!({ "robot": robot, "bag": shown.display().to_string(), "scans": scans, "points": points })
        );
    }
    Ok(())
}
