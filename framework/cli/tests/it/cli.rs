//! The `skid` binary end to end: plugin listing, configuration display and checking (including
//! environment overrides set on the child process), and a short run on the real KITTI excerpt.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn skid(args: &[&str], envs: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command.current_dir(repo()).args(args).env_remove("RUST_LOG");
    for (key, value) in envs {
        command.env(key, value);
    }
    command.output().expect("skid runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn plugins_lists_every_slot_with_defaults() {
    let output = skid(&["plugins"], &[]);
    assert!(output.status.success());
    let stdout = text(&output.stdout);
    for expected in [
        "[source]",
        "kitti",
        "cloud_dir",
        "[odometry]",
        "ground_truth",
        "translation_noise_m = 0.0",
        "[transport]",
    ] {
        assert!(stdout.contains(expected), "missing {expected} in:\n{stdout}");
    }
    let json = skid(&["plugins", "--json", "--slot", "odometry"], &[]);
    let rows: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let names: Vec<&str> = rows
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|row| row["name"].as_str())
        .collect();
    assert_eq!(names, ["auto", "ground_truth", "kiss_icp", "lio"]);
    assert_eq!(rows[1]["defaults"]["keyframe"]["distance_m"], 2.0);
    // `auto` shows both candidates' defaults.
    assert_eq!(rows[0]["defaults"]["kiss_icp"]["keyframe"]["distance_m"], 2.0);
    assert!(rows[0]["defaults"]["lio"]["map_voxel_m"].is_number());
    let bad = skid(&["plugins", "--slot", "odometryy"], &[]);
    assert!(!bad.status.success());
    assert!(text(&bad.stderr).contains("unknown slot `odometryy`"));
}

#[test]
fn config_show_prints_the_merged_default_as_toml() {
    let output = skid(
        &["config", "show", "--set", "run.robots=2"],
        &[("SKID_RUN__SEED", "99")],
    );
    assert!(output.status.success(), "{}", text(&output.stderr));
    let shown: toml::Table = text(&output.stdout).parse().unwrap();
    assert_eq!(shown["run"]["robots"].as_integer(), Some(2));
    assert_eq!(shown["run"]["seed"].as_integer(), Some(99));
    assert_eq!(shown["source"]["plugin"].as_str(), Some("sim"));
    assert!(shown["odometry"]["kiss_icp"]["keyframe"].is_table());
}

#[test]
fn config_check_reports_file_key_and_expected_keys() {
    let bad = repo().join("framework/config/tests/bad/typo_key.toml");
    let output = skid(&["config", "check", bad.to_str().unwrap()], &[]);
    assert!(!output.status.success());
    let stderr = text(&output.stderr);
    assert!(stderr.contains("typo_key.toml"), "{stderr}");
    assert!(
        stderr.contains("odometry.ground_truth.translation_noize_m"),
        "{stderr}"
    );
    assert!(stderr.contains("translation_noise_m"), "{stderr}");
    let good = skid(&["config", "check", "configs/default.toml"], &[]);
    assert!(good.status.success(), "{}", text(&good.stderr));
}

#[test]
fn a_bad_environment_variable_is_named() {
    let output = skid(&["config", "show"], &[("SKID_RUN__ROBOTZ", "2")]);
    assert!(!output.status.success());
    let stderr = text(&output.stderr);
    assert!(
        stderr.contains("SKID_RUN__ROBOTZ") && stderr.contains("robots"),
        "{stderr}"
    );
}

