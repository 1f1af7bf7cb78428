//! The reference KISS-Matcher (the authors' Python package `kiss-matcher`, C++ core) on the same pairs as
//! SKiD's plugins, run in the same benchmark: the pairs are written as KITTI `.bin` files into a
//! temporary folder and `python/kiss_matcher_pairs.py` runs under `$SKID_PYTHON` (`cargo xtask bench`
//! sets it to the benchmark venv, which has the package).

use anyhow::{Context, Result, bail};
use serde::Deserialize;
use skid_core::{Cloud, Pose};
use skid_io::kitti::write_kitti_bin;

use crate::python_peers::script_stdout;

/// The method name of the reference in tables.
pub const REFERENCE_NAME: &str = "KISS-Matcher (reference)";

/// What the reference returned for one pair.
#[derive(Clone, Debug)]
pub struct ReferenceOutcome {
    pub estimate: Pose,
    pub valid: bool,
    pub final_inliers: usize,
    pub time_ms: f64,
}

#[derive(Deserialize)]
struct Record {
    pair: usize,
    target_from_source: Vec<f64>,
    final_inliers: usize,
    valid: bool,
    ms: f64,
}

fn pose_from_row_major(values: &[f64]) -> Result<Pose> {
    let matrix = <[f64; 16]>::try_from(values)
        .ok()
        .filter(|values| values.iter().all(|v| v.is_finite()))
        .context("the reference returned a pose that is not 16 finite numbers")?;
    skid_io::geometry::isometry_from_4x4(&matrix).map_err(|message| {
        anyhow::anyhow!("the reference returned a pose that is not a transform: {message}")
    })
}

/// Runs the reference on `(target, source)` pairs with voxel size `voxel_m`. `Ok(None)` when
/// `$SKID_PYTHON` is not set (the row is then left out, and said so on stderr).
pub fn reference_kiss_matcher(
    pairs: &[(&Cloud, &Cloud)],
    voxel_m: f64,
) -> Result<Option<Vec<ReferenceOutcome>>> {
    let Some(python) = std::env::var_os("SKID_PYTHON") else {
        eprintln!(
            "registration: SKID_PYTHON is not set (cargo xtask bench sets it); the reference KISS-Matcher is skipped"
        );
        return Ok(None);
    };
    let temporary = tempfile::tempdir().context("creating a folder for the reference's pairs")?;
    // `SKID_BENCH_KEEP_PAIRS=DIR` keeps the pairs for a look with other tools (`skid register`).
    let kept = std::env::var_os("SKID_BENCH_KEEP_PAIRS").map(std::path::PathBuf::from);
    let folder = kept.as_deref().unwrap_or(temporary.path());
    std::fs::create_dir_all(folder).with_context(|| format!("creating {}", folder.display()))?;
    for (index, (target, source)) in pairs.iter().enumerate() {
        write_kitti_bin(
            folder.join(format!("{index:04}_target.bin")),
            target.view().points(),
        )?;
        write_kitti_bin(
            folder.join(format!("{index:04}_source.bin")),
            source.view().points(),
        )?;
    }
    let voxel = voxel_m.to_string();
    let stdout = script_stdout(
        &python,
        "kiss_matcher_pairs.py",
        &[folder.as_os_str(), voxel.as_ref()],
    )?;
    let mut outcomes: Vec<Option<ReferenceOutcome>> = vec![None; pairs.len()];
    for line in String::from_utf8_lossy(&stdout)
        .lines()
        .filter(|l| !l.trim().is_empty())
    {
        let record: Record =
            serde_json::from_str(line).with_context(|| format!("reference output line `{line}`"))?;
        let slot = outcomes.get_mut(record.pair).with_context(|| {
            format!(
                "the reference answered for pair {} of {}",
                record.pair,
                pairs.len()
            )
        })?;
        *slot = Some(ReferenceOutcome {
            estimate: pose_from_row_major(&record.target_from_source)?,
            valid: record.valid,
            final_inliers: record.final_inliers,
            time_ms: record.ms,
        });
    }
    let answered: Option<Vec<ReferenceOutcome>> = outcomes.into_iter().collect();
    match answered {
        Some(all) => Ok(Some(all)),
        None => bail!("the reference did not answer for every pair"),
    }
}
