//! `skid pcm` on the shared multi-robot PCM sets (robust_distributed_mapper's
//! `pairwise_consistency_maximization` test data, per-robot g2o files with GTSAM symbol keys): the
//! accepted counts its own tests expect, the loops named by their keys, GNC after PCM on the accepted
//! loops only, and clear errors for a missing folder and for keys without a robot letter.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn pcm(args: &[&Path], extra: &[&str]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command.arg("pcm").args(extra).args(args);
    command.output().unwrap()
}

fn sets_root() -> PathBuf {
    skid_io::data_dir()
        .join("multi_robot_pose_graphs/pcm_robust_distributed_mapper/pairwise_consistency_maximization")
}

#[test]
fn pcm_accepts_the_counts_the_sets_expect() {
    for (set, robots, expected) in [
        ("clean/simulation/example_2robots", 2, 10),
        ("spoiled/simulation/example_2robots", 2, 10),
        ("spoiled/simulation_not_in_order/example_2robots", 2, 10),
        ("spoiled/simulation/example_4robots", 4, 24),
        ("spoiled/simulation/example_8robots", 8, 112),
    ] {
        let output = pcm(&[&sets_root().join(set)], &["--json"]);
        assert!(
            output.status.success(),
            "{set}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        let line: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
        assert_eq!(line["robots"], robots, "{set}");
        let accepted = line["accepted"].as_array().unwrap();
        assert_eq!(accepted.len(), expected, "{set}: {line}");
        // Accepted loops join two different robots, named by GTSAM keys (`a12`).
        for l in accepted {
            let (from, to) = (l["from"].as_str().unwrap(), l["to"].as_str().unwrap());
            assert_ne!(from.chars().next(), to.chars().next(), "{set}: {l}");
        }
        assert!(line["verify_ms"].as_f64().unwrap() >= 0.0);
    }
}

#[test]
fn then_gnc_optimises_the_odometry_and_the_accepted_loops() {
    let set = sets_root().join("spoiled/simulation/example_4robots");
    let output = pcm(&[&set], &["--then", "gnc", "--json"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let gnc = &line["gnc"];
    assert_eq!(gnc["robust"], "gnc", "{gnc}");
    assert_eq!(
        gnc["loop_edges"], 24,
        "only the accepted loops enter the graph: {gnc}"
    );
    assert_eq!(gnc["converged"], true, "{gnc}");
    assert!(
        gnc["final_cost"].as_f64().unwrap() < gnc["start_cost"].as_f64().unwrap(),
        "{gnc}"
    );
}

#[test]
fn bad_inputs_are_clear_errors() {
    let missing = pcm(&[Path::new("/nonexistent/set")], &[]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("/nonexistent/set"));

    // A graph whose keys are plain integers (no robot letter in the top byte).
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("0.g2o"),
        "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n\
         EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n",
    )
    .unwrap();
    let plain = pcm(&[dir.path()], &[]);
    assert!(!plain.status.success());
    let message = String::from_utf8_lossy(&plain.stderr);
    assert!(
        message.contains("no robot letter") && message.contains("0.g2o"),
        "the error does not name the file: {message}"
    );
}

#[test]
fn placeholder_covariances_that_starve_pcm_get_a_hint() {
    // A clean set whose files' information matrices are not the measurements' uncertainty: PCM keeps
    // 16 of its 83 loops under them and all of them with identities.
    let set = skid_io::data_dir()
        .join("multi_robot_pose_graphs/pcm_robust_distributed_mapper/argos_simulation/clean/example_4robots");
    let output = pcm(&[&set], &["--json"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(line["loops"], 83, "{line}");
    assert_eq!(line["accepted"].as_array().unwrap().len(), 16, "{line}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("16 of 83") && stderr.contains("--unit-covariance"),
        "{stderr}"
    );
    let output = pcm(&[&set], &["--json", "--unit-covariance"]);
    let line: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(line["accepted"].as_array().unwrap().len(), 83, "{line}");
    assert!(!String::from_utf8_lossy(&output.stderr).contains("note:"));
}
