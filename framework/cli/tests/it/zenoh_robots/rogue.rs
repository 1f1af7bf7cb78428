//! The rogue of the fleet test: three zenoh sessions in the test process, started beside a mutual-TLS
//! fleet of robots `0..3` whose access control admits robots `0..4`.
//! - The stranger holds a certificate another CA signed: TLS refuses its links.
//! - The impostor holds robot 3's genuine certificate and publishes as robot 1: the access control drops
//!   its messages and counts them.
//! - The flooder is robot 3, authorised, and sends malformed bytes, replays, messages whose envelope
//!   claims robot 1, descriptors of another kind or length stamped an hour off, loops that are not its own
//!   or name keyframes that do not exist, clouds nobody asked for, and large blobs, as fast as it can.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use skid_core::slots::{Destination, Transport};
use skid_core::{KeyframeId, RobotId};
use skid_protocol::{
    Capabilities, CloudMsg, CompressedPoints, DescriptorBatch, DescriptorEncoding, DescriptorEntry,
    DescriptorValues, InformationMsg, LoopMsg, Loops, Message, OdomChain, PeerStatus, PoseMsg,
    ProtocolConfig, ProtocolEndpoint,
};
use skid_transport_zenoh::{TlsFiles, ZenohConfig, ZenohTransport};

/// One hour, the offset of the flooder's stamps.
const HOUR_NANOS: u64 = 3_600_000_000_000;

fn session(folder: &Path, certificate: &str, robot: u32, ports: &[u16], prefix: &str) -> ZenohTransport {
    let config = ZenohConfig {
        listen: Vec::new(),
        connect: ports.iter().map(|port| format!("tls/127.0.0.1:{port}")).collect(),
        key_prefix: prefix.into(),
        tls: TlsFiles {
            ca_certificate: folder.join("ca.pem"),
            certificate: folder.join(format!("{certificate}.pem")),
            private_key: folder.join(format!("{certificate}.key")),
        },
        ..ZenohConfig::default()
    };
    ZenohTransport::open(RobotId(robot), config, 4).unwrap()
}

fn descriptors(robot: u32, keyframe_index: u32, kind: &str, values: usize, stamp_nanos: u64) -> Message {
    let values: Vec<f32> = (0..values).map(|i| (i % 7) as f32 * 0.1).collect();
    Message::Descriptors(DescriptorBatch {
        robot: RobotId(robot),
        kind: kind.into(),
        entries: vec![DescriptorEntry {
            keyframe_index,
            stamp_nanos,
            values: DescriptorValues::encode(&values, DescriptorEncoding::U8).unwrap(),
            newest_held: Vec::new(),
        }],
    })
}

/// A forged loop, 50 m off: accepted anywhere, it would drag a trajectory by metres.
fn a_loop(target: KeyframeId, source: KeyframeId) -> LoopMsg {
    let fifty_metres = skid_core::Pose::translation(50.0, 0.0, 0.0);
    LoopMsg {
        target,
        source,
        target_from_source: PoseMsg::from_pose(&fifty_metres),
        information: InformationMsg::identity(),
        fitness_m2: 0.01,
    }
}

/// Well-formed messages robot `robot` could send; what a flooder or impostor sends.
fn hostile_messages(robot: u32) -> Vec<Message> {
    let points: Vec<skid_core::Point> = (0..200)
        .map(|i| skid_core::Point::new(i as f32 * 0.1, 1.0, 0.5))
        .collect();
    vec![
        Message::Hello(PeerStatus {
            robot: RobotId(robot),
            latest_keyframe: Some(5),
            capabilities: Capabilities::default(),
            settled: false,
        }),
        // Each on its own keyframe: a host hands a keyframe's descriptor to its index once.
        descriptors(robot, 5, "scan_context", 40, HOUR_NANOS + 1),
        descriptors(robot, 6, "solid", 7, HOUR_NANOS + 2),
        Message::Loops(Loops {
            robot: RobotId(robot),
            accepted: vec![
                a_loop(KeyframeId::new(0, 1), KeyframeId::new(2, 1)),
                a_loop(KeyframeId::new(0, 999_999), KeyframeId::new(robot, 5)),
            ],
            retracted: vec![(KeyframeId::new(0, 2), KeyframeId::new(1, 3))],
        }),
        Message::Cloud(CloudMsg {
            keyframe: KeyframeId::new(robot, 5),
            stamp_nanos: HOUR_NANOS,
            world_from_sensor: PoseMsg::IDENTITY,
            points: CompressedPoints::encode(&points, 0.01, false).unwrap(),
        }),
        Message::OdomChain(OdomChain {
            robot: RobotId(robot),
            from_index: 0,
            to_index: 0,
            edges: Vec::new(),
            world_from_first: PoseMsg::IDENTITY,
        }),
    ]
}

/// The three rogue sessions, sending on a thread until stopped.
pub struct Rogue {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<(ZenohTransport, u64)>>,
}

impl Rogue {
    /// Starts the rogue against the fleet at `ports`; `certs` are the fleet's, `foreign` another CA's.
    pub fn start(certs: &Path, foreign: &Path, ports: &[u16], prefix: &str) -> Self {
        let stranger = session(foreign, "robot-3", 3, ports, prefix);
        let impostor = session(certs, "robot-3", 1, ports, prefix);
        let flooder = session(certs, "robot-3", 3, ports, prefix);
        let stop = Arc::new(AtomicBool::new(false));
        let running = Arc::clone(&stop);
        let thread = std::thread::spawn(move || flood(stranger, impostor, flooder, &running));
        Self {
            stop,
            thread: Some(thread),
        }
    }

    /// Stops sending; returns the stranger's session (to ask whom it reached) and the messages sent.
    pub fn stop(mut self) -> (ZenohTransport, u64) {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

fn flood(
    mut stranger: ZenohTransport,
    mut impostor: ZenohTransport,
    mut flooder: ZenohTransport,
    stop: &AtomicBool,
) -> (ZenohTransport, u64) {
    let config = ProtocolConfig::default();
    let mut as_robot_3 = ProtocolEndpoint::new(RobotId(3), 77, config.clone());
    let mut as_robot_1 = ProtocolEndpoint::new(RobotId(1), 78, config);
    let mut sent = 0u64;
    let mut round = 0u64;
    let mut send = |transport: &mut ZenohTransport, bytes: &[u8]| {
        // A dropped send under congestion is part of flooding.
        let _ = transport.send(Destination::AllPeers, bytes);
        sent += 1;
    };
    while !stop.load(Ordering::Relaxed) {
        round += 1;
        for message in hostile_messages(3) {
            let bytes = as_robot_3.encode(&message).unwrap();
            send(&mut flooder, &bytes);
            // Replays of the same message.
            send(&mut flooder, &bytes);
            send(&mut flooder, &bytes);
        }
        for message in hostile_messages(1) {
            let bytes = as_robot_1.encode(&message).unwrap();
            // The envelope claims robot 1; the key (robot 3's) does not.
            send(&mut flooder, &bytes);
            send(&mut impostor, &bytes);
            send(&mut stranger, &bytes);
        }
        send(&mut flooder, &round.to_le_bytes().repeat(40));
        send(&mut flooder, b"SKiD\x01\x00\xff\xff\xff\xff\x0f");
        if round.is_multiple_of(20) {
            send(&mut flooder, &vec![0xA5; 1 << 20]);
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    (stranger, sent)
}
