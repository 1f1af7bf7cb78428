//! The C++17 example plugin (`point_to_plane_icp`, skid-example-cpp) end to end through the command
//! line: `skid plugins --check` runs the fine slot's conformance suite on it and passes, a two-robot run
//! on the real KITTI excerpt with `--plugin-lib … --set fine.plugin=point_to_plane_icp` finishes with an
//! inter-robot loop refined by it, and a value the plugin refuses is named.

use std::path::PathBuf;
use std::process::{Command, Output};

fn skid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skid"))
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../.."))
        .env_remove("RUST_LOG")
        .env_remove("SKID_PLUGIN_LIBS")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn plugins_check_runs_the_fine_suite_on_the_cpp_plugin() {
    let output = skid(&["plugins", "--check", skid_example_cpp::LIBRARY_PATH]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains("[fine] point_to_plane_icp"), "{stdout}");
    assert_eq!(stdout.matches("  PASS  ").count(), 4, "{stdout}");
    assert!(
        stdout.contains("PASS  two instances on two threads at once"),
        "{stdout}"
    );
    assert!(stdout.contains("4 checks, 4 passed, 0 failed"), "{stdout}");
}

fn run_with_cpp_fine(out: &std::path::Path, extra: &[&str]) -> Output {
    let output_dir = format!("run.output_dir={}", out.display());
    let mut args = vec![
        "-q",
        "run",
        "--plugin-lib",
        skid_example_cpp::LIBRARY_PATH,
        "--set",
        "fine.plugin=point_to_plane_icp",
        "--set",
        "run.robots=2",
        "--set",
        "run.name=cpp",
        "--set",
        &output_dir,
        "--set",
        "source.plugin=kitti",
        "--set",
        "source.kitti.split.enabled=true",
        "--set",
        "coarse.plugin=none",
        "--set",
        "verifier.pcm.consistency.min_loops_before_decision=1",
        "--set",
        // One loop on a 16-scan snippet: the spread a merge needs between robots is waived here.
        "verifier.pcm.consistency.min_spread_m=0",
        "--set",
        "output.record=false",
    ];
    args.extend_from_slice(extra);
    skid(&args)
}

#[test]
fn a_run_with_the_cpp_fine_registration_finishes_with_its_loops() {
    let out = tempfile::tempdir().unwrap();
    let output = run_with_cpp_fine(out.path(), &[]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(summary["slots"]["fine"], "point_to_plane_icp");
    let robots = summary["robots"].as_array().unwrap();
    let fine_ms: f64 = robots
        .iter()
        .filter_map(|robot| robot["stage_ms"]["fine"].as_f64())
        .sum();
    assert!(fine_ms > 0.0, "the plugin refined: {summary}");
    let accepted: u64 = robots
        .iter()
        .map(|robot| robot["loops"]["accepted_inter"].as_u64().unwrap())
        .sum();
    let not_converged: u64 = robots
        .iter()
        .map(|robot| robot["loops"]["fine_not_converged"].as_u64().unwrap())
        .sum();
    assert!(
        accepted >= 1,
        "the robots share a street: an inter-robot loop is expected ({summary})"
    );
    assert_eq!(not_converged, 0, "{summary}");
}

#[test]
fn a_value_the_cpp_plugin_refuses_is_named() {
    let out = tempfile::tempdir().unwrap();
    let output = run_with_cpp_fine(out.path(), &["--set", "fine.point_to_plane_icp.max_iterations=0"]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("max_iterations") && stderr.contains("between 1 and 1000"),
        "{stderr}"
    );
}
