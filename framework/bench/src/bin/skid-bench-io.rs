//! `cargo xtask bench io`: read and write throughput of the file formats on the real shared data
//! (KITTI 00 frames 0-15, the fast_gicp PCD pair, every g2o benchmark graph), and bag decoding of the shared
//! KITTI 00 ROS 1 and MCAP bags beside `rosbags` + numpy measured in the same run.

use anyhow::{Context, Result};
use clap::Parser;
use serde::Serialize;
use skid_bench::stats::time_ms;
use skid_bench::{BenchArgs, Report, Timing};
use skid_io::{CloudReadOptions, g2o, kitti, pcd, ply};

#[derive(Serialize)]
struct Row {
    format: String,
    operation: String,
    files: usize,
    points_or_lines: usize,
    median_ms: f64,
    p90_ms: f64,
    mpoints_per_s: f64,
}

fn row(format: &str, operation: &str, counts: &[usize], timings_ms: &[f64]) -> Row {
    let timing = Timing::from_ms(timings_ms);
    let total: usize = counts.iter().sum();
    let total_ms: f64 = timings_ms.iter().sum();
    Row {
        format: format.to_owned(),
        operation: operation.to_owned(),
        files: counts.len(),
        points_or_lines: total,
        median_ms: timing.median_ms,
        p90_ms: timing.p90_ms,
        mpoints_per_s: if total_ms > 0.0 {
            total as f64 / total_ms / 1e3
        } else {
            0.0
        },
    }
}

fn main() -> Result<()> {
    let args = BenchArgs::parse();
    let data = skid_io::data_dir();
    let mut report = Report::new("io");
    let scratch = tempfile::tempdir()?;

    let mut scans: Vec<_> = std::fs::read_dir(data.join("kitti_00_lidar_frames_0000_0015/velodyne"))
        .with_context(|| {
            format!(
                "KITTI frames under {} (set {})",
                data.display(),
                skid_io::DATA_DIR_VAR
            )
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    scans.sort();
    let (mut counts, mut read_ms, mut pcd_w, mut pcd_r, mut ply_w, mut ply_r) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for scan in &scans {
        let (cloud, ms) = time_ms(|| kitti::read_kitti_bin(scan, CloudReadOptions::default()));
        let cloud = cloud?;
        counts.push(cloud.points.len());
        read_ms.push(ms);
        let pcd_path = scratch.path().join("scan.pcd");
        let options = pcd::PcdWriteOptions {
            data: pcd::PcdData::BinaryCompressed,
            ..Default::default()
        };
        pcd_w.push(time_ms(|| pcd::write_pcd(&pcd_path, &cloud.points, &options)).1);
        pcd_r.push(time_ms(|| pcd::read_pcd(&pcd_path, CloudReadOptions::default())).1);
        let ply_path = scratch.path().join("scan.ply");
        ply_w
            .push(time_ms(|| ply::write_ply(&ply_path, &cloud.points, ply::PlyFormat::BinaryLittleEndian)).1);
        ply_r.push(time_ms(|| ply::read_ply(&ply_path, CloudReadOptions::default())).1);
    }
    report.push(&row("kitti .bin", "read", &counts, &read_ms))?;
    report.push(&row("pcd binary_compressed", "write", &counts, &pcd_w))?;
    report.push(&row("pcd binary_compressed", "read", &counts, &pcd_r))?;
    report.push(&row("ply binary_le", "write", &counts, &ply_w))?;
    report.push(&row("ply binary_le", "read", &counts, &ply_r))?;

    let graphs = skid_bench::files::files_with_extension(&data.join("pose_graph_benchmarks"), "g2o")?;
    let (mut lines, mut g2o_ms) = (vec![], vec![]);
    for graph in &graphs {
        let text_lines = std::fs::read_to_string(graph)?.lines().count();
        let (parsed, ms) = time_ms(|| g2o::read_g2o(graph, &g2o::G2oReadOptions::default()));
        parsed.with_context(|| format!("reading {}", graph.display()))?;
        lines.push(text_lines);
        g2o_ms.push(ms);
    }
    report.push(&row("g2o", "read", &lines, &g2o_ms))?;
    report.write(&args.out)?;

    // Bags: every PointCloud2 decoded into SKiD's points on one thread, beside rosbags + numpy.
    let mut bags = Report::new("io/bags");
    for (label, relative) in [
        (
            "ROS 1, LZ4 chunks",
            "kitti_00_rosbags/kitti00_velodyne_ros1-lz4.bag",
        ),
        ("ROS 2, MCAP", "kitti_00_rosbags/kitti00_velodyne_mcap"),
    ] {
        bags.push(&skid_bench::bag_io::measure(
            label,
            &data.join(relative),
            "/velodyne_points",
            5,
            5,
        )?)?;
    }
    bags.write(&args.out.join("bags"))
}
