//! GICP on the real HDL-32E pair (`lidar_scan_pair_fast_gicp`), one thread, end to end from raw points
//! (both clouds prepared, then aligned from the identity): SKiD's `gicp` at its defaults (which include
//! the coarse-to-fine stage) against small_gicp's `align` with its settings for this pair. The issue's
//! goal is at most 0.8× small_gicp's time.

use std::ffi::{OsStr, OsString};

use anyhow::Result;
use serde::Deserialize;
use skid_core::slots::FineRegistration;
use skid_core::{CloudView, PluginContext, Pose};
use skid_fine_gicp::{GicpConfig, GicpRegistration, PrepareTimings};
use skid_io::{CloudReadOptions, pcd};

use skid_bench::python_peers;
use skid_bench::stats::median;

use crate::Row;

#[derive(Deserialize)]
struct PeerRuns {
    end_to_end_ms: Vec<f64>,
    preprocess_ms: Vec<f64>,
    align_ms: Vec<f64>,
    iterations: usize,
    inliers: usize,
}

/// One row: end-to-end medians, with the preparation / alignment split in the detail.
pub fn row(python: Option<&OsStr>, repeats: usize) -> Result<Row> {
    let folder = skid_io::data_path("lidar_scan_pair_fast_gicp")?;
    let target = pcd::read_pcd(folder.join("251370668.pcd"), CloudReadOptions::VALID_ONLY)?.points;
    let source = pcd::read_pcd(folder.join("251371071.pcd"), CloudReadOptions::VALID_ONLY)?.points;
    let files = tempfile::tempdir()?;
    let (target_bin, source_bin) = (files.path().join("target.bin"), files.path().join("source.bin"));
    skid_io::kitti::write_kitti_bin(&target_bin, &target)?;
    skid_io::kitti::write_kitti_bin(&source_bin, &source)?;
    let context = PluginContext {
        threads: 1,
        ..PluginContext::default()
    };
    let mut registration = GicpRegistration::new(GicpConfig::default(), &context)?;
    let (mut skid_total, mut skid_prepare, mut skid_align) = (Vec::new(), Vec::new(), Vec::new());
    let (mut iterations, mut inliers) = (0, 0);
    let mut source_stages = Vec::new();
    let mut peer_runs: Option<PeerRuns> = None;
    for round in 0..3 {
        for run in 0..=repeats {
            let started = std::time::Instant::now();
            let prepared_target = registration.prepare(CloudView::new(&target))?;
            let prepared_source = registration.prepare(CloudView::new(&source))?;
            let prepared_ms = started.elapsed().as_secs_f64() * 1e3;
            let report = registration.refine_report(&prepared_target, &prepared_source, &Pose::identity())?;
            let total_ms = started.elapsed().as_secs_f64() * 1e3;
            // The first run of the first round warms caches.
            if round > 0 || run > 0 {
                skid_total.push(total_ms);
                skid_prepare.push(prepared_ms);
                skid_align.push(total_ms - prepared_ms);
            }
            (iterations, inliers) = (report.alignment.iterations, report.alignment.inlier_count);
            if let Some(timings) = skid_fine_gicp::prepared_data(&prepared_source).map(|d| d.timings()) {
                source_stages.push(timings);
            }
        }
        if let Some(python) = python {
            let repeats = OsString::from(repeats.to_string());
            let args = [target_bin.as_os_str(), source_bin.as_os_str(), &repeats];
            let runs: PeerRuns = python_peers::run(python, "gicp", &args)?;
            match &mut peer_runs {
                Some(all) => {
                    all.end_to_end_ms.extend(runs.end_to_end_ms);
                    all.preprocess_ms.extend(runs.preprocess_ms);
                    all.align_ms.extend(runs.align_ms);
                }
                None => peer_runs = Some(runs),
            }
        }
    }
    let skid = median(&mut skid_total);
    let peer = peer_runs.as_mut().map(|runs| {
        (
            median(&mut runs.end_to_end_ms),
            median(&mut runs.preprocess_ms),
            median(&mut runs.align_ms),
            runs.iterations,
            runs.inliers,
        )
    });
    Ok(Row {
        stage: "GICP end to end, 1 thread".into(),
        input: format!("real HDL-32E pair, {} and {} points", target.len(), source.len()),
        skid: format!("{skid:.1} ms"),
        peer: peer.map_or("–".into(), |(ms, ..)| format!("small_gicp {ms:.1} ms")),
        ratio: peer.map(|(ms, ..)| skid / ms),
        goal: "≤ 0.8×".into(),
        detail: format!(
            "SKiD prepare {:.1} (source cloud: {}) + align {:.1} ms, {iterations} linearisations, {inliers} inliers{}",
            median(&mut skid_prepare),
            stage_medians(&source_stages),
            median(&mut skid_align),
            peer.map_or(String::new(), |(_, prepare, align, it, inl)| format!(
                "; small_gicp preprocess {prepare:.1} + align {align:.1} ms, {it} iterations, {inl} inliers"
            ))
        ),
    })
}

/// The median of each preparation stage over the runs, as text.
fn stage_medians(runs: &[PrepareTimings]) -> String {
    let stage = |pick: fn(&PrepareTimings) -> f64| median(&mut runs.iter().map(pick).collect::<Vec<_>>());
    format!(
        "downsample {:.1}, tree {:.1}, covariances {:.1}, coarse level {:.1} ms",
        stage(|t| t.downsample_ms),
        stage(|t| t.tree_ms),
        stage(|t| t.covariance_ms),
        stage(|t| t.coarse_ms)
    )
}
