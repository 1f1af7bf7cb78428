//! Live ROS 2 output (`output.ros2 = true`): a two-robot run on the real KITTI excerpt publishes each
//! robot's odometry, `/tf`, optimised path, map and loops on zenoh with rmw_zenoh's keys, and an
//! independent listener (`tests/fixtures/listen_ros2.py`: eclipse-zenoh, and rosbags' ROS 2 Jazzy type
//! store to decode the CDR, with `$SKID_PYTHON`) receives and decodes them: the types and their hashes,
//! the attachments, the frames, the path of every scan, a map and the loop markers, a robot's place in
//! the prior map it localises in and its standing there, and the liveliness tokens that put the node
//! and its publishers in the ROS graph.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn an_independent_listener_decodes_every_robots_live_topics() {
    let out = tempfile::tempdir().unwrap();
    let port = skid_testkit::net::free_tcp_ports::<1>()[0];
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let summary_path = out.path().join("heard.json");
    let python = std::env::var("SKID_PYTHON").unwrap_or_else(|_| "python3".to_owned());
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/listen_ros2.py");
    let mut listener = Command::new(&python)
        .arg(&script)
        .arg(&endpoint)
        .arg("0")
        .arg(&summary_path)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut ready = String::new();
    BufReader::new(listener.stdout.take().unwrap())
        .read_line(&mut ready)
        .unwrap();
    assert_eq!(
        ready.trim(),
        "ready",
        "the listener (SKID_PYTHON needs eclipse-zenoh and rosbags) did not start"
    );

    // The same snippet mapped first: the live run localises in it (beside its own SLAM) and publishes
    // where each robot's map sits in the prior's.
    let mapped = Command::new(env!("CARGO_BIN_EXE_skid"))
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .args(["-q", "run"])
        .args(["--set", "run.robots=2", "--set", "run.name=mapped"])
        .arg("--set")
        .arg(format!("run.output_dir={}", out.path().display()))
        .args([
            "--set",
            "source.plugin=kitti",
            "--set",
            "source.kitti.split.enabled=true",
        ])
        .args(["--set", "coarse.plugin=none", "--set", "output.record=false"])
        .output()
        .unwrap();
    assert!(
        mapped.status.success(),
        "{}",
        String::from_utf8_lossy(&mapped.stderr)
    );

    let sets = [
        "run.robots=2".to_owned(),
        "run.name=live".to_owned(),
        format!("prior.path={}", out.path().join("mapped").display()),
        "prior.own_loops=true".to_owned(),
        format!("run.output_dir={}", out.path().display()),
        "source.plugin=kitti".to_owned(),
        "source.kitti.split.enabled=true".to_owned(),
        "coarse.plugin=none".to_owned(),
        "verifier.pcm.consistency.min_loops_before_decision=1".to_owned(),
        // One loop on a 16-scan snippet: the spread a merge needs between robots is waived here.
        "verifier.pcm.consistency.min_spread_m=0".to_owned(),
        "output.record=false".to_owned(),
        "output.ros2=true".to_owned(),
        format!("output.ros2_connect=[\"{endpoint}\"]"),
    ];
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .args(["-q", "run"]);
    for set in &sets {
        command.args(["--set", set]);
    }
    let output = command.output().unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    drop(listener.stdin.take());
    assert!(listener.wait().unwrap().success(), "the listener failed");
    let heard: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary_path).unwrap()).unwrap();
    let topics = &heard["topics"];

    for robot in 0..2 {
        let scans = summary["robots"][robot]["scans"].as_u64().unwrap();
        let name = format!("robot{robot}");
        let expect = |topic: &str, kind: &str| {
            let entry = &topics[format!("/{name}/{topic}")];
            assert_eq!(entry["type"], kind, "/{name}/{topic}: {heard}");
            assert_eq!(
                entry["hash_ok"], true,
                "/{name}/{topic}: the key's type hash is not Jazzy's"
            );
            assert_eq!(entry["attachments_ok"], true, "/{name}/{topic}: attachment");
            let sequences: Vec<u64> = entry["sequences"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| s.as_u64().unwrap())
                .collect();
            assert!(
                sequences.windows(2).all(|w| w[0] < w[1]),
                "/{name}/{topic}: sequence numbers {sequences:?}"
            );
            entry.clone()
        };
        let odometry = expect("odometry", "nav_msgs/msg/Odometry");
        // The listener is subscribed before the run starts; on loopback nothing is dropped.
        assert_eq!(odometry["count"].as_u64().unwrap(), scans, "/{name}/odometry");
        assert_eq!(odometry["first"]["frame"], format!("{name}/odom"));
        assert_eq!(odometry["first"]["child"], format!("{name}/base_link"));
        let path = expect("path", "nav_msgs/msg/Path");
        assert_eq!(path["last"]["frame"], format!("{name}/map"));
        assert_eq!(
            path["last"]["poses"].as_u64().unwrap(),
            scans,
            "the final path holds every scan"
        );
        let map = expect("map", "sensor_msgs/msg/PointCloud2");
        assert!(map["last"]["points"].as_u64().unwrap() > 1000, "{map}");
        assert_eq!(map["last"]["frame"], format!("{name}/map"));
        let loops = expect("loops", "visualization_msgs/msg/MarkerArray");
        let namespaces = loops["last"]["namespaces"].to_string();
        assert!(
            namespaces.contains("accepted") && namespaces.contains("undecided"),
            "{namespaces}"
        );
    }
    // One loop joined the robots: robot 1's graph holds robot 0's keyframes and draws them.
    let loops = &topics["/robot1/loops"]["last"];
    assert!(loops["namespaces"].to_string().contains("peer robot0"), "{loops}");
    assert!(loops["points"].as_u64().unwrap() >= 2, "{loops}");
    let tf = &topics["/tf"];
    assert_eq!(tf["type"], "tf2_msgs/msg/TFMessage");
    assert_eq!(tf["hash_ok"], true);
    let pairs = tf["last"]["pairs"].to_string();
    assert!(
        pairs.contains("odom") && pairs.contains("base_link") && pairs.contains("/map"),
        "{pairs}"
    );
    // Robot 0 is localised in the prior: `/tf` places its map in `prior/map`, and its standing says so.
    let all_pairs = tf["all_pairs"].to_string();
    assert!(all_pairs.contains(r#"["prior/map","robot0/map"]"#), "{all_pairs}");
    let standing = &topics["/robot0/localisation"];
    assert_eq!(standing["type"], "std_msgs/msg/String");
    assert_eq!(standing["hash_ok"], true);
    let last: serde_json::Value = serde_json::from_str(standing["last"]["data"].as_str().unwrap()).unwrap();
    assert_eq!(last["localised"], true, "{last}");
    assert_eq!(
        summary["robots"][0]["localisation"]["localised"], true,
        "{summary}"
    );

    // The ROS graph: a node per robot and a publisher token per topic, as rmw_zenoh writes them.
    let tokens: Vec<String> = heard["tokens"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_str().unwrap().to_owned())
        .collect();
    for robot in 0..2 {
        let node = format!("/NN/%/%robot{robot}/skid");
        assert!(
            tokens
                .iter()
                .any(|t| t.starts_with("@ros2_lv/0/") && t.ends_with(&node)),
            "{tokens:?}"
        );
        for topic in ["odometry", "path", "map", "loops"] {
            let publisher = format!("/MP/%/%robot{robot}/skid/%robot{robot}%{topic}/");
            assert!(
                tokens.iter().any(|t| t.contains(&publisher)),
                "{publisher} in {tokens:?}"
            );
        }
    }
}
