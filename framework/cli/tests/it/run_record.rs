//! The run record: a short two-robot run on real KITTI scans writes `runs/<name>/run.mcap`, which an independent reader
//! (the Python `mcap` package for the container, rosbags' type system and CDR deserializer for the
//! messages, built from the schemas in the file) opens; its topics, message counts, frames and loop
//! markers agree with the run's other outputs, and each robot's path equals its `trajectory.tum`.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn run(out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .args(["-q", "run"]);
    // The real KITTI excerpt split between two robots: their keyframes overlap, so robot 1's first
    // keyframe closes an inter-robot loop with robot 0's, which PCM decides on at once. Global
    // registration of 120k-point keyframes costs seconds in a test build; the runs and benchmarks in
    // release cover it.
    let sets = [
        "run.robots=2".to_owned(),
        "run.name=recorded".to_owned(),
        format!("run.output_dir={}", out.display()),
        "source.plugin=kitti".to_owned(),
        "source.kitti.split.enabled=true".to_owned(),
        "coarse.plugin=none".to_owned(),
        "verifier.pcm.consistency.min_loops_before_decision=1".to_owned(),
        // One loop on a 16-scan snippet: the spread a merge needs between robots is waived here.
        "verifier.pcm.consistency.min_spread_m=0".to_owned(),
    ];
    for set in sets.iter().map(String::as_str).chain(extra.iter().copied()) {
        command.args(["--set", set]);
    }
    let output = command.output().unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

