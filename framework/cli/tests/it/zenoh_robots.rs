//! Three robots of one fleet as three `skid run --set deploy.robot=i` processes on 127.0.0.1, talking
//! through the `zenoh` transport with explicit endpoints (issue 9, items 4 and 6): each process simulates
//! its robot of the shared world, and from each one's `summary.json` the robots exchanged descriptors,
//! fetched each other's clouds for loop candidates and agreed on inter-robot loops (the distributed
//! SKiD-SLAM pipeline, Sec. III of the paper). A second run kills robot 1 mid-run and restarts it: the
//! other robots keep running and finish, and the restarted robot catches up and finds its loops.
//!
//! The links are mutual TLS with certificates from `skid fleet certs` (issue #20). A third run adds a
//! fourth, rogue process to a fleet (this test process, with three zenoh sessions): one whose
//! certificate another CA signed, one with a fleet certificate that publishes under another robot's id,
//! and a fleet robot that floods malformed, replayed and hostile messages. The fleet ends with the same
//! pose graphs as a run without the rogue, and every refusal is counted in `summary.json`.
//!
//! The world and route are chosen so all three robots' paths overlap within ~12 s of flight: an aerial
//! route in the urban world where robots 0 and 2 fly together and robot 1 flies the same street towards
//! them. VLP-16 scans, ground-truth odometry, no coarse registration keep the processes light.

#[path = "zenoh_robots/rogue.rs"]
mod rogue;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const SCANS: u64 = 130;

/// How long a robot of the first two fleets answers at most after its source ends; they stop sooner,
/// once every robot of the fleet says it is settled.
const LINGER_CAP_S: f64 = 60.0;

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

struct Fleet {
    out: tempfile::TempDir,
    ports: [u16; 3],
    prefix: String,
    /// The fleet's certificates (`skid fleet certs`), for robots `0..robots`.
    certs: PathBuf,
    /// `run.robots`: the fleet the access control admits (three processes run).
    robots: u32,
}

impl Fleet {
    fn new(name: &str, robots: u32) -> Self {
        let out = tempfile::tempdir().unwrap();
        let certs = out.path().join("certs");
        let made = Command::new(env!("CARGO_BIN_EXE_skid"))
            .args(["fleet", "certs", "--robots", &robots.to_string()])
            .arg(&certs)
            .output()
            .unwrap();
        assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
        Self {
            out,
            ports: skid_testkit::net::free_tcp_ports::<3>(),
            prefix: format!("skidtest/{name}/{}", std::process::id()),
            certs,
            robots,
        }
    }

