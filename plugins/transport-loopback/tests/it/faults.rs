//! Fault handling at the transport and protocol level (issue 9, item 6): three robots exchange
//! descriptors and heartbeats through the protocol over a loopback hub with 30% loss, duplication and
//! reordering, a peer sending malformed and oversized messages, a cut link, and a robot that leaves and
//! returns. The others keep running, nothing they already hold is lost, and everything gets through once
//! the link is back (robots resend their descriptor batches periodically, as the runtime does).

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use skid_core::RobotId;
use skid_core::slots::{Destination, Transport};
use skid_protocol::*;
use skid_transport_loopback::*;

const MS: u64 = 1_000_000;

/// One robot: its transport, its protocol endpoint, what it produced and what it learnt from peers.
struct Robot {
    id: RobotId,
    transport: LoopbackEndpoint,
    protocol: ProtocolEndpoint,
    keyframes: u32,
    /// `(peer, keyframe index) → first descriptor value`, the state that must never lose entries.
    known: BTreeMap<(RobotId, u32), f32>,
    restarts_seen: Vec<RobotId>,
    errors: Vec<String>,
}

impl Robot {
    fn new(hub: &LoopbackHub, id: u32, session: u32) -> Self {
        Self {
            id: RobotId(id),
            transport: hub.endpoint(RobotId(id)).unwrap(),
            protocol: ProtocolEndpoint::new(RobotId(id), session, ProtocolConfig::default()),
            keyframes: 0,
            known: BTreeMap::new(),
            restarts_seen: Vec::new(),
            errors: Vec::new(),
        }
    }

    /// Adds a keyframe and broadcasts the descriptors of the last 40 keyframes and a heartbeat.
    fn step(&mut self, produce: bool) {
        if produce {
            self.keyframes += 1;
        }
        let first = self.keyframes.saturating_sub(40);
        let entries = (first..self.keyframes)
            .map(|index| DescriptorEntry {
                keyframe_index: index,
                stamp_nanos: u64::from(index) * 100 * MS,
                values: DescriptorValues::encode(&descriptor(self.id, index), DescriptorEncoding::U8)
                    .unwrap(),
                newest_held: Vec::new(),
            })
            .collect::<Vec<_>>();
        let mut messages = vec![Message::Heartbeat(PeerStatus {
            robot: self.id,
            latest_keyframe: self.keyframes.checked_sub(1),
            capabilities: Capabilities::default(),
            settled: false,
        })];
        if !entries.is_empty() {
            messages.push(Message::Descriptors(DescriptorBatch {
                robot: self.id,
                kind: "solid".into(),
                entries,
            }));
        }
        for message in &messages {
            let bytes = self.protocol.encode(message).unwrap();
            self.transport.send(Destination::AllPeers, &bytes).unwrap();
        }
    }

    fn receive(&mut self) {
        for datagram in self.transport.poll(Duration::ZERO).unwrap() {
            match self.protocol.receive(datagram.from, &datagram.payload) {
                Ok(Incoming::Message(received)) => {
                    if received.arrival == (Arrival::First { restarted: true }) {
                        self.restarts_seen.push(received.envelope.robot);
                    }
                    if let Message::Descriptors(batch) = received.message {
                        for entry in batch.entries {
                            let values = entry.values.decode().unwrap();
                            self.known.insert((batch.robot, entry.keyframe_index), values[0]);
                        }
                    }
                }
                Ok(Incoming::Dropped { .. }) => {}
                Err(error) => self.errors.push(error.class().to_owned()),
            }
        }
    }

    fn knows_all_of(&self, peer: RobotId, keyframes: u32) -> bool {
        (0..keyframes).all(|index| self.known.contains_key(&(peer, index)))
    }
}

fn descriptor(robot: RobotId, index: u32) -> Vec<f32> {
    (0..100)
        .map(|i| (robot.0 * 1000 + index + i) as f32 * 0.01)
        .collect()
}

fn faulty_link() -> LinkModel {
    LinkModel {
        loss: 0.3,
        duplicate: 0.2,
        reorder: 0.3,
        reorder_delay_ms: 80.0,
        jitter_ms: 20.0,
        ..LinkModel::default()
    }
}

fn hub(link: LinkModel) -> LoopbackHub {
    LoopbackHub::new(
        HubConfig {
            link,
            ..HubConfig::default()
        },
        2024,
    )
    .unwrap()
}

/// Runs `ticks` rounds of 100 ms: every robot steps (a keyframe every other round), then all receive.
fn run(hub: &LoopbackHub, robots: &mut [Robot], from_tick: u64, ticks: u64, produce: bool) {
    for tick in from_tick..from_tick + ticks {
        hub.advance_to(tick * 100 * MS);
        for robot in robots.iter_mut() {
            robot.step(produce && tick % 2 == 0);
        }
        for robot in robots.iter_mut() {
            robot.receive();
        }
    }
}