fn read_record(path: &Path) -> serde_json::Value {
    let python = std::env::var("SKID_PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/read_run_record.py");
    let output = Command::new(&python).arg(script).arg(path).output().unwrap();
    assert!(
        output.status.success(),
        "the reader (SKID_PYTHON needs mcap and rosbags) failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

/// The rows of a TUM file: stamp, position, quaternion (x, y, z, w).
fn tum_rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|line| !line.starts_with('#') && !line.trim().is_empty())
        .map(|line| line.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn the_run_record_opens_in_an_independent_reader_and_agrees_with_the_run() {
    let out = tempfile::tempdir().unwrap();
    let summary = run(out.path(), &[]);
    let folder = out.path().join("recorded");
    let record = read_record(&folder.join("run.mcap"));
    let topics = &record["topics"];
    let count = |topic: &str| topics[topic]["count"].as_u64().unwrap_or(0);
    let kind = |topic: &str| topics[topic]["type"].as_str().unwrap_or("").to_owned();

    let mut scans_total = 0;
    for (index, robot) in summary["robots"].as_array().unwrap().iter().enumerate() {
        let name = format!("robot{index}");
        let scans = robot["scans"].as_u64().unwrap();
        scans_total += scans;
        assert_eq!(count(&format!("/{name}/odometry")), scans, "{name} odometry");
        assert_eq!(kind(&format!("/{name}/odometry")), "nav_msgs/msg/Odometry");
        assert_eq!(
            count(&format!("/{name}/keyframes")),
            robot["keyframes"].as_u64().unwrap(),
            "{name} keyframes"
        );
        assert_eq!(count(&format!("/{name}/path")), 1);
        assert_eq!(count(&format!("/{name}/ground_truth")), 1);

        // The path read back is the trajectory file, pose for pose.
        let path = record["paths"][format!("/{name}/path")].as_array().unwrap();
        let tum = tum_rows(&folder.join(&name).join("trajectory.tum"));
        assert_eq!(path.len(), tum.len(), "{name}");
        for (pose, row) in path.iter().zip(&tum) {
            let pose: Vec<f64> = pose
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let sign = if pose[7] * row[7] < 0.0 { -1.0 } else { 1.0 };
            assert!(
                (pose[0] - row[0]).abs() < 1e-6,
                "{name} stamp {pose:?} vs {row:?}"
            );
            for axis in 1..4 {
                assert!(
                    (pose[axis] - row[axis]).abs() < 1e-6,
                    "{name} {pose:?} vs {row:?}"
                );
            }
            for axis in 4..8 {
                assert!(
                    (sign * pose[axis] - row[axis]).abs() < 1e-6,
                    "{name} {pose:?} vs {row:?}"
                );
            }
        }
        let cloud = &record["clouds"][format!("/{name}/keyframes")];
        assert_eq!(cloud["frame"], format!("{name}/map"));
        assert!(cloud["points"].as_u64().unwrap() > 100, "{cloud}");
        let tf = record["tf"].as_array().unwrap();
        for pair in [
            [format!("{name}/odom"), format!("{name}/base_link")],
            [format!("{name}/map"), format!("{name}/odom")],
        ] {
            assert!(
                tf.iter().any(|t| t[0] == pair[0] && t[1] == pair[1]),
                "{pair:?} not on /tf"
            );
        }
    }
    assert_eq!(count("/tf"), scans_total);
    assert_eq!(count("/map"), 1);
    assert_eq!(kind("/loops"), "visualization_msgs/msg/MarkerArray");
    assert_eq!(
        record["clouds"]["/map"]["fields"],
        serde_json::json!(["x", "y", "z", "intensity", "ring", "time"])
    );
    let placed = record["tf_static"].as_array().unwrap();
    assert!(
        placed.iter().any(|t| t[0] == "map" && t[1] == "robot0/map"),
        "{placed:?}"
    );

    // Every loop a robot submitted is drawn once, in its class, when both its robots are placed in `map`.
    let markers = &record["markers"];
    let drawn = |namespace: &str| markers[namespace].as_u64().unwrap_or(0);
    let accepted: u64 = summary["robots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            r["loops"]["accepted_intra"].as_u64().unwrap() + r["loops"]["accepted_inter"].as_u64().unwrap()
        })
        .sum();
    assert!(accepted > 0, "the run found no loop: {summary}");
    if placed.len() == 2 {
        assert_eq!(drawn("accepted"), 2 * accepted, "{markers}");
    } else {
        assert!(
            drawn("accepted") <= 2 * accepted && drawn("accepted") > 0,
            "{markers}"
        );
    }
}

#[test]
fn skid_plot_draws_the_plots_again_from_the_record() {
    let out = tempfile::tempdir().unwrap();
    run(out.path(), &[]);
    let folder = out.path().join("recorded");
    let plots = ["trajectories.png", "errors.png", "map.png"];
    let run_map_pixels = inked_pixels(&folder.join("map.png"));
    for plot in plots {
        assert!(folder.join(plot).is_file(), "the run wrote no {plot}");
        std::fs::remove_file(folder.join(plot)).unwrap();
    }
    let output = Command::new(env!("CARGO_BIN_EXE_skid"))
        .arg("plot")
        .arg(&folder)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let listed = String::from_utf8_lossy(&output.stdout);
    for plot in plots {
        let bytes = std::fs::read(folder.join(plot)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 5_000, "{plot}");
        assert!(listed.contains(plot), "{listed}");
    }
    // The map drawn again is thinned as the run's own is, so it is no denser (unthinned, this run's
    // redrawn map has 5 % more inked pixels).
    let redrawn_map_pixels = inked_pixels(&folder.join("map.png"));
    let ratio = redrawn_map_pixels as f64 / run_map_pixels as f64;
    assert!(
        (0.99..=1.01).contains(&ratio),
        "map.png drawn again has {redrawn_map_pixels} inked pixels, the run's {run_map_pixels}"
    );
    // A folder without a record is a clear error.
    std::fs::remove_file(folder.join("run.mcap")).unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_skid"))
        .arg("plot")
        .arg(&folder)
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("has no run.mcap"));
}

#[test]
fn the_record_can_be_turned_off() {
    let out = tempfile::tempdir().unwrap();
    run(out.path(), &["output.record=false"]);
    let folder = out.path().join("recorded");
    assert!(folder.join("summary.json").is_file());
    assert!(!folder.join("run.mcap").exists());
}

/// Pixels of a PNG that are not white.
fn inked_pixels(path: &std::path::Path) -> usize {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    let channels = info.color_type.samples();
    buffer[..info.buffer_size()]
        .chunks(channels)
        .filter(|pixel| pixel.iter().take(3).any(|&value| value != 255))
        .count()
}
