//! SOLiD extraction (`describe`, voxel downsampling included) on the real KITTI 00 scans of the shared
//! data, one thread; the goal is at most 1 ms per scan of 105-129k points. SOLiD has no
//! packaged peer to run beside it.

use anyhow::{Context, Result};
use skid_bench::stats::{median, time_ms};
use skid_core::CloudView;
use skid_core::slots::Descriptor;
use skid_descriptor_solid::{SolidConfig, SolidDescriptor};
use skid_io::{CloudReadOptions, kitti};

use crate::Row;

/// One row: the median over scans of each scan's median extraction time.
pub fn row(repeats: usize) -> Result<Row> {
    let folder = skid_io::data_path("kitti_00_lidar_frames_0000_0015/velodyne")?;
    let mut files: Vec<_> = std::fs::read_dir(&folder)
        .with_context(|| format!("listing {}", folder.display()))?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.extension().is_some_and(|e| e == "bin"))
        .collect();
    files.sort();
    let mut descriptor = SolidDescriptor::new(SolidConfig::default())?;
    let (mut per_scan_ms, mut points) = (Vec::new(), Vec::new());
    for file in &files {
        let cloud = kitti::read_kitti_bin(file, CloudReadOptions::VALID_ONLY)?.points;
        descriptor.describe(CloudView::new(&cloud))?;
        let mut runs: Vec<f64> = (0..repeats)
            .map(|_| {
                let (described, ms) = time_ms(|| descriptor.describe(CloudView::new(&cloud)));
                described.map(|_| ms)
            })
            .collect::<Result<_, _>>()?;
        per_scan_ms.push(median(&mut runs));
        points.push(cloud.len());
    }
    let (fewest, most) = (points.iter().min().copied(), points.iter().max().copied());
    Ok(Row {
        stage: "SOLiD extraction, default config".into(),
        input: format!(
            "{} KITTI 00 scans, {}-{} points",
            files.len(),
            fewest.unwrap_or(0),
            most.unwrap_or(0)
        ),
        skid: format!("{:.3} ms", median(&mut per_scan_ms)),
        peer: "– (no packaged peer)".into(),
        ratio: None,
        goal: "≤ 1 ms".into(),
        detail: format!(
            "median over scans of each scan's median of {repeats}; slowest scan {:.3} ms",
            per_scan_ms.iter().copied().fold(0.0, f64::max)
        ),
    })
}
