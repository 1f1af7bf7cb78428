//! Replays every fuzz target's seeds, committed corpus (`fuzz/corpus/<target>/`) and kept crashers
//! (`fuzz/regressions/<target>/`) through its harness: a bounded, deterministic run of the fuzz targets
//! in `cargo test`, so CI exercises every decoder and a fixed crash stays fixed.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};

use skid_fuzz_harness::{TARGETS, seeds::seeds};

fn fuzz_folder() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

/// The files of `folder` in name order (none when it does not exist).
fn files_in(folder: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|entry| entry.path())
        .filter(|path| path.is_file())
        .collect();
    files.sort();
    files
}

#[test]
fn every_target_has_seeds_and_a_committed_corpus() {
    for (target, _) in TARGETS {
        assert!(!seeds(target).is_empty(), "{target} has no seeds");
        let corpus = files_in(&fuzz_folder().join("corpus").join(target));
        assert!(
            !corpus.is_empty(),
            "fuzz/corpus/{target} is empty: run `cargo xtask fuzz {target}`"
        );
        let script = fuzz_folder().join("fuzz_targets").join(format!("{target}.rs"));
        assert!(script.is_file(), "no cargo-fuzz target {}", script.display());
    }
}

#[test]
fn seeds_corpus_and_regressions_replay_without_a_defect() {
    let mut replayed = 0usize;
    for (target, harness) in TARGETS {
        for seed in seeds(target) {
            harness(&seed);
            replayed += 1;
        }
        for folder in ["corpus", "regressions"] {
            for file in files_in(&fuzz_folder().join(folder).join(target)) {
                let data = std::fs::read(&file).unwrap();
                let outcome = std::panic::catch_unwind(|| harness(&data));
                assert!(outcome.is_ok(), "{target}: {} fails its harness", file.display());
                replayed += 1;
            }
        }
    }
    assert!(replayed > TARGETS.len());
}
