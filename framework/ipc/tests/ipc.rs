//! skid-ipc: typed round trips between threads (`local` services), a subscriber in this process reading a
//! 2 MB keyframe that a child process wrote, in place in shared memory, and a child publisher killed with
//! SIGKILL being detected, cleaned up and replaced while the subscriber keeps going. Service and node names
//! carry the test process id so parallel runs do not collide.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // Test code fails loudly by design.

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

use skid_core::Point;
use skid_ipc::*;
use skid_msgs::{DescriptorHeader, KeyframeHeader, LoopMeasurement};

/// The point `i` of keyframe `sequence`: a pattern the reader can check without a copy of the data.
fn pattern(sequence: u32, i: usize) -> Point {
    Point::with_intensity(i as f32 * 0.001, sequence as f32, -(i as f32), (i % 256) as f32)
}

fn keyframe_header(sequence: u32, points: usize) -> KeyframeHeader {
    KeyframeHeader {
        stamp_nanos: 1_000 + u64::from(sequence),
        robot_id: 2,
        sequence,
        point_count: points as u32,
        ..KeyframeHeader::default()
    }
}

#[test]
fn typed_ports_round_trip_between_threads() {
    let namespace = format!("skid-test-{}-local", std::process::id());
    let node = ThreadNode::new("stage", &namespace).unwrap();
    let keyframes_out = node.publisher::<Keyframes>().unwrap();
    let keyframes_in = node.subscriber::<Keyframes>().unwrap();
    let descriptors_out = node.publisher::<Descriptors>().unwrap();
    let descriptors_in = node.subscriber::<Descriptors>().unwrap();
    let graph_out = node.publisher::<GraphUpdates>().unwrap();
    let graph_in = node.subscriber::<GraphUpdates>().unwrap();
    assert!(
        keyframes_out
            .wait_for_subscribers(1, Duration::from_secs(1))
            .unwrap()
    );

    assert_eq!(
        keyframes_out
            .send_with(keyframe_header(7, 1000), 1000, |i| pattern(7, i))
            .unwrap(),
        1
    );
    let keyframe = keyframes_in.receive(Duration::from_secs(1)).unwrap().unwrap();
    assert_eq!(*keyframe.header(), keyframe_header(7, 1000));
    assert_eq!(keyframe.cloud().len(), 1000);
    assert!(
        keyframe
            .items()
            .iter()
            .enumerate()
            .all(|(i, p)| *p == pattern(7, i))
    );

    let mut header = DescriptorHeader {
        sequence: 7,
        value_count: 100,
        ..DescriptorHeader::default()
    };
    header.set_kind("solid");
    let values: Vec<f32> = (0..100).map(|i| i as f32 / 3.0).collect();
    descriptors_out.send_slice(header, &values).unwrap();
    let descriptor = descriptors_in.receive(Duration::from_secs(1)).unwrap().unwrap();
    assert_eq!(descriptor.header().kind(), "solid");
    assert_eq!(descriptor.items(), &values[..]);

    let loops = [LoopMeasurement {
        target_robot_id: 0,
        source_robot_id: 1,
        target_sequence: 3,
        source_sequence: 9,
        fitness_m2: 0.02,
        ..LoopMeasurement::default()
    }];
    let header = GraphUpdateHeader {
        kind: GraphUpdateKind::LoopsAccepted as u32,
        ..GraphUpdateHeader::default()
    };
    graph_out.send_slice(header, &loops).unwrap();
    let update = graph_in.receive(Duration::from_secs(1)).unwrap().unwrap();
    assert_eq!(update.header().kind(), Some(GraphUpdateKind::LoopsAccepted));
    assert_eq!(update.items(), &loops[..]);

    // Nothing more: receive waits on the event service for the timeout, then returns None.
    let started = Instant::now();
    assert!(keyframes_in.receive(Duration::from_millis(50)).unwrap().is_none());
    assert!(started.elapsed() >= Duration::from_millis(45));
}

// ---------------------------------------------------------------------------------------------------
// Child processes.

const ROLE: &str = "SKID_IPC_TEST_NAMESPACE";
const SEQUENCE: &str = "SKID_IPC_TEST_SEQUENCE";
const POINTS: &str = "SKID_IPC_TEST_POINTS";

/// Child role: publishes keyframe `SEQUENCE` of `POINTS` points on `ROLE`'s namespace once a subscriber
/// is there, prints `SENT`, and stays alive until its stdin closes (or 30 s pass).
#[test]
#[ignore = "child-process role of the cross-process tests"]
fn ipc_publisher_process() {
    let namespace = std::env::var(ROLE).unwrap();
    let sequence: u32 = std::env::var(SEQUENCE).unwrap().parse().unwrap();
    let points: usize = std::env::var(POINTS).unwrap().parse().unwrap();
    let node = ProcessNode::new(&publisher_node_name(&namespace, sequence), &namespace).unwrap();
    let publisher = node.publisher::<Keyframes>().unwrap();
    assert!(
        publisher
            .wait_for_subscribers(1, Duration::from_secs(10))
            .unwrap()
    );
    let delivered = publisher
        .send_with(keyframe_header(sequence, points), points, |i| {
            pattern(sequence, i)
        })
        .unwrap();
    println!("SKID SENT {delivered}");
    let (done, finished) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = std::io::stdin().read_to_end(&mut Vec::new());
        let _ = done.send(());
    });
    let _ = finished.recv_timeout(Duration::from_secs(30));
}

/// The node name of the child publisher of keyframe `sequence` in `namespace`. Node names are global to
/// the machine, so they carry the namespace: a test then judges only its own nodes, never those of a
/// test running beside it.
fn publisher_node_name(namespace: &str, sequence: u32) -> String {
    format!("{namespace}-publisher-{sequence}")
}