#[test]
fn run_writes_trajectories_and_a_summary() {
    let out = tempfile::tempdir().unwrap();
    let out_arg = format!("run.output_dir={}", out.path().display());
    let output = skid(
        &[
            "-q",
            "run",
            "--set",
            &out_arg,
            "--set",
            "run.robots=2",
            "--set",
            "run.name=e2e",
            // The real KITTI excerpt split between the two robots, through the default pipeline.
            "--set",
            "source.plugin=kitti",
            "--set",
            "source.kitti.split.enabled=true",
            // Global registration of 120k-point KITTI keyframes costs seconds in a debug build; the
            // release run and the registration benchmarks cover it.
            "--set",
            "coarse.plugin=none",
        ],
        &[],
    );
    assert!(output.status.success(), "{}", text(&output.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(summary["robots"].as_array().unwrap().len(), 2);
    assert!(summary["robots"][0]["estimated_path_length_m"].as_f64().unwrap() > 1.0);
    assert_eq!(summary["robots"][0]["scans_read"], 8);
    assert_eq!(summary["robots"][0]["scans_skipped"], 0);
    // The summary names what made it: the version, and the commit when built from a git work tree.
    assert_eq!(summary["skid_version"], env!("CARGO_PKG_VERSION"));
    if std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../.git")
        .exists()
    {
        let commit = summary["skid_commit"].as_str().unwrap_or_default();
        assert!(
            commit.len() >= 40 && commit[..40].chars().all(|c| c.is_ascii_hexdigit()),
            "{commit}"
        );
    }
    // `-q` keeps stderr to warnings: no human table.
    assert!(
        !text(&output.stderr).contains("outputs:"),
        "{}",
        text(&output.stderr)
    );
    let folder = out.path().join("e2e");
    for robot in ["robot0", "robot1"] {
        let trajectory = skid_io_read_tum(&folder.join(robot).join("trajectory.tum"));
        assert_eq!(trajectory, 8, "{robot}: {trajectory} poses");
    }
    assert!(folder.join("config.toml").is_file());
    assert!(folder.join("summary.json").is_file());
    for file in [
        "map.ply",
        "map.png",
        "trajectories.png",
        "robot0/pose_graph.g2o",
        "robot1/ground_truth.kitti",
    ] {
        assert!(folder.join(file).is_file(), "{file} missing");
    }
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(folder.join("metrics.json")).unwrap()).unwrap();
    let robots = metrics["robots"].as_array().unwrap();
    assert_eq!(robots.len(), 2);
    for robot in robots {
        let ate_m = robot["trajectory"]["ate_m"]["rmse"].as_f64().unwrap();
        assert!(ate_m.is_finite() && ate_m >= 0.0, "{robot}");
        // The straight KITTI excerpt cannot fix the alignment's roll: metrics.json says so.
        assert_eq!(
            robot["trajectory"]["alignment_conditioning"]["ill_conditioned"], true,
            "{robot}"
        );
        assert!(
            robot["trajectory"]["rpe_rotation_deg"]["rmse"].as_f64().is_some(),
            "{robot}"
        );
        assert!(
            robot["trajectory"]["ground_truth_path_length_m"]
                .as_f64()
                .unwrap()
                > 1.0
        );
        // Every candidate ends in exactly one outcome.
        let loops = &robot["loops"];
        let count = |key: &str| loops[key].as_u64().unwrap();
        let candidates = count("candidates_intra") + count("candidates_inter");
        let outcomes: u64 = [
            "repeated_pair",
            "cloud_missing",
            "queued",
            "expired",
            "awaiting_cloud",
            "coarse_invalid",
            "coarse_ambiguous",
            "fine_not_converged",
            "accepted_intra",
            "accepted_inter",
            "rejected",
            "undecided",
        ]
        .iter()
        .map(|key| count(key))
        .sum();
        assert_eq!(candidates, outcomes, "{loops}");
        // Every refusal has one reason.
        let by_reason: u64 = loops["rejected_by"]
            .as_object()
            .unwrap()
            .values()
            .map(|count| count.as_u64().unwrap())
            .sum();
        assert_eq!(by_reason, count("rejected"), "{loops}");
    }
    assert!(metrics["inter_robot_candidates"].as_u64().is_some(), "{metrics}");
    // Robot 1 is β: either its α/β alignment error or the reason it has none.
    assert!(robots[1]["alignment"].is_object() || robots[1]["alignment_unavailable"].is_string());
    check_session(&folder);
    let g2o = std::fs::read_to_string(folder.join("robot0/pose_graph.g2o")).unwrap();
    assert!(g2o.lines().any(|l| l.starts_with("VERTEX_SE3:QUAT")), "{g2o}");
    // Every edge joins two vertices of the file.
    let vertices: std::collections::BTreeSet<&str> = g2o
        .lines()
        .filter(|l| l.starts_with("VERTEX_SE3:QUAT"))
        .filter_map(|l| l.split_whitespace().nth(1))
        .collect();
    for edge in g2o.lines().filter(|l| l.starts_with("EDGE_SE3:QUAT")) {
        let ends: Vec<&str> = edge.split_whitespace().skip(1).take(2).collect();
        assert!(
            ends.iter().all(|id| vertices.contains(id)),
            "dangling edge: {edge}"
        );
    }
}

/// The run's session reads back: every keyframe described, its cloud as long as stated, and its pose
/// the optimised trajectory's at its stamp.
fn check_session(folder: &Path) {
    let dir = folder.join("session");
    let session = skid_session::read_session(&dir).unwrap();
    assert_eq!(session.name, "e2e");
    assert_eq!(session.descriptor.as_ref().unwrap().kind, "solid");
    assert_eq!(session.robots.len(), 2);
    for robot in &session.robots {
        assert!(!robot.keyframes.is_empty());
        let trajectory =
            skid_io::trajectory::read_tum(folder.join(format!("robot{}/trajectory.tum", robot.robot)))
                .unwrap();
        for keyframe in &robot.keyframes {
            assert_eq!(
                keyframe.descriptor.as_ref().map(Vec::len),
                Some(session.descriptor.as_ref().unwrap().length)
            );
            let points = skid_session::read_keyframe_cloud(&dir, robot, keyframe).unwrap();
            assert!(points.len() > 1000, "{} points", points.len());
            let stamp_s = keyframe.stamp_nanos as f64 * 1e-9;
            let scan = trajectory
                .iter()
                .find(|pose| (pose.stamp_s - stamp_s).abs() < 1e-6)
                .unwrap();
            let offset =
                scan.world_from_sensor.translation.vector - keyframe.map_from_sensor.translation.vector;
            assert!(offset.norm() < 1e-3, "keyframe {}: {offset:?}", keyframe.index);
        }
    }
    assert!(session.robots[0].map_from_robot.is_some());
    let info = skid(&["session", "info", "--json", &folder.display().to_string()], &[]);
    assert!(info.status.success(), "{}", text(&info.stderr));
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(
        info["robots"][1]["keyframes"].as_u64(),
        Some(session.robots[1].keyframes.len() as u64)
    );
    let missing = skid(
        &["session", "info", &folder.join("robot0").display().to_string()],
        &[],
    );
    assert!(!missing.status.success());
    assert!(
        text(&missing.stderr).contains("not a session folder"),
        "{}",
        text(&missing.stderr)
    );
}

fn skid_io_read_tum(path: &Path) -> usize {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .count()
}

#[test]
fn fleet_certs_refuse_to_replace_a_ca_unless_told() {
    let dir = tempfile::tempdir().unwrap();
    let certs = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_skid"))
            .args(["fleet", "certs", "--robots", "2"])
            .args(extra)
            .arg(dir.path())
            .output()
            .unwrap()
    };
    assert!(certs(&[]).status.success());
    let first_ca = std::fs::read(dir.path().join("ca.pem")).unwrap();
    let again = certs(&[]);
    assert!(!again.status.success());
    let message = String::from_utf8_lossy(&again.stderr);
    assert!(
        message.contains("ca.pem") && message.contains("--overwrite"),
        "{message}"
    );
    assert_eq!(std::fs::read(dir.path().join("ca.pem")).unwrap(), first_ca);
    assert!(certs(&["--overwrite"]).status.success());
    assert_ne!(std::fs::read(dir.path().join("ca.pem")).unwrap(), first_ca);
}

