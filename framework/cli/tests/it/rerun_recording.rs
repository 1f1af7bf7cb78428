//! The Rerun recording (`skid run --rerun-save FILE.rrd`, in a `skid` built with `--features rerun`): a
//! two-robot run on the real KITTI excerpt is saved as `.rrd`, and the `rerun-sdk` Python package's own
//! reader (`tests/fixtures/read_rrd.py`, with `$SKID_PYTHON`) finds every robot's entities on the
//! `scan_time` timeline, one logged pose per scan, the paths, maps and loops, and the link statistics.
//! Without the feature, asking for Rerun is a clear error.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn run(out: &Path, extra: &[&str]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .args(["-q", "run"]);
    let sets = [
        "run.robots=2".to_owned(),
        "run.name=viewed".to_owned(),
        format!("run.output_dir={}", out.display()),
        "source.plugin=kitti".to_owned(),
        "source.kitti.split.enabled=true".to_owned(),
        "coarse.plugin=none".to_owned(),
        "verifier.pcm.consistency.min_loops_before_decision=1".to_owned(),
        // One loop on a 16-scan snippet: the spread a merge needs between robots is waived here.
        "verifier.pcm.consistency.min_spread_m=0".to_owned(),
        "output.record=false".to_owned(),
    ];
    for set in &sets {
        command.args(["--set", set]);
    }
    command.args(extra).output().unwrap()
}

#[cfg(feature = "rerun")]
#[test]
fn the_recording_opens_in_the_rerun_sdk_with_every_robots_entities() {
    let out = tempfile::tempdir().unwrap();
    let rrd = out.path().join("run.rrd");
    let output = run(out.path(), &["--rerun-save", rrd.to_str().unwrap()]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let python = std::env::var("SKID_PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/read_rrd.py");
    let read = Command::new(&python).arg(script).arg(&rrd).output().unwrap();
    assert!(
        read.status.success(),
        "the reader (SKID_PYTHON needs rerun-sdk 0.36.3) failed: {}",
        String::from_utf8_lossy(&read.stderr)
    );
    let recording: serde_json::Value = serde_json::from_slice(&read.stdout).unwrap();
    assert_eq!(recording["applications"], serde_json::json!(["skid"]));
    let entities = &recording["entities"];
    for robot in 0..2 {
        let scans = summary["robots"][robot]["scans"].as_u64().unwrap();
        let entity = |name: &str| entities[format!("/robot{robot}/{name}")].clone();
        let pose = entity("pose");
        assert_eq!(pose["rows"].as_u64().unwrap(), scans, "one pose per scan: {pose}");
        assert!(pose["timelines"].to_string().contains("scan_time"), "{pose}");
        assert!(pose["columns"].to_string().contains("Transform3D"), "{pose}");
        assert_eq!(entity("position")["rows"].as_u64().unwrap(), scans);
        assert!(
            entity("path")["columns"].to_string().contains("LineStrips3D"),
            "{entities}"
        );
        assert!(
            entity("loops")["columns"].to_string().contains("LineStrips3D"),
            "{entities}"
        );
        let map = entity("map");
        assert!(
            map["rows"].as_u64().unwrap() >= 1 && map["columns"].to_string().contains("Points3D"),
            "{map}"
        );
        for statistic in ["sent_bytes", "received_bytes", "cloud_wait_s"] {
            let series = &entities[format!("/link/robot{robot}/{statistic}")];
            assert_eq!(series["rows"].as_u64().unwrap(), scans, "{statistic}: {series}");
            assert!(series["columns"].to_string().contains("Scalars"), "{series}");
        }
    }
}

#[cfg(not(feature = "rerun"))]
#[test]
fn asking_for_rerun_without_the_feature_says_how_to_build_it() {
    let out = tempfile::tempdir().unwrap();
    let output = run(out.path(), &["--rerun-save", "never.rrd"]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("--features rerun"), "{stderr}");
    assert!(!repo().join("never.rrd").exists());
}
