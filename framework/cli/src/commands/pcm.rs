//! `skid pcm DIR|FILE…`: pairwise consistency maximisation on a multi-robot pose graph given as per-robot
//! g2o files with GTSAM symbol keys (see `skid-pcm-sets`): prints the loops PCM accepts, with their ids
//! and keys, and the time it took; `--then gnc` optimises the odometry and the accepted loops with GNC
//! afterwards; `--json` prints one JSON line instead.

use std::path::PathBuf;

use anyhow::{Context, Result};
use skid_backend_pgo::{PgoOptions, PgoReport, RobustMode};
use skid_pcm_sets::key_name;

/// Optimises the set's odometry and PCM's accepted loops with GNC (truncated least squares on the loops).
fn then_gnc(set: &skid_pcm_sets::MultiRobotGraph, result: &skid_pcm_sets::PcmSetResult) -> Result<PgoReport> {
    let mut graph = skid_pcm_sets::accepted_graph(set, result)?;
    let options = PgoOptions {
        robust: RobustMode::parse("gnc")?,
        ..PgoOptions::default()
    };
    let mut report = skid_backend_pgo::optimize_pose_graph::<_, 6>(&mut graph, &options)?;
    report.costs.clear();
    Ok(report)
}

/// When PCM keeps fewer than half of many loops under the files' own information matrices, the hint
/// that those matrices may be placeholders (many datasets write them), which `--unit-covariance` replaces.
fn covariance_hint(accepted: usize, loops: usize, unit_covariance: bool) -> Option<String> {
    (!unit_covariance && loops >= 10 && 2 * accepted < loops).then(|| {
        format!(
            "PCM kept {accepted} of {loops} loops under the files' information matrices. If most of them \
             should be inliers, the matrices may not be the measurements' real uncertainty (datasets often \
             write placeholders): `--unit-covariance` replaces them with identities"
        )
    })
}

pub fn pcm(paths: &[PathBuf], unit_covariance: bool, gnc: bool, json: bool) -> Result<()> {
    let (set, result) =
        skid_pcm_sets::verify_set(paths, unit_covariance).context("verifying the multi-robot graph")?;
    for (file, line) in &set.skipped_lines {
        tracing::warn!(file = %file.display(), line, "skipped a malformed line");
    }
    if let Some(hint) = covariance_hint(result.accepted.len(), result.loops.len(), unit_covariance) {
        eprintln!("note: {hint}");
    }
    let optimised = if gnc { Some(then_gnc(&set, &result)?) } else { None };
    if json {
        let accepted: Vec<serde_json::Value> = result
            .accepted
            .iter()
            .map(|l| serde_json::json!({"id": l.id, "from": key_name(l.from_key), "to": key_name(l.to_key)}))
            .collect();
        let line = serde_json::json!({
            "files": set.files.len(),
            "robots": result.robots,
            "duplicate_edges": set.duplicate_edges,
            "loops": result.loops.len(),
            "accepted": accepted,
            "verify_ms": result.verify_ms,
            "gnc": optimised,
        });
        println!("{line}");
        return Ok(());
    }
    println!(
        "{} files, {} robots, {} loop closures ({} duplicate edges dropped); PCM accepted {} in {:.1} ms:",
        set.files.len(),
        result.robots,
        result.loops.len(),
        set.duplicate_edges,
        result.accepted.len(),
        result.verify_ms
    );
    for accepted in &result.accepted {
        println!(
            "  loop {:>4}: {} - {}",
            accepted.id,
            key_name(accepted.from_key),
            key_name(accepted.to_key)
        );
    }
    if let Some(report) = optimised {
        println!(
            "then GNC: {} iterations, cost {:.6} -> {:.6}, {} loops judged outliers, {:.3} s ({})",
            report.iterations,
            report.start_cost,
            report.final_cost,
            report.outliers,
            report.time_s,
            report.stop
        );
    }
    Ok(())
}
