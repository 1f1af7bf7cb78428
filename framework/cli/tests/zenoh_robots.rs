//! Three robots of one fleet as three `skid run --set deploy.robot=i` processes on 127.0.0.1, talking
//! through the `zenoh` transport with explicit endpoints (issue 9, items 4 and 6): each process simulates
//! its robot of the shared world, and from each one's `summary.json` the robots exchanged descriptors,
//! fetched each other's clouds for loop candidates and agreed on inter-robot loops (the distributed
//! SKiD-SLAM pipeline, Sec. III of the paper). A second run kills robot 1 mid-run and restarts it: the
//! other robots keep running and finish, and the restarted robot catches up and finds its loops.
//!
//! The world and route are chosen so all three robots' paths overlap within ~12 s of flight: an aerial
//! route in the urban world where robots 0 and 2 fly together and robot 1 flies the same street towards
//! them. VLP-16 scans, ground-truth odometry, no coarse registration keep the processes light.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const SCANS: u64 = 130;

/// The fleets of the tests below run one at a time: each is three processes in real time, and two at
/// once on a 2-core machine would starve the robots of the time their exchanges need.
static ONE_FLEET_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_fleet_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    ONE_FLEET_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Three TCP ports free right now on 127.0.0.1.
fn free_ports() -> [u16; 3] {
    let listeners: Vec<std::net::TcpListener> = (0..3)
        .map(|_| std::net::TcpListener::bind("127.0.0.1:0").unwrap())
        .collect();
    let ports: Vec<u16> = listeners.iter().map(|l| l.local_addr().unwrap().port()).collect();
    [ports[0], ports[1], ports[2]]
}

struct Fleet {
    out: tempfile::TempDir,
    ports: [u16; 3],
    prefix: String,
}

impl Fleet {
    fn new(name: &str) -> Self {
        Self {
            out: tempfile::tempdir().unwrap(),
            ports: free_ports(),
            prefix: format!("skidtest/{name}/{}", std::process::id()),
        }
    }

    /// Starts robot `robot`'s process, lingering `linger_s` after its source ends.
    fn spawn(&self, robot: usize, linger_s: f64) -> Child {
        let endpoint = |port: u16| format!("\"tcp/127.0.0.1:{port}\"");
        let peers: Vec<String> = (0..3)
            .filter(|&i| i != robot)
            .map(|i| endpoint(self.ports[i]))
            .collect();
        let sets = [
            format!("deploy.robot={robot}"),
            format!("deploy.linger_s={linger_s}"),
            "deploy.playback_speed=2".to_owned(),
            "transport.plugin=zenoh".to_owned(),
            format!("transport.zenoh.listen=[{}]", endpoint(self.ports[robot])),
            format!("transport.zenoh.connect=[{}]", peers.join(",")),
            format!("transport.zenoh.key_prefix=\"{}\"", self.prefix),
            format!("run.output_dir={}", self.out.path().display()),
            "run.name=zenoh".to_owned(),
            "run.robots=3".to_owned(),
            "run.threads=1".to_owned(),
            format!("run.max_scans={SCANS}"),
            "source.sim.world=urban".to_owned(),
            "source.sim.mission=shared_route".to_owned(),
            "source.sim.profile=aerial".to_owned(),
            "source.sim.sensor=vlp16".to_owned(),
            "source.sim.speed_mps=6".to_owned(),
            "source.sim.route_length_m=50".to_owned(),
            "odometry.plugin=ground_truth".to_owned(),
            "odometry.ground_truth.keyframe.distance_m=0.75".to_owned(),
            "coarse.plugin=none".to_owned(),
        ];
        let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
        command
            .current_dir(repo())
            .env_remove("RUST_LOG")
            .arg("run")
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        for set in &sets {
            command.arg("--set").arg(set);
        }
        command.spawn().expect("skid starts")
    }

    fn summary(&self, robot: usize) -> serde_json::Value {
        let path = self
            .out
            .path()
            .join(format!("zenoh-robot{robot}"))
            .join("summary.json");
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
    }
}

