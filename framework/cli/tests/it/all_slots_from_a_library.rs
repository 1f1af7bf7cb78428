//! Every plugin slot from an out-of-tree library at once: a two-robot run on the real KITTI excerpt whose
//! source, odometry, fine registration, verifier and back-end are the example cdylib's (the built-ins
//! compiled into `skid-example-cdylib` and loaded through the C ABI) finishes with its inter-robot loop
//! and the same trajectory error as the same run with the built-ins.

use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The example plugin library, a dev-dependency of this crate.
fn example_library() -> PathBuf {
    skid_testkit::cdylib::dev_dependency_library("skid-example-cdylib")
}

/// A run's summary, with the given plugin library and slot choices.
fn run(out: &Path, name: &str, library: Option<&Path>, slots: &[(&str, &str)]) -> serde_json::Value {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command
        .current_dir(workspace())
        .env_remove("RUST_LOG")
        .env_remove("SKID_PLUGIN_LIBS");
    command.arg("-q").arg("run");
    if let Some(library) = library {
        command.arg("--plugin-lib").arg(library);
    }
    let mut sets = vec![
        "run.robots=2".to_owned(),
        format!("run.name={name}"),
        format!("run.output_dir={}", out.display()),
        "coarse.plugin=none".to_owned(),
        "output.record=false".to_owned(),
    ];
    for (slot, plugin) in slots {
        sets.push(format!("{slot}.plugin={plugin}"));
    }
    let source = slots
        .iter()
        .find(|(slot, _)| *slot == "source")
        .map_or("kitti", |(_, plugin)| plugin);
    let verifier = slots
        .iter()
        .find(|(slot, _)| *slot == "verifier")
        .map_or("pcm", |(_, plugin)| plugin);
    sets.push(format!("source.{source}.split.enabled=true"));
    sets.push(format!(
        "verifier.{verifier}.consistency.min_loops_before_decision=1"
    ));
    // One loop on a 16-scan snippet: the spread a merge needs between robots is waived here.
    sets.push(format!("verifier.{verifier}.consistency.min_spread_m=0"));
    for set in &sets {
        command.args(["--set", set]);
    }
    let output = command.output().unwrap();
    assert!(
        output.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

#[test]
fn a_run_with_every_slot_from_the_example_library_matches_the_built_ins() {
    let library = example_library();
    let out = tempfile::tempdir().unwrap();
    let loaded = run(
        out.path(),
        "loaded",
        Some(&library),
        &[
            ("source", "kitti_cdylib"),
            ("odometry", "kiss_icp_cdylib"),
            ("fine", "gicp_cdylib"),
            ("verifier", "pcm_cdylib"),
            ("backend", "pgo_cdylib"),
        ],
    );
    assert_eq!(loaded["slots"]["backend"], "pgo_cdylib");
    assert_eq!(loaded["slots"]["verifier"], "pcm_cdylib");
    let built_in = run(
        out.path(),
        "built_in",
        None,
        &[
            ("source", "kitti"),
            ("odometry", "kiss_icp"),
            ("fine", "gicp"),
            ("verifier", "pcm"),
            ("backend", "pgo"),
        ],
    );
    let accepted = |summary: &serde_json::Value| -> u64 {
        summary["robots"]
            .as_array()
            .unwrap()
            .iter()
            .map(|robot| robot["loops"]["accepted_inter"].as_u64().unwrap())
            .sum()
    };
    assert!(accepted(&loaded) >= 1, "{loaded}");
    assert_eq!(accepted(&loaded), accepted(&built_in));
    for robot in 0..2 {
        let ate = |summary: &serde_json::Value| {
            summary["robots"][robot]["ate_first_pose_aligned_m"]
                .as_f64()
                .unwrap()
        };
        assert!(
            (ate(&loaded) - ate(&built_in)).abs() < 1e-6,
            "robot {robot}: {} vs {}",
            ate(&loaded),
            ate(&built_in)
        );
    }
}