    /// Starts robot `robot`'s process, lingering `linger_s` after its source ends.
    fn spawn(&self, robot: usize, linger_s: f64) -> RobotProcess {
        let endpoint = |port: u16| format!("\"tls/127.0.0.1:{port}\"");
        let file = |name: String| format!("\"{}\"", self.certs.join(name).display());
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
            format!("transport.zenoh.tls.ca_certificate={}", file("ca.pem".into())),
            format!(
                "transport.zenoh.tls.certificate={}",
                file(format!("robot-{robot}.pem"))
            ),
            format!(
                "transport.zenoh.tls.private_key={}",
                file(format!("robot-{robot}.key"))
            ),
            format!("run.output_dir={}", self.out.path().display()),
            "run.name=zenoh".to_owned(),
            format!("run.robots={}", self.robots),
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
            // These processes test the transport, so the verifier is classic PCM: with loops as scarce as
            // a slow machine's real-time run leaves them, the earned-merge rules (tested on their own)
            // may rightly withhold a robot's only merge.
            "verifier.pcm.consistency.min_spread_m=0".to_owned(),
            "verifier.pcm.consistency.dominance_ratio=0".to_owned(),
        ];
        let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
        command
            .current_dir(repo())
            .env_remove("RUST_LOG")
            .arg("run")
            .stdout(Stdio::null());
        static SPAWNED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let number = SPAWNED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let log = self.out.path().join(format!("robot{robot}-{number}.log"));
        command.stderr(std::fs::File::create(&log).unwrap());
        for set in &sets {
            command.arg("--set").arg(set);
        }
        RobotProcess {
            child: command.spawn().expect("skid starts"),
            log,
        }
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

/// A robot's process, its stderr going to a file (a pipe read only at the end would fill and block a
/// chatty process).
struct RobotProcess {
    child: Child,
    log: PathBuf,
}

/// Waits for a process to exit (killing it after `limit`) and returns its stderr; panics on failure.
fn finish(process: RobotProcess, robot: usize, limit: Duration) -> String {
    let RobotProcess { mut child, log } = process;
    let started = Instant::now();
    let read_log = || without_ansi(&String::from_utf8_lossy(&std::fs::read(&log).unwrap_or_default()));
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let stderr = read_log();
            assert!(status.success(), "robot {robot} failed ({status}):\n{stderr}");
            return stderr;
        }
        if started.elapsed() > limit {
            child.kill().unwrap();
            let stderr = read_log();
            let tail: String = stderr.lines().rev().take(40).collect::<Vec<_>>().join("\n");
            eprintln!("robot {robot}'s last log lines (newest first):\n{tail}");
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
    let fleet = Fleet::new("three", 3);
    // Each robot answers its peers for up to a minute after its last scan: on a loaded machine a robot
    // that verifies many loops falls well behind real time, and finds its loops with robot 1 (whose
    // scans may all be made before that robot's descriptors of the shared street arrive) after robot
    // 1's source has ended. The robots stop sooner, once all three say they are settled.
    let children: Vec<RobotProcess> = (0..3).map(|robot| fleet.spawn(robot, LINGER_CAP_S)).collect();
    let mut clouds_fetched = 0;
    let mut found_total = 0;
    for (robot, child) in children.into_iter().enumerate() {
        let stderr = finish(child, robot, Duration::from_secs(240));
        assert!(
            stderr.contains("every robot of the fleet is settled"),
            "robot {robot} lingered to the end instead of stopping with the fleet:\n{stderr}"
        );
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
    let fleet = Fleet::new("restart", 3);
    // Every robot lingers long enough to serve the others to their ends: on a loaded machine a robot
    // that verifies many loops falls well behind real time, and finds its loops with robot 1 after
    // robot 1's source has ended.
    let first = fleet.spawn(0, LINGER_CAP_S);
    let third = fleet.spawn(2, LINGER_CAP_S);
    let mut second = fleet.spawn(1, 4.0);
    std::thread::sleep(Duration::from_secs(4));
    assert!(
        second.child.try_wait().unwrap().is_none(),
        "robot 1 ended before it was killed"
    );
    second.child.kill().unwrap();
    second.child.wait().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let restarted = fleet.spawn(1, LINGER_CAP_S);
    let restarted_log = finish(restarted, 1, Duration::from_secs(240));
    let first_log = finish(first, 0, Duration::from_secs(240));
    let third_log = finish(third, 2, Duration::from_secs(240));
    // Every robot's loops are printed before any is checked, so a failure shows the whole fleet.
    let summaries: Vec<serde_json::Value> = (0..3).map(|robot| fleet.summary(robot)).collect();
    for (robot, summary) in summaries.iter().enumerate() {
        eprintln!("robot {robot}'s loops: {}", summary["robots"][0]["loops"]);
    }
    check_robot(&summaries[1], 1, &restarted_log);
    for (robot, stderr) in [(0, first_log), (2, third_log)] {
        check_robot(&summaries[robot], robot, &stderr);
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

/// One robot's pose graph as its run wrote it: keyframe vertices and loop edges.
#[derive(Debug, PartialEq)]
struct GraphShape {
    vertices: std::collections::BTreeSet<u64>,
    edges: std::collections::BTreeSet<(u64, u64)>,
}

impl Fleet {
    fn graph(&self, robot: usize) -> GraphShape {
        let path = self
            .out
            .path()
            .join(format!("zenoh-robot{robot}"))
            .join(format!("robot{robot}"))
            .join("pose_graph.g2o");
        let (graph, _) = skid_io::g2o::read_g2o_3d(&path, &Default::default()).unwrap();
        GraphShape {
            vertices: graph.vertices.keys().copied().collect(),
            edges: graph.edges.iter().map(|edge| (edge.from, edge.to)).collect(),
        }
    }

    /// Runs the three robot processes to their end; returns each one's stderr.
    fn run_all(&self, linger_s: f64) -> Vec<String> {
        let children: Vec<RobotProcess> = (0..3).map(|robot| self.spawn(robot, linger_s)).collect();
        children
            .into_iter()
            .enumerate()
            .map(|(robot, child)| finish(child, robot, Duration::from_secs(240)))
            .collect()
    }
}

/// The id a g2o vertex of robot `robot` has (`robot · 10⁶ + keyframe`).
fn robot_of_vertex(vertex: u64) -> u64 {
    vertex / 1_000_000
}

/// How long the robots of the rogue test answer after their source ends. Robot 1 raises no candidates
/// of its own on this route (it passes each place first), so its inter-robot loops are the ones robots 0
/// and 2 verify and share; on a slow build under the flood that can come well after robot 1's own
/// scans are done, and it must still be listening.
const LINGER_S: f64 = 20.0;

#[test]
fn a_rogue_process_changes_no_graph_and_every_refusal_is_counted() {
    let _turn = one_fleet_at_a_time();
    // The access control admits robots 0..4; robot 3 is the rogue's.
    let clean = Fleet::new("clean", 4);
    clean.run_all(LINGER_S);
    let attacked = Fleet::new("attacked", 4);
    let foreign = attacked.out.path().join("foreign-ca");
    skid_transport_zenoh::write_fleet_certificates(&foreign, 4, 1).unwrap();
    let children: Vec<RobotProcess> = (0..3).map(|robot| attacked.spawn(robot, LINGER_S)).collect();
    let rogue = rogue::Rogue::start(&attacked.certs, &foreign, &attacked.ports, &attacked.prefix);
    let stderrs: Vec<String> = children
        .into_iter()
        .enumerate()
        .map(|(robot, child)| finish(child, robot, Duration::from_secs(240)))
        .collect();
    let (stranger, sent) = rogue.stop();
    eprintln!("the rogue sent {sent} messages");
    assert!(
        stranger.alive_peers().is_empty(),
        "the stranger reached a fleet robot"
    );
    for robot in 0..3u64 {
        let index = robot as usize;
        let (with_rogue, without) = (attacked.graph(index), clean.graph(index));
        // Real-time processes are not repeatable loop for loop (when a descriptor arrives decides which
        // candidates are tried), so the graphs are compared on what the rogue could have changed: the
        // robot's own keyframes, anything of robot 3's, and how accurate the optimised trajectory is.
        let own = |graph: &GraphShape| -> Vec<u64> {
            graph
                .vertices
                .iter()
                .copied()
                .filter(|&v| robot_of_vertex(v) == robot)
                .collect()
        };
        assert_eq!(
            own(&with_rogue),
            own(&without),
            "robot {robot}'s keyframes changed"
        );
        assert!(
            !with_rogue.vertices.iter().any(|&v| robot_of_vertex(v) == 3)
                && !with_rogue
                    .edges
                    .iter()
                    .any(|&(a, b)| robot_of_vertex(a) == 3 || robot_of_vertex(b) == 3),
            "robot 3 reached robot {robot}'s graph:\n{}",
            stderrs[index]
        );
        let inter_robot = with_rogue
            .edges
            .iter()
            .filter(|&&(a, b)| robot_of_vertex(a) != robot_of_vertex(b));
        let me = &attacked.summary(index)["robots"][0];
        assert!(
            inter_robot.count() > 0,
            "robot {robot} has no inter-robot loop under attack; its loops: {}, messages: {}",
            me["loops"],
            me["messages"]
        );
        let ate =
            |summary: &serde_json::Value| summary["robots"][0]["ate_first_pose_aligned_m"].as_f64().unwrap();
        let (ate_attacked, ate_clean) = (ate(&attacked.summary(index)), ate(&clean.summary(index)));
        eprintln!(
            "robot {robot}: ATE {ate_attacked:.3} m (without the rogue {ate_clean:.3} m) loops {} refusals {} \
             faults {} rejected {} duplicates {}",
            me["loops"],
            me["transport_refusals"],
            me["peer_faults"],
            me["messages"]["rejected"],
            me["messages"]["duplicates"]
        );
        // Two real-time runs differ by centimetres; one forged 50 m loop would cost metres.
        assert!(
            ate_attacked <= ate_clean + 0.25,
            "robot {robot}'s trajectory got worse under attack"
        );
        assert!(
            count(me, &["transport_refusals", "access_denied robot-3"]) > 0,
            "impostor not counted"
        );
        assert!(count(me, &["messages", "rejected", "robot_mismatch", "messages"]) > 0);
        assert!(count(me, &["messages", "rejected", "bad_magic", "messages"]) > 0);
        assert!(
            count(me, &["messages", "duplicates", "messages"]) > 0,
            "replays not counted"
        );
        for class in [
            "descriptor_wrong_kind",
            "descriptor_refused",
            "loop_not_shared",
            "cloud_unrequested",
            "clock_offset",
        ] {
            assert!(
                count(me, &["peer_faults", class]) > 0,
                "robot {robot}: {class} not counted"
            );
        }
        let malformed_lines = stderrs[index]
            .lines()
            .filter(|l| l.contains("malformed message dropped"))
            .count();
        assert!(
            malformed_lines < 100,
            "{malformed_lines} warnings about malformed messages: not rate-limited"
        );
    }
    let robot_0 = &attacked.summary(0)["robots"][0];
    assert!(count(robot_0, &["peer_faults", "loop_unknown_keyframe"]) > 0);
}
