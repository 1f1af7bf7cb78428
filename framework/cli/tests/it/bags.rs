//! `skid` on ROS bags: `bag info`, `odometry` on a bag against the same scans as a KITTI folder, and a
//! two-robot `run` whose robots read a ROS 1 bag and a ROS 2 MCAP bag of the same drive (the shared
//! KITTI 00 bags in `$SKID_DATA_DIR/kitti_00_rosbags`, written by the independent `rosbags` library).

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

fn data(relative: &str) -> String {
    skid_io::data_path(relative).unwrap().display().to_string()
}

fn ros1_bag() -> String {
    data("kitti_00_rosbags/kitti00_velodyne_ros1-lz4.bag")
}

fn mcap_bag() -> String {
    data("kitti_00_rosbags/kitti00_velodyne_mcap")
}

fn ok(output: &Output) -> String {
    assert!(
        output.status.success(),
        "skid failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

#[test]
fn bag_info_lists_topics_counts_and_the_cloud_layout() {
    for bag in [ros1_bag(), mcap_bag()] {
        let text = ok(&skid(&["bag", "info", &bag]));
        for expected in [
            "/velodyne_points",
            "sensor_msgs/PointCloud2",
            "/imu/data",
            "sensor_msgs/Imu",
            "70 msgs",
            "nav_msgs/Odometry",
            "time time (float32), time in s",
            "ring ring (uint16)",
            "1 x 124668 points",
        ] {
            assert!(text.contains(expected), "{expected} missing from:\n{text}");
        }
        let json: serde_json::Value =
            serde_json::from_str(&ok(&skid(&["bag", "info", "--json", &bag]))).unwrap();
        let topics = json["topics"].as_array().unwrap();
        assert_eq!(topics.len(), 3);
        assert!((json["duration_s"].as_f64().unwrap() - 0.7258).abs() < 1e-3);
    }
}

#[test]
fn bag_info_refuses_what_is_not_a_bag_naming_it() {
    let missing = skid(&["bag", "info", "no/such.bag"]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no/such.bag"));
    let not_a_bag = skid(&["bag", "info", "Cargo.toml"]);
    assert!(!not_a_bag.status.success());
    let error = String::from_utf8_lossy(&not_a_bag.stderr).into_owned();
    assert!(
        error.contains("Cargo.toml") && error.contains("not a ROS 1 bag"),
        "{error}"
    );
}

fn odometry(input: &str, out: &Path, extra: &[&str]) -> String {
    let mut args = vec!["odometry", input, "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    ok(&skid(&args));
    std::fs::read_to_string(out.join("trajectory.kitti")).unwrap()
}

#[test]
fn odometry_on_either_bag_equals_odometry_on_the_kitti_folder() {
    let dir = tempfile::tempdir().unwrap();
    // Without deskewing the scans are the same points, so the trajectories agree bit for bit. The
    // folder has no IMU, so the LiDAR-only odometry is compared on both.
    let lidar_only = ["--set", "odometry.plugin=kiss_icp"];
    let plain = [
        lidar_only.as_slice(),
        &["--set", "odometry.kiss_icp.deskew=false"],
    ]
    .concat();
    let kitti = odometry(
        &data("kitti_00_lidar_frames_0000_0015"),
        &dir.path().join("kitti"),
        &[plain.as_slice(), &["--set", "source.kitti.max_scans=8"]].concat(),
    );
    assert_eq!(kitti.lines().count(), 8);
    // The source's ground truth is written beside the estimate, one pose per registered scan.
    for file in ["ground_truth.tum", "ground_truth.kitti"] {
        let truth = std::fs::read_to_string(dir.path().join("kitti").join(file)).unwrap();
        assert_eq!(truth.lines().filter(|l| !l.starts_with('#')).count(), 8, "{file}");
    }
    assert_eq!(odometry(&ros1_bag(), &dir.path().join("ros1"), &plain), kitti);
    assert_eq!(odometry(&mcap_bag(), &dir.path().join("mcap"), &plain), kitti);
    // With deskewing the bags' per-point times are used, identically from both bags.
    assert_eq!(
        odometry(&ros1_bag(), &dir.path().join("ros1-deskew"), &lidar_only),
        odometry(&mcap_bag(), &dir.path().join("mcap-deskew"), &lidar_only)
    );
}

#[test]
fn auto_odometry_runs_lio_on_a_bag_with_an_imu_and_kiss_icp_on_a_folder_without() {
    let dir = tempfile::tempdir().unwrap();
    let chosen = |input: &str, out: &str, extra: &[&str]| {
        let mut args = vec!["odometry", input, "--out"];
        let out = dir.path().join(out);
        args.push(out.to_str().unwrap());
        args.extend_from_slice(extra);
        let output = skid(&args);
        ok(&output);
        let log = String::from_utf8_lossy(&output.stderr).into_owned();
        let trajectory = std::fs::read_to_string(out.join("trajectory.kitti")).unwrap();
        (log, trajectory)
    };
    let (log, _) = chosen(
        &data("kitti_00_lidar_frames_0000_0015"),
        "kitti",
        &["--set", "source.kitti.max_scans=4"],
    );
    assert!(log.contains("source has no IMU, running kiss_icp"), "{log}");
    let (ros1_log, ros1) = chosen(&ros1_bag(), "ros1", &[]);
    assert!(
        ros1_log.contains("source provides an IMU, running lio"),
        "{ros1_log}"
    );
    // The IMU samples and stamps decode identically from both containers, so lio's estimates agree.
    let (_, mcap) = chosen(&mcap_bag(), "mcap", &[]);
    assert_eq!(ros1.lines().count(), 8);
    assert_eq!(ros1, mcap);
    // Without the IMU topic the bag is LiDAR-only again.
    let (log, _) = chosen(&ros1_bag(), "no-imu", &["--set", "source.bag.imu_topic=\"\""]);
    assert!(log.contains("source has no IMU, running kiss_icp"), "{log}");
}

#[test]
fn two_robots_run_from_a_ros1_and_a_ros2_bag() {
    let dir = tempfile::tempdir().unwrap();
    let bags = dir.path().join("bags");
    std::fs::create_dir_all(&bags).unwrap();
    std::os::unix::fs::symlink(ros1_bag(), bags.join("robot0")).unwrap();
    std::os::unix::fs::symlink(mcap_bag(), bags.join("robot1")).unwrap();
    let path_setting = format!("source.bag.path=\"{}/robot{{robot}}\"", bags.display());
    let output_setting = format!("run.output_dir=\"{}\"", dir.path().join("runs").display());
    let line = ok(&skid(&[
        "run",
        "--set",
        "source.plugin=bag",
        "--set",
        &path_setting,
        "--set",
        "run.robots=2",
        "--set",
        "run.name=bags",
        "--set",
        &output_setting,
    ]));
    let summary: serde_json::Value = serde_json::from_str(line.lines().last().unwrap()).unwrap();
    let run = dir.path().join("runs/bags");
    for file in [
        "metrics.json",
        "summary.json",
        "map.ply",
        "robot0/trajectory.tum",
        "robot1/ground_truth.tum",
    ] {
        assert!(run.join(file).is_file(), "{file} missing");
    }
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("metrics.json")).unwrap()).unwrap();
    for robot in 0..2 {
        assert_eq!(summary["robots"][robot]["scans"], 8);
        let trajectory = &metrics["robots"][robot]["trajectory"];
        assert_eq!(
            trajectory["ate_m"]["count"], 8,
            "robot {robot}: evaluated against the bag's ground truth"
        );
        assert!(trajectory["ate_m"]["rmse"].as_f64().unwrap() < 1.0);
        // Both robots drive the same road: their descriptors meet across the two bag formats.
        assert!(
            summary["robots"][robot]["loops"]["candidates_inter"]
                .as_u64()
                .unwrap()
                >= 1
        );
    }
}
