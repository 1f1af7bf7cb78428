//! The zenoh transport on 127.0.0.1: the transport conformance suite, configuration checks, and three
//! robots as separate OS processes (this test binary re-run in a child role) exchanging protocol
//! messages, with one robot killed and restarted while the other two keep running.

use skid_testkit::net::free_tcp_ports;
use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use skid_core::slots::{Destination, Transport};
use skid_core::{Params, PluginContext, Registry, RobotId};
use skid_protocol::*;
use skid_transport_zenoh::*;

fn endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

/// Plain TCP, asked for explicitly (the mutual-TLS transport has its own tests in `mutual_tls.rs`).
fn config(listen: u16, connect: &[u16], prefix: &str) -> ZenohConfig {
    ZenohConfig {
        listen: vec![endpoint(listen)],
        connect: connect.iter().map(|&p| endpoint(p)).collect(),
        key_prefix: prefix.into(),
        security: Security::PlainTcp,
        ..ZenohConfig::default()
    }
}

/// Robots in the fleets of these tests.
const FLEET_SIZE: u32 = 3;

#[test]
fn conformance_over_localhost() {
    let (pa, pb) = {
        let [a, b] = free_tcp_ports::<2>();
        (a, b)
    };
    let prefix = format!("skid-test-{}", std::process::id());
    let mut a = ZenohTransport::open(RobotId(0), config(pa, &[], &prefix), FLEET_SIZE).unwrap();
    let mut b = ZenohTransport::open(RobotId(1), config(pb, &[pa], &prefix), FLEET_SIZE).unwrap();
    assert!(a.wait_for_peers(&[RobotId(1)], Duration::from_secs(5)).unwrap());
    assert!(b.wait_for_peers(&[RobotId(0)], Duration::from_secs(5)).unwrap());
    skid_testkit::transport::check_transport(&mut a, &mut b);
    // Oversized messages are refused by the sender.
    let limit = ZenohConfig::default().max_message_bytes;
    assert!(a.send(Destination::AllPeers, &vec![0; limit + 1]).is_err());
    // A robot that closes disappears from its peers' liveliness view.
    drop(b);
    let deadline = Instant::now() + Duration::from_secs(5);
    while a.alive_peers().contains(&RobotId(1)) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(!a.alive_peers().contains(&RobotId(1)), "a closed peer leaves");
}

#[test]
fn registry_and_config_checks() {
    let mut registry = Registry::new();
    register(&mut registry).unwrap();
    let typo = Params::from_toml_str("listn = [\"tcp/127.0.0.1:1\"]").unwrap();
    assert!(registry.transport.parse("zenoh", &typo).is_err());
    let nowhere = Params::from_toml_str("listen = []\nconnect = []").unwrap();
    assert!(
        registry
            .transport
            .create("zenoh", &nowhere, &PluginContext::default())
            .is_err()
    );
    let wildcard = Params::from_toml_str("key_prefix = \"skid/*\"").unwrap();
    assert!(
        registry
            .transport
            .create("zenoh", &wildcard, &PluginContext::default())
            .is_err()
    );
    let port = free_tcp_ports::<1>()[0];
    let plain_unasked = Params::from_toml_str(&format!("listen = [\"{}\"]", endpoint(port))).unwrap();
    let error = registry
        .transport
        .create("zenoh", &plain_unasked, &PluginContext::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("plain_tcp"),
        "plain TCP only when asked for: {error}"
    );
    let good = Params::from_toml_str(&format!(
        "listen = [\"{}\"]\nsecurity = \"plain_tcp\"",
        endpoint(port)
    ))
    .unwrap();
    let transport = registry
        .transport
        .create("zenoh", &good, &PluginContext::default())
        .unwrap();
    assert_eq!(transport.local_robot(), RobotId(0));
}

// ---------------------------------------------------------------------------------------------------
// Three robots in three processes.

const ROLE: &str = "SKID_ZENOH_TEST_ROBOT";
const PORTS: &str = "SKID_ZENOH_TEST_PORTS";
const PREFIX: &str = "SKID_ZENOH_TEST_PREFIX";