#[test]
fn fleet_certs_write_a_working_configuration_per_robot() {
    let dir = tempfile::tempdir().unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_skid"))
        .args(["fleet", "certs", "--robots", "3"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let printed = String::from_utf8_lossy(&output.stdout);
    for robot in 0..3 {
        let file = dir.path().join(format!("robot-{robot}.toml"));
        let config = std::fs::read_to_string(&file).unwrap();
        assert!(
            printed.contains(&config),
            "robot {robot}'s configuration is not printed:\n{printed}"
        );
        assert!(config.contains(&format!("robot = {robot}")), "{config}");
        assert!(
            config.contains(&format!("tls/127.0.0.1:{}", 7447 + robot)),
            "{config}"
        );
        // The file is a configuration SKiD accepts, certificate files included, from another folder.
        let checked = Command::new(env!("CARGO_BIN_EXE_skid"))
            .current_dir(std::env::temp_dir())
            .args(["config", "check"])
            .arg(&file)
            .output()
            .unwrap();
        assert!(
            checked.status.success(),
            "{}",
            String::from_utf8_lossy(&checked.stderr)
        );
        let effective = Command::new(env!("CARGO_BIN_EXE_skid"))
            .args(["config", "show", "--config"])
            .arg(&file)
            .output()
            .unwrap();
        let effective = String::from_utf8_lossy(&effective.stdout);
        assert!(effective.contains("plugin = \"zenoh\""), "{effective}");
    }
    // Robots on their own machines listen on every interface and connect to the others' addresses.
    let remote = tempfile::tempdir().unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_skid"))
        .args([
            "fleet",
            "certs",
            "--robots",
            "2",
            "--hosts",
            "10.0.0.10,10.0.0.11",
        ])
        .arg(remote.path())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let config = std::fs::read_to_string(remote.path().join("robot-0.toml")).unwrap();
    assert!(
        config.contains("tls/0.0.0.0:7447") && config.contains("tls/10.0.0.11:7447"),
        "{config}"
    );
    let output = Command::new(env!("CARGO_BIN_EXE_skid"))
        .args(["fleet", "certs", "--robots", "3", "--hosts", "10.0.0.10"])
        .arg(tempfile::tempdir().unwrap().path())
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("--hosts names 1"));
}