struct PublisherProcess {
    child: Child,
    /// The child's stdout, held open until it ends: libtest prints its result line on the way out.
    _stdout: BufReader<ChildStdout>,
}

impl PublisherProcess {
    /// Starts a child publisher and waits until it has sent.
    fn start(namespace: &str, sequence: u32, points: usize) -> Self {
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args([
                "--ignored",
                "--exact",
                "ipc_publisher_process",
                "--nocapture",
                "--test-threads=1",
            ])
            .env(ROLE, namespace)
            .env(SEQUENCE, sequence.to_string())
            .env(POINTS, points.to_string())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        // libtest may print "test ipc_publisher_process ... " on the same line first.
        let sent = stdout
            .by_ref()
            .lines()
            .map_while(Result::ok)
            .find_map(|line| line.find("SKID SENT").map(|at| line[at..].to_owned()));
        assert_eq!(
            sent.as_deref(),
            Some("SKID SENT 1"),
            "the child published to one subscriber"
        );
        Self {
            child,
            _stdout: stdout,
        }
    }
}

impl Drop for PublisherProcess {
    /// Closes the child's stdin so it ends and removes its node itself; it is killed only if it has not
    /// ended within 5 s. A killed child would leave a dead node for another test's cleanup to find.
    fn drop(&mut self) {
        drop(self.child.stdin.take());
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if !matches!(self.child.try_wait(), Ok(None)) {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The line of /proc/self/maps whose address range holds `address`.
fn mapping_of(address: usize) -> String {
    let maps = std::fs::read_to_string("/proc/self/maps").unwrap();
    maps.lines()
        .find(|line| {
            let range = line.split_whitespace().next().unwrap();
            let (start, end) = range.split_once('-').unwrap();
            let start = usize::from_str_radix(start, 16).unwrap();
            let end = usize::from_str_radix(end, 16).unwrap();
            (start..end).contains(&address)
        })
        .unwrap_or_else(|| panic!("no mapping holds {address:#x}"))
        .to_owned()
}

#[test]
fn subscriber_reads_another_process_keyframe_in_shared_memory() {
    let namespace = format!("skid-test-{}-zero-copy", std::process::id());
    let node = ProcessNode::new("subscriber", &namespace).unwrap();
    let subscriber = node.subscriber::<Keyframes>().unwrap();
    // A 2 MB keyframe: 131,072 points of 16 bytes.
    let points = 131_072;
    let _publisher = PublisherProcess::start(&namespace, 4, points);
    let keyframe = subscriber
        .receive(Duration::from_secs(10))
        .unwrap()
        .expect("a keyframe");
    assert_eq!(*keyframe.header(), keyframe_header(4, points));
    assert!(
        keyframe
            .items()
            .iter()
            .enumerate()
            .all(|(i, p)| *p == pattern(4, i))
    );
    // The slice we read is not a copy in our heap: it lies in a shared-memory file the publisher's
    // process created and wrote, mapped into this process.
    let mapping = mapping_of(keyframe.items().as_ptr() as usize);
    assert!(mapping.contains("/dev/shm/"), "{mapping}");
    let end = keyframe.items().as_ptr() as usize + std::mem::size_of_val(keyframe.items()) - 1;
    assert_eq!(mapping_of(end), mapping, "the whole slice is in the same segment");
    assert!(keyframe.cloud().ensure_usable("keyframe", 10).is_ok());
}

#[test]
fn a_killed_publisher_is_detected_cleaned_up_and_replaced() {
    let namespace = format!("skid-test-{}-dead", std::process::id());
    let mut node = ProcessNode::new("subscriber", &namespace).unwrap();
    let subscriber = node.subscriber::<Keyframes>().unwrap();
    let mut first = PublisherProcess::start(&namespace, 1, 100);
    let keyframe = subscriber.receive(Duration::from_secs(10)).unwrap().unwrap();
    assert_eq!(keyframe.header().sequence, 1);
    drop(keyframe);
    assert_eq!(subscriber.publisher_count(), 1);

    // SIGKILL: the process cannot clean up after itself.
    first.child.kill().unwrap();
    first.child.wait().unwrap();
    let first_name = publisher_node_name(&namespace, 1);
    let deadline = Instant::now() + Duration::from_secs(5);
    while !node.dead_nodes().contains(&first_name) {
        assert!(Instant::now() < deadline, "the dead node is listed");
        std::thread::sleep(Duration::from_millis(10));
    }
    // A cleanup skips a node that someone else is cleaning at that moment, and any participant may be the
    // one that cleans (here the nodes of the tests running beside this one); the stage loop calls it
    // again a second later, and so does this test.
    while node.dead_nodes().contains(&first_name) {
        assert!(Instant::now() < deadline, "the dead node is cleaned up");
        node.cleanup_dead_nodes();
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(subscriber.publisher_count(), 0);
    assert!(subscriber.receive(Duration::from_millis(500)).unwrap().is_none());
    assert!(
        subscriber.take_publisher_events().died >= 1,
        "the subscriber learns its publisher died"
    );

    // The restarted stage publishes again on the same topic; the subscriber carries on.
    let _second = PublisherProcess::start(&namespace, 2, 100);
    let keyframe = subscriber.receive(Duration::from_secs(10)).unwrap().unwrap();
    assert_eq!(keyframe.header().sequence, 2);
    // Other tests of this binary run beside this one, and their nodes are listed too; this test judges
    // only the nodes of its own namespace.
    node.cleanup_dead_nodes();
    let own_dead: Vec<String> = node
        .dead_nodes()
        .into_iter()
        .filter(|name| name.starts_with(&namespace))
        .collect();
    assert!(
        own_dead.is_empty(),
        "nothing of this test left dead: {own_dead:?}"
    );
}
