//! `skid sim export --format ros1|mcap` writes bags that an independent reader (`rosbags`, through
//! `tests/fixtures/dump_bag.py` run with `$SKID_PYTHON`) opens, holding exactly the scans of the KITTI
//! export of the same simulation, and that SKiD's own `bag` source runs the pipeline on.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn skid(args: &[&str]) -> Output {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    Command::new(env!("CARGO_BIN_EXE_skid"))
        .current_dir(repo)
        .args(args)
        .env_remove("RUST_LOG")
        .output()
        .expect("skid runs")
}

fn ok(output: &Output) -> String {
    assert!(
        output.status.success(),
        "skid failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// The independent reader's view of a bag: counts per topic and ground-truth positions.
fn dump_with_rosbags(bag: &Path, out: &Path) -> serde_json::Value {
    let python = std::env::var("SKID_PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/dump_bag.py");
    let output = Command::new(&python)
        .arg(&script)
        .arg(bag)
        .arg(out)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{python} {} failed (needs rosbags and numpy; `cargo xtask ci` sets SKID_PYTHON to a venv with them):\n{}",
        script.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

const FLAGS: [&str; 8] = [
    "--robots", "2", "--frames", "6", "--sensor", "vlp16", "--world", "cave",
];

#[test]
fn exported_bags_hold_the_kitti_export_scans_for_an_independent_reader() {
    let dir = tempfile::tempdir().unwrap();
    let export = |format: &str| {
        let out = dir.path().join(format);
        let mut args = vec!["sim", "export", "--format", format];
        args.extend_from_slice(&FLAGS);
        args.push(out.to_str().unwrap());
        ok(&skid(&args));
        out
    };
    let kitti = export("kitti");
    for (format, bag_name) in [("ros1", "robot{}.bag"), ("mcap", "robot{}")] {
        let bags = export(format);
        for robot in 0..2 {
            let bag = bags.join(bag_name.replace("{}", &robot.to_string()));
            let dumped = dir.path().join(format!("dump-{format}-{robot}"));
            let seen = dump_with_rosbags(&bag, &dumped);
            assert_eq!(seen["counts"]["/points"], 6, "{format} robot {robot}");
            assert_eq!(seen["counts"]["/ground_truth"], 6);
            assert!(
                seen["counts"]["/imu"].as_u64().unwrap() >= 100,
                "200 Hz IMU over 0.6 s"
            );
            for frame in 0..6 {
                let name = format!("{frame:06}.bin");
                let expected = std::fs::read(kitti.join(format!("robot{robot}/velodyne/{name}"))).unwrap();
                let got = std::fs::read(dumped.join(&name)).unwrap();
                assert!(
                    got == expected,
                    "{format} robot {robot} scan {frame}: points differ"
                );
            }
            // Ground truth: the KITTI export's poses are relative to the first scan.
            let poses = std::fs::read_to_string(kitti.join(format!("robot{robot}/poses.txt"))).unwrap();
            let truth = seen["ground_truth"].as_array().unwrap();
            let first: Vec<f64> = truth[0]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let last: Vec<f64> = truth[5]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let moved =
                ((last[0] - first[0]).powi(2) + (last[1] - first[1]).powi(2) + (last[2] - first[2]).powi(2))
                    .sqrt();
            let kitti_last: Vec<f64> = poses
                .lines()
                .nth(5)
                .unwrap()
                .split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect();
            let kitti_moved = (kitti_last[3].powi(2) + kitti_last[7].powi(2) + kitti_last[11].powi(2)).sqrt();
            assert!(
                (moved - kitti_moved).abs() < 1e-6,
                "{format} robot {robot}: {moved} vs {kitti_moved}"
            );
        }
    }
    // SKiD's own source reads the exported fleet back and runs the pipeline on it.
    let run_dir = dir.path().join("runs");
    let path_setting = format!(
        "source.bag.path=\"{}/robot{{robot}}.bag\"",
        dir.path().join("ros1").display()
    );
    let output_setting = format!("run.output_dir=\"{}\"", run_dir.display());
    let line = ok(&skid(&[
        "run",
        "--set",
        "source.plugin=bag",
        "--set",
        &path_setting,
        "--set",
        "source.bag.points_topic=/points",
        "--set",
        "source.bag.imu_topic=/imu",
        "--set",
        "run.robots=2",
        "--set",
        "run.name=sim-bags",
        "--set",
        &output_setting,
    ]));
    let summary: serde_json::Value = serde_json::from_str(line.lines().last().unwrap()).unwrap();
    assert_eq!(summary["robots"][1]["scans"], 6);
    assert!(run_dir.join("sim-bags/metrics.json").is_file());
}