/// Waits for a process to exit (killing it after `limit`) and returns its stderr; panics on failure.
fn finish(mut child: Child, robot: usize, limit: Duration) -> String {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut stderr = String::new();
            if let Some(mut pipe) = child.stderr.take() {
                std::io::Read::read_to_string(&mut pipe, &mut stderr).unwrap();
            }
            let stderr = without_ansi(&stderr);
            assert!(status.success(), "robot {robot} failed ({status}):\n{stderr}");
            return stderr;
        }
        if started.elapsed() > limit {
            child.kill().unwrap();
            panic!("robot {robot} did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The text without terminal colour sequences (the log is coloured even through a pipe).
fn without_ansi(text: &str) -> String {
    let mut plain = String::with_capacity(text.len());
    let mut chars = text.chars();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            // Skip `ESC [ ... letter`.
            for c in chars.by_ref() {
                if c.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            plain.push(c);
        }
    }
    plain
}

fn count(value: &serde_json::Value, path: &[&str]) -> u64 {
    path.iter().fold(value, |v, key| &v[*key]).as_u64().unwrap_or(0)
}

/// Checks one robot's summary: all scans read, descriptors received from peers, and inter-robot loops
/// (found here or accepted by a peer and received); returns (loops found here, loops received).
fn check_robot(summary: &serde_json::Value, robot: usize, stderr: &str) -> (u64, u64) {
    let me = &summary["robots"][0];
    assert_eq!(count(me, &["robot"]), robot as u64);
    assert_eq!(count(me, &["scans"]), SCANS, "robot {robot}:\n{stderr}");
    let descriptors = count(me, &["messages", "received", "descriptors", "messages"]);
    assert!(descriptors > 0, "robot {robot} heard no descriptors:\n{stderr}");
    eprintln!(
        "robot {robot}: loops {} received {}",
        me["loops"], me["messages"]["received"]
    );
    let found = count(me, &["loops", "accepted_inter"]);
    let received = count(me, &["loops", "received_from_peers"]);
    assert!(
        found + received > 0,
        "robot {robot} has no inter-robot loop: {}\n{stderr}",
        me["loops"]
    );
    (found, received)
}

#[test]
fn three_robot_processes_find_each_others_loops_over_zenoh() {
    let _turn = one_fleet_at_a_time();
    let fleet = Fleet::new("three");
    // Each robot answers its peers for 8 s after its last scan, so a loop robot 1 finds on its last
    // keyframes still gets the peers' clouds on a loaded machine.
    let children: Vec<Child> = (0..3).map(|robot| fleet.spawn(robot, 8.0)).collect();
    let mut clouds_fetched = 0;
    let mut found_total = 0;
    for (robot, child) in children.into_iter().enumerate() {
        let stderr = finish(child, robot, Duration::from_secs(240));
        let summary = fleet.summary(robot);
        let (found, _) = check_robot(&summary, robot, &stderr);
        found_total += found;
        clouds_fetched += count(
            &summary["robots"][0],
            &["messages", "received", "cloud", "messages"],
        );
    }
    assert!(found_total > 0, "no robot verified a loop itself");
    assert!(clouds_fetched > 0, "no cloud was fetched");
}

#[test]
fn a_killed_robot_process_restarts_and_the_others_finish() {
    let _turn = one_fleet_at_a_time();
    let fleet = Fleet::new("restart");
    // Robots 0 and 2 linger long enough to serve the restarted robot 1 to its end.
    let first = fleet.spawn(0, 20.0);
    let third = fleet.spawn(2, 20.0);
    let mut second = fleet.spawn(1, 4.0);
    std::thread::sleep(Duration::from_secs(4));
    assert!(
        second.try_wait().unwrap().is_none(),
        "robot 1 ended before it was killed"
    );
    second.kill().unwrap();
    second.wait().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let restarted = fleet.spawn(1, 8.0);
    let stderr = finish(restarted, 1, Duration::from_secs(240));
    let summary = fleet.summary(1);
    check_robot(&summary, 1, &stderr);
    for (robot, child) in [(0, first), (2, third)] {
        let stderr = finish(child, robot, Duration::from_secs(240));
        check_robot(&fleet.summary(robot), robot, &stderr);
        // The peer saw robot 1 come back with a new session (and caught it up).
        assert!(
            stderr.contains("peer session started") && stderr.contains("restarted=true"),
            "robot {robot} did not notice the restart:\n{stderr}"
        );
    }
    assert_restarted_log(&fleet.out.path().join("zenoh-robot1"));
}

/// The restarted robot wrote its own outputs.
fn assert_restarted_log(folder: &Path) {
    assert!(folder.join("config.toml").is_file());
    assert!(folder.join("robot1").join("trajectory.tum").is_file());
}

#[test]
fn a_robot_outside_the_fleet_is_refused() {
    let output = Command::new(env!("CARGO_BIN_EXE_skid"))
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .args(["run", "--set", "run.robots=3", "--set", "deploy.robot=3"])
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = without_ansi(&String::from_utf8_lossy(&output.stderr));
    assert!(
        stderr.contains("deploy.robot = 3") && stderr.contains("expected 0 to 2"),
        "{stderr}"
    );
}