#[test]
fn thirty_percent_loss_with_duplicates_and_reordering() {
    let hub = hub(faulty_link());
    let mut robots: Vec<Robot> = (0..3).map(|r| Robot::new(&hub, r, 100 + r)).collect();
    run(&hub, &mut robots, 0, 60, true);
    // Stop producing; keep resending so the last batches also get through the lossy link.
    run(&hub, &mut robots, 60, 20, false);
    for robot in &robots {
        for peer in &robots {
            if peer.id != robot.id {
                assert!(
                    robot.knows_all_of(peer.id, peer.keyframes),
                    "{} misses {}'s keyframes",
                    robot.id,
                    peer.id
                );
            }
        }
        assert!(robot.errors.is_empty(), "{:?}", robot.errors);
        let counters = robot.protocol.counters().snapshot();
        assert!(
            counters.duplicates.messages > 10,
            "duplicates are dropped: {counters:?}"
        );
        assert!(
            robot
                .protocol
                .counters()
                .received(MessageKind::Heartbeat)
                .messages
                > 0
        );
    }
    let stats = hub.stats();
    let lost: u64 = stats.links.iter().map(|l| l.dropped_lost).sum();
    let sent: u64 = stats.links.iter().map(|l| l.sent_messages).sum();
    let fraction = lost as f64 / sent as f64;
    assert!((0.25..0.35).contains(&fraction), "loss {fraction}");
}

#[test]
fn malformed_and_oversized_messages_from_a_peer_are_refused() {
    let hub = hub(LinkModel::ideal());
    let mut robots: Vec<Robot> = (0..2).map(|r| Robot::new(&hub, r, r)).collect();
    let mut rogue = hub.endpoint(RobotId(7)).unwrap();
    let mut good = ProtocolEndpoint::new(RobotId(7), 1, ProtocolConfig::default());
    let valid = good
        .encode(&Message::Heartbeat(PeerStatus {
            robot: RobotId(7),
            latest_keyframe: None,
            capabilities: Capabilities::default(),
            settled: false,
        }))
        .unwrap();
    let mut oversized = b"SKiD".to_vec();
    oversized.extend_from_slice(&[PROTOCOL_VERSION as u8, 7, 0, 0, 3, 0xff, 0xff, 0xff, 0xff, 0x0f]);
    let mut wrong_version = valid.clone();
    wrong_version[4] = 9;
    let impostor = ProtocolEndpoint::new(RobotId(0), 5, ProtocolConfig::default())
        .encode(&Message::Heartbeat(PeerStatus {
            robot: RobotId(0),
            latest_keyframe: Some(1_000_000),
            capabilities: Capabilities::default(),
            settled: false,
        }))
        .unwrap();
    for bytes in [
        b"garbage that is not a message".to_vec(),
        valid[..valid.len() - 2].to_vec(),
        oversized,
        wrong_version,
        impostor,
        Vec::new(),
    ] {
        rogue.send(Destination::AllPeers, &bytes).unwrap();
    }
    rogue.send(Destination::AllPeers, &valid).unwrap();
    run(&hub, &mut robots, 0, 5, true);
    for robot in &robots {
        let errors: BTreeSet<&str> = robot.errors.iter().map(String::as_str).collect();
        let expected: BTreeSet<&str> = [
            "bad_magic",
            "length_mismatch",
            "oversized",
            "unsupported_version",
            "robot_mismatch",
            "truncated",
        ]
        .into();
        assert_eq!(errors, expected);
        // The valid heartbeat after the garbage is still accepted, and the robots still talk.
        assert_eq!(
            robot
                .protocol
                .counters()
                .received(MessageKind::Heartbeat)
                .messages,
            1 + 5
        );
        assert_eq!(robot.known.len(), 3);
    }
}

#[test]
fn a_cut_link_heals_and_a_robot_leaves_and_returns() {
    let hub = hub(LinkModel {
        loss: 0.1,
        ..LinkModel::default()
    });
    let mut robots: Vec<Robot> = (0..3).map(|r| Robot::new(&hub, r, 10 + r)).collect();
    run(&hub, &mut robots, 0, 10, true);
    hub.cut_link(RobotId(0), RobotId(1));
    run(&hub, &mut robots, 10, 20, true);
    assert!(
        !robots[0].knows_all_of(RobotId(1), robots[1].keyframes),
        "the cut link carries nothing"
    );
    assert!(robots[0].knows_all_of(RobotId(2), robots[2].keyframes - 1));
    hub.restore_link(RobotId(0), RobotId(1));
    run(&hub, &mut robots, 30, 10, false);
    assert!(robots[0].knows_all_of(RobotId(1), robots[1].keyframes));
    assert!(robots[1].knows_all_of(RobotId(0), robots[0].keyframes));

    // Robot 2's process dies: its endpoint and protocol state are gone. The others keep running.
    let before: Vec<usize> = robots[..2].iter().map(|r| r.known.len()).collect();
    let departed = robots.pop().unwrap();
    drop(departed);
    run(&hub, &mut robots, 40, 20, true);
    for (robot, count) in robots.iter().zip(&before) {
        assert!(robot.known.len() >= *count, "nothing already known is lost");
        assert!(robot.knows_all_of(RobotId(2), 15));
        let silent = robot
            .transport
            .peers()
            .into_iter()
            .find(|p| p.robot == RobotId(2))
            .unwrap();
        assert!(silent.silent_for.unwrap() >= Duration::from_secs(1), "{silent:?}");
    }
    // It returns with a new session and its keyframe counter restored; peers see the restart.
    let mut returned = Robot::new(&hub, 2, 99);
    returned.keyframes = 15;
    robots.push(returned);
    run(&hub, &mut robots, 60, 20, true);
    for robot in &robots[..2] {
        assert_eq!(robot.restarts_seen, vec![RobotId(2)]);
        assert!(robot.knows_all_of(RobotId(2), robots[2].keyframes));
    }
    assert!(robots[2].knows_all_of(RobotId(0), robots[0].keyframes - 1));
}
