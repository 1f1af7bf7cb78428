//! `skid pcm DIR|FILE…`: pairwise consistency maximisation on a multi-robot pose graph given as per-robot
//! g2o files with GTSAM symbol keys (see `skid-pcm-sets`): prints the loops PCM accepts, with their ids
//! and keys, and the time it took; `--json` prints one JSON line instead.

use std::path::PathBuf;

use anyhow::{Context, Result};
use skid_pcm_sets::key_name;

pub fn pcm(paths: &[PathBuf], unit_covariance: bool, json: bool) -> Result<()> {
    let (set, result) =
        skid_pcm_sets::verify_set(paths, unit_covariance).context("verifying the multi-robot graph")?;
    for (file, line) in &set.skipped_lines {
        tracing::warn!(file = %file.display(), line, "skipped a malformed line");
    }
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
    Ok(())
}
