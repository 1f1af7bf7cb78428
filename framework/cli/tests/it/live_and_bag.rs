//! Two robots of one fleet as two `skid run --set deploy.robot=i` processes over the `zenoh` transport:
//! robot 0's scans arrive live through the `ros2` source from an independent publisher that plays the
//! shared KITTI MCAP bag the way a ROS 2 node on rmw_zenoh publishes (`tests/fixtures/replay_live.py`,
//! eclipse-zenoh + rosbags, run with `$SKID_PYTHON`), robot 1's come from the ROS 1 bag of the same drive.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn wait(mut child: Child, what: &str, limit: Duration) -> String {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut stderr = String::new();
            if let Some(mut pipe) = child.stderr.take() {
                std::io::Read::read_to_string(&mut pipe, &mut stderr).unwrap();
            }
            assert!(status.success(), "{what} failed ({status}):\n{stderr}");
            return stderr;
        }
        if started.elapsed() > limit {
            child.kill().unwrap();
            panic!("{what} did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn one_robot_live_over_rmw_zenoh_and_one_from_a_bag() {
    let out = tempfile::tempdir().unwrap();
    let [live_port, port0, port1] = skid_testkit::net::free_tcp_ports::<3>();
    let endpoint = |port: u16| format!("\"tcp/127.0.0.1:{port}\"");
    let data = |relative: &str| skid_io::data_path(relative).unwrap().display().to_string();
    let robot = |index: usize, source: &[String]| {
        let (mine, peer) = if index == 0 {
            (port0, port1)
        } else {
            (port1, port0)
        };
        let mut sets = vec![
            format!("deploy.robot={index}"),
            "deploy.linger_s=3".to_owned(),
            "transport.plugin=zenoh".to_owned(),
            // Plain TCP on loopback, asked for by name (the fleet tests cover mutual TLS).
            "transport.zenoh.security=\"plain_tcp\"".to_owned(),
            format!("transport.zenoh.listen=[{}]", endpoint(mine)),
            format!("transport.zenoh.connect=[{}]", endpoint(peer)),
            format!(
                "transport.zenoh.key_prefix=\"skidtest/live/{}\"",
                std::process::id()
            ),
            format!("run.output_dir=\"{}\"", out.path().display()),
            "run.name=live".to_owned(),
            "run.robots=2".to_owned(),
            "run.threads=1".to_owned(),
        ];
        sets.extend_from_slice(source);
        let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
        command
            .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../.."))
            .env_remove("RUST_LOG")
            .arg("run")
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        for set in &sets {
            command.arg("--set").arg(set);
        }
        command.spawn().unwrap()
    };
    let live = robot(
        0,
        &[
            "source.plugin=ros2".to_owned(),
            "source.ros2.points_topic=\"/robot{robot}/velodyne_points\"".to_owned(),
            "source.ros2.imu_topic=\"/robot{robot}/imu/data\"".to_owned(),
            "source.ros2.connect=[]".to_owned(),
            format!("source.ros2.listen=[{}]", endpoint(live_port)),
            "source.ros2.idle_timeout_s=4".to_owned(),
        ],
    );
    let recorded = robot(
        1,
        &[
            "source.plugin=bag".to_owned(),
            format!(
                "source.bag.path=\"{}\"",
                data("kitti_00_rosbags/kitti00_velodyne_ros1-lz4.bag")
            ),
        ],
    );
    let python = std::env::var("SKID_PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/replay_live.py");
    let publisher = Command::new(&python)
        .arg(&script)
        .arg(format!("tcp/127.0.0.1:{live_port}"))
        .arg("robot0")
        .arg(data("kitti_00_rosbags/kitti00_velodyne_mcap"))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait(
        publisher,
        "the live publisher (SKID_PYTHON needs eclipse-zenoh and rosbags)",
        Duration::from_secs(120),
    );
    let live_log = wait(live, "robot 0 (live)", Duration::from_secs(120));
    let bag_log = wait(recorded, "robot 1 (bag)", Duration::from_secs(120));
    for (index, log) in [(0, &live_log), (1, &bag_log)] {
        let path = out.path().join(format!("live-robot{index}/summary.json"));
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let me = &summary["robots"][0];
        assert_eq!(me["scans"], 8, "robot {index}:\n{log}");
        let heard = me["messages"]["received"]["descriptors"]["messages"]
            .as_u64()
            .unwrap_or(0);
        assert!(
            heard > 0,
            "robot {index} heard no descriptors from its peer:\n{log}"
        );
    }
}
