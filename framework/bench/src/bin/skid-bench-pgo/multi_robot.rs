//! Multi-robot PCM sets (robust_distributed_mapper's `pairwise_consistency_maximization`): every set
//! folder under the shared data is read and verified by `skid-pcm-sets` (what `skid pcm` runs), and the
//! accepted count is set against the repository tests' expectations. PCM runs with its defaults
//! (probability 0.99) on the files' own information matrices and decides from the first loop on. (The
//! repository's tests mention `use_covariance = false`; with unit covariances every spoiled loop of these
//! small worlds passes a 0.99 χ² test, so the expected counts must come from the files' noise models,
//! which reproduce them exactly.)

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::Serialize;
use skid_bench::Report;

#[derive(Serialize)]
struct Row {
    set: String,
    robots: usize,
    inter_robot_edges: usize,
    covariance: String,
    accepted: usize,
    expected: String,
    verify_ms: String,
    ok: bool,
}

/// The accepted counts the repository's own tests expect, by set folder.
const EXPECTED: [(&str, usize); 5] = [
    ("clean/simulation/example_2robots", 10),
    ("spoiled/simulation/example_2robots", 10),
    ("spoiled/simulation_not_in_order/example_2robots", 10),
    ("spoiled/simulation/example_4robots", 24),
    ("spoiled/simulation/example_8robots", 112),
];

/// The multi-robot table.
pub fn rows(report: &mut Report) -> Result<()> {
    let root = skid_io::data_dir()
        .join("multi_robot_pose_graphs/pcm_robust_distributed_mapper/pairwise_consistency_maximization");
    // Every folder that holds g2o files is one set.
    let mut folders: Vec<PathBuf> = skid_bench::files::files_with_extension(&root, "g2o")?
        .iter()
        .filter_map(|file| file.parent().map(Path::to_path_buf))
        .collect();
    folders.dedup();
    for folder in folders {
        let set = folder
            .strip_prefix(&root)
            .unwrap_or(&folder)
            .display()
            .to_string();
        let (_, result) = skid_pcm_sets::verify_set(std::slice::from_ref(&folder), false)?;
        let expected = EXPECTED
            .iter()
            .find(|(name, _)| *name == set)
            .map(|(_, count)| *count);
        report.push(&Row {
            set,
            robots: result.robots,
            inter_robot_edges: result.loops.len(),
            covariance: "file".into(),
            accepted: result.accepted.len(),
            expected: expected.map_or_else(|| "-".to_owned(), |count| count.to_string()),
            verify_ms: format!("{:.1}", result.verify_ms),
            ok: expected.is_none_or(|count| count == result.accepted.len()),
        })?;
    }
    Ok(())
}