/// The child role: robot `ROLE` listens on its port, connects to the others, and for at most 30 s sends
/// a heartbeat and its descriptors every 100 ms, reporting on stdout what it hears.
#[test]
#[ignore = "child-process role of three_robot_processes_find_each_other_and_survive_a_restart"]
fn zenoh_robot_process() {
    let robot: u32 = std::env::var(ROLE).unwrap().parse().unwrap();
    let ports: Vec<u16> = std::env::var(PORTS)
        .unwrap()
        .split(',')
        .map(|p| p.parse().unwrap())
        .collect();
    let others: Vec<u16> = ports
        .iter()
        .enumerate()
        .filter(|&(i, _)| i as u32 != robot)
        .map(|(_, &p)| p)
        .collect();
    let prefix = std::env::var(PREFIX).unwrap();
    let mut transport = ZenohTransport::open(
        RobotId(robot),
        config(ports[robot as usize], &others, &prefix),
        FLEET_SIZE,
    )
    .unwrap();
    let session = std::process::id();
    let mut protocol = ProtocolEndpoint::new(RobotId(robot), session, ProtocolConfig::default());
    let values: Vec<f32> = (0..100).map(|i| (robot * 100 + i) as f32).collect();
    let batch = Message::Descriptors(DescriptorBatch {
        robot: RobotId(robot),
        kind: "solid".into(),
        entries: vec![DescriptorEntry {
            keyframe_index: 0,
            stamp_nanos: 0,
            values: DescriptorValues::encode(&values, DescriptorEncoding::U8).unwrap(),
            newest_held: Vec::new(),
        }],
    });
    let heartbeat = Message::Heartbeat(PeerStatus {
        robot: RobotId(robot),
        latest_keyframe: Some(0),
        capabilities: Capabilities::default(),
        settled: false,
    });
    let mut got = BTreeSet::new();
    let mut alive = BTreeSet::new();
    let started = Instant::now();
    let mut next_send = Instant::now();
    println!("SKID {robot} STARTED");
    while started.elapsed() < Duration::from_secs(30) {
        if Instant::now() >= next_send {
            for message in [&heartbeat, &batch] {
                let bytes = protocol.encode(message).unwrap();
                transport.send(Destination::AllPeers, &bytes).unwrap();
            }
            next_send += Duration::from_millis(100);
        }
        for datagram in transport.poll(Duration::from_millis(50)).unwrap() {
            match protocol.receive(datagram.from, &datagram.payload) {
                Ok(Incoming::Message(received)) => {
                    let peer = received.envelope.robot.0;
                    if received.arrival == (Arrival::First { restarted: true }) {
                        println!("SKID {robot} RESTARTED {peer}");
                    }
                    if let Message::Descriptors(batch) = received.message
                        && batch.entries[0].values.decode().unwrap()[0] == (peer * 100) as f32
                        && got.insert(peer)
                    {
                        println!("SKID {robot} GOT {peer}");
                    }
                }
                Ok(Incoming::Dropped { .. }) => {}
                Err(error) => println!("SKID {robot} ERROR {error}"),
            }
        }
        let now_alive = transport.alive_peers();
        if now_alive != alive {
            alive = now_alive;
            let list: Vec<String> = alive.iter().map(|r| r.0.to_string()).collect();
            println!("SKID {robot} ALIVE [{}]", list.join(","));
        }
    }
}

/// A robot process and the lines it printed.
struct RobotProcess {
    child: Child,
    lines: Receiver<String>,
}

impl RobotProcess {
    fn spawn(robot: u32, ports: &[u16], prefix: &str) -> Self {
        let ports: Vec<String> = ports.iter().map(u16::to_string).collect();
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args([
                "--ignored",
                "--exact",
                // The test's name within the test binary: its module path without the crate's name.
                &format!(
                    "{}::zenoh_robot_process",
                    module_path!().split_once("::").map_or("", |(_, path)| path)
                ),
                "--nocapture",
                "--test-threads=1",
            ])
            .env(ROLE, robot.to_string())
            .env(PORTS, ports.join(","))
            .env(PREFIX, prefix)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let stdout = child.stdout.take().unwrap();
        let (sender, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if line.starts_with("SKID ") && sender.send(line).is_err() {
                    break;
                }
            }
        });
        Self { child, lines }
    }

    /// Waits until every line of `wanted` was printed, in any order; panics with the lines seen after
    /// `timeout`.
    fn expect(&self, wanted: &[String], timeout: Duration) {
        let deadline = Instant::now() + timeout;
        let mut missing: BTreeSet<&String> = wanted.iter().collect();
        let mut seen = Vec::new();
        while !missing.is_empty() {
            let Some(left) = deadline.checked_duration_since(Instant::now()) else {
                break;
            };
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    missing.remove(&line);
                    seen.push(line);
                }
                Err(_) => break,
            }
        }
        assert!(
            missing.is_empty(),
            "missing {missing:?} after {timeout:?}; saw {seen:?}"
        );
    }

    fn expect_got_from(&self, robot: u32, peers: &[u32]) {
        let lines: Vec<String> = peers
            .iter()
            .map(|peer| format!("SKID {robot} GOT {peer}"))
            .collect();
        self.expect(&lines, Duration::from_secs(15));
    }
}

impl Drop for RobotProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn three_robot_processes_find_each_other_and_survive_a_restart() {
    let ports = free_tcp_ports::<3>();
    let prefix = format!("skid-procs-{}", std::process::id());
    let mut robots: Vec<RobotProcess> = (0..3).map(|r| RobotProcess::spawn(r, &ports, &prefix)).collect();
    // Each robot's descriptors reach both other processes.
    robots[0].expect_got_from(0, &[1, 2]);
    robots[1].expect_got_from(1, &[0, 2]);
    robots[2].expect_got_from(2, &[0, 1]);

    // Robot 2's process is killed (SIGKILL); the others see it leave and keep running.
    robots[2].child.kill().unwrap();
    robots[2].child.wait().unwrap();
    for (robot, process) in robots[..2].iter().enumerate() {
        let other = 1 - robot;
        process.expect(
            &[format!("SKID {robot} ALIVE [{other}]")],
            Duration::from_secs(15),
        );
    }

    // It comes back on the same port with a new session: everyone hears everyone again.
    robots[2] = RobotProcess::spawn(2, &ports, &prefix);
    robots[2].expect_got_from(2, &[0, 1]);
    for (robot, process) in robots[..2].iter().enumerate() {
        process.expect(&[format!("SKID {robot} RESTARTED 2")], Duration::from_secs(15));
    }
}
