//! Round trips of every message kind, the envelope checks, endpoint classification of duplicated and
//! reordered messages, and fuzz-style robustness: random, truncated and bit-flipped bytes never panic.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skid_core::{Information, KeyframeId, Point, Pose, RobotId};
use skid_protocol::*;

fn sample_messages(robot: u32) -> Vec<Message> {
    let status = PeerStatus {
        robot: RobotId(robot),
        latest_keyframe: Some(41),
        capabilities: Capabilities {
            descriptor_kind: "solid".into(),
            descriptor_len: 100,
            serves_clouds: true,
            max_message_bytes: 4 << 20,
        },
        settled: false,
    };
    let values: Vec<f32> = (0..100).map(|i| (i as f32 * 0.37).sin().abs()).collect();
    let pose = Pose::new(Vector3::new(1.0, 2.0, -0.5), Vector3::new(0.0, 0.1, 1.2));
    let points: Vec<Point> = (0..500)
        .map(|i| Point::with_intensity((i % 25) as f32 * 0.4, (i / 25) as f32 * 0.4, -1.5, i as f32))
        .collect();
    let edge = ChainEdge {
        target_from_source: PoseMsg::from_pose(&pose),
        information: InformationMsg::from_information(&(Information::identity() * 50.0)),
    };
    vec![
        Message::Hello(status.clone()),
        Message::Heartbeat(PeerStatus {
            latest_keyframe: None,
            ..status
        }),
        Message::Descriptors(DescriptorBatch {
            robot: RobotId(robot),
            kind: "solid".into(),
            entries: vec![
                DescriptorEntry {
                    keyframe_index: 3,
                    stamp_nanos: 1_000_000_123,
                    values: DescriptorValues::encode(&values, DescriptorEncoding::F32).unwrap(),
                    newest_held: Vec::new(),
                },
                DescriptorEntry {
                    keyframe_index: 4,
                    stamp_nanos: 2_000_000_456,
                    values: DescriptorValues::encode(&values, DescriptorEncoding::U8).unwrap(),
                    newest_held: Vec::new(),
                },
            ],
        }),
        Message::CloudRequest(CloudRequest {
            requester: RobotId(robot),
            keyframes: vec![KeyframeId::new(robot + 1, 7), KeyframeId::new(robot + 1, 9)],
        }),
        Message::Cloud(CloudMsg {
            keyframe: KeyframeId::new(robot, 7),
            stamp_nanos: 77,
            world_from_sensor: PoseMsg::from_pose(&pose),
            points: CompressedPoints::encode(&points, 0.01, true).unwrap(),
        }),
        Message::OdomChain(OdomChain {
            robot: RobotId(robot),
            from_index: 5,
            to_index: 7,
            edges: vec![edge, edge],
            world_from_first: PoseMsg::IDENTITY,
        }),
        Message::Loops(Loops {
            robot: RobotId(robot),
            accepted: vec![LoopMsg {
                target: KeyframeId::new(robot, 3),
                source: KeyframeId::new(robot + 1, 12),
                target_from_source: PoseMsg::from_pose(&pose),
                information: InformationMsg::identity(),
                fitness_m2: 0.04,
            }],
            retracted: vec![(KeyframeId::new(robot, 1), KeyframeId::new(robot + 2, 2))],
        }),
    ]
}

#[test]
fn every_kind_round_trips() {
    let config = ProtocolConfig::default();
    for (sequence, message) in sample_messages(1).into_iter().enumerate() {
        let bytes = encode(&message, RobotId(1), 99, sequence as u64, &config).unwrap();
        assert_eq!(&bytes[..4], b"SKiD");
        let (envelope, back) = decode(&bytes, &config).unwrap();
        assert_eq!(back, message);
        assert_eq!(envelope.kind, message.kind());
        assert_eq!(envelope.robot, RobotId(1));
        assert_eq!(envelope.session, 99);
        assert_eq!(envelope.sequence, sequence as u64);
        assert_eq!(envelope.version, PROTOCOL_VERSION);
    }
}

#[test]
fn envelope_checks_come_before_the_payload() {
    let config = ProtocolConfig::default();
    let message = &sample_messages(0)[2];
    let bytes = encode(message, RobotId(0), 1, 0, &config).unwrap();

    let mut bad_magic = bytes.clone();
    bad_magic[0] = b'X';
    assert!(matches!(
        decode(&bad_magic, &config),
        Err(DecodeError::BadMagic { .. })
    ));

    // The next version in the first header byte (a one-byte varint).
    let mut future = bytes.clone();
    future[4] = (PROTOCOL_VERSION + 1) as u8;
    assert!(matches!(
        decode(&future, &config),
        Err(DecodeError::UnsupportedVersion { found, .. }) if found == PROTOCOL_VERSION + 1
    ));
    // Version 1 sent clouds as bare varints; a peer of that version is refused, not misread.
    let mut old = bytes.clone();
    old[4] = 1;
    assert!(matches!(
        decode(&old, &config),
        Err(DecodeError::UnsupportedVersion { found: 1, .. })
    ));

    let truncated = &bytes[..bytes.len() - 1];
    assert!(matches!(
        decode(truncated, &config),
        Err(DecodeError::LengthMismatch { .. })
    ));
    let mut trailing = bytes.clone();
    trailing.push(0);
    assert!(matches!(
        decode(&trailing, &config),
        Err(DecodeError::LengthMismatch { .. })
    ));
    assert!(matches!(
        decode(b"SK", &config),
        Err(DecodeError::Truncated { .. })
    ));

    // A receiver with a smaller limit refuses by the declared length.
    let tight = ProtocolConfig {
        max_message_bytes: 100,
        ..ProtocolConfig::default()
    };
    assert!(matches!(
        decode(&bytes, &tight),
        Err(DecodeError::Oversized { .. })
    ));
    // And a sender refuses to build what it may not send.
    assert!(matches!(
        encode(message, RobotId(0), 1, 0, &tight),
        Err(EncodeError::Oversized { .. })
    ));
}

#[test]
fn a_lying_length_is_refused_without_decoding() {
    let config = ProtocolConfig::default();
    // Magic, this version, robot 0, session 0, sequence 0, kind 5 (cloud), payload_len = 2^31 (varint).
    let mut bytes = b"SKiD".to_vec();
    bytes.extend_from_slice(&[PROTOCOL_VERSION as u8, 0, 0, 0, 5, 0x80, 0x80, 0x80, 0x80, 0x08]);
    bytes.extend_from_slice(&[0; 16]);
    assert!(matches!(
        decode(&bytes, &config),
        Err(DecodeError::Oversized {
            declared: 2_147_483_648,
            ..
        })
    ));
    // A kind this build does not know.
    let mut unknown = b"SKiD".to_vec();
    unknown.extend_from_slice(&[PROTOCOL_VERSION as u8, 0, 0, 0, 42, 0]);
    assert!(matches!(
        decode(&unknown, &config),
        Err(DecodeError::UnknownKind(42))
    ));
}

#[test]
fn a_version_2_status_reads_as_not_settled_and_a_version_3_one_as_sent() {
    let config = ProtocolConfig::default();
    let Message::Hello(status) = sample_messages(0)[0].clone() else {
        unreachable!()
    };
    let settled = PeerStatus {
        settled: true,
        ..status.clone()
    };
    let bytes = encode(&Message::Hello(settled.clone()), RobotId(0), 1, 0, &config).unwrap();
    assert_eq!(decode(&bytes, &config).unwrap().1, Message::Hello(settled));
    // Version 2's status is version 3's without the last field: the same header (robot 0, session 1,
    // sequence 0, kind 1, a one-byte length) and the payload without its `settled` byte.
    let header_len = 4 + 5 + 1;
    assert!(bytes.len() - header_len < 128, "the length is a one-byte varint");
    let payload = &bytes[header_len..bytes.len() - 1];
    let mut old = b"SKiD".to_vec();
    old.extend_from_slice(&[2, 0, 1, 0, MessageKind::Hello.code(), payload.len() as u8]);
    old.extend_from_slice(payload);
    let (envelope, message) = decode(&old, &config).unwrap();
    assert_eq!(envelope.version, 2);
    assert_eq!(
        message,
        Message::Hello(PeerStatus {
            settled: false,
            ..status
        })
    );
    // A version-3 status without the byte is truncated, not read as version 2.
    let mut short = old.clone();
    short[4] = 3;
    assert!(matches!(
        decode(&short, &config),
        Err(DecodeError::Payload { .. })
    ));
}

#[test]
fn invalid_bodies_are_refused_on_both_sides() {
    let config = ProtocolConfig::default();
    let mut chain = match &sample_messages(0)[5] {
        Message::OdomChain(chain) => chain.clone(),
        _ => unreachable!(),
    };
    chain.edges[1].target_from_source.translation_m[0] = f64::NAN;
    let bad = Message::OdomChain(chain.clone());
    assert!(matches!(
        encode(&bad, RobotId(0), 0, 0, &config),
        Err(EncodeError::Invalid { .. })
    ));
    chain.edges.pop();
    assert!(Message::OdomChain(chain).validate().is_err());

    // A message whose body names another robot than its envelope.
    let hello = &sample_messages(3)[0];
    let bytes = encode(hello, RobotId(4), 0, 0, &config).unwrap();
    assert!(matches!(
        decode(&bytes, &config),
        Err(DecodeError::RobotMismatch { .. })
    ));
}

#[test]
fn endpoint_drops_duplicates_accepts_reordered_and_counts_bytes() {
    let mut sender = ProtocolEndpoint::new(RobotId(1), 5, ProtocolConfig::default());
    let mut receiver = ProtocolEndpoint::new(RobotId(0), 6, ProtocolConfig::default());
    let messages = sample_messages(1);
    let encoded: Vec<Vec<u8>> = messages.iter().map(|m| sender.encode(m).unwrap()).collect();
    // Deliver 0, 2, 1, 2 (duplicate), 3..
    let order = [0usize, 2, 1, 2, 3, 4, 5, 6];
    let mut arrivals = Vec::new();
    for &i in &order {
        match receiver.receive(RobotId(1), &encoded[i]).unwrap() {
            Incoming::Message(received) => {
                assert_eq!(received.message, messages[i]);
                arrivals.push(received.arrival);
            }
            Incoming::Dropped { arrival, .. } => arrivals.push(arrival),
        }
    }
    assert_eq!(arrivals[0], Arrival::First { restarted: false });
    assert_eq!(arrivals[1], Arrival::AfterGap { missing: 1 });
    assert_eq!(arrivals[2], Arrival::Late);
    assert_eq!(arrivals[3], Arrival::Duplicate);
    let counters = receiver.counters();
    assert_eq!(counters.duplicates().messages, 1);
    assert_eq!(counters.received(MessageKind::Cloud).messages, 1);
    assert_eq!(
        counters.received(MessageKind::Cloud).bytes,
        encoded[4].len() as u64,
    );
    assert_eq!(
        sender.counters().sent(MessageKind::Descriptors).bytes,
        encoded[2].len() as u64
    );
    // A peer claiming to be robot 1 over robot 2's link is refused and counted.
    assert!(matches!(
        receiver.receive(RobotId(2), &encoded[0]),
        Err(DecodeError::SenderMismatch { .. })
    ));
    let snapshot = receiver.counters().snapshot();
    assert_eq!(snapshot.rejected["robot_mismatch"].messages, 1);
    assert_eq!(snapshot.received_total.messages, 7);
    // A restarted sender (new session, sequence from 0) is accepted again.
    let mut restarted = ProtocolEndpoint::new(RobotId(1), 8, ProtocolConfig::default());
    let again = restarted.encode(&messages[0]).unwrap();
    match receiver.receive(RobotId(1), &again).unwrap() {
        Incoming::Message(received) => assert_eq!(received.arrival, Arrival::First { restarted: true }),
        other => panic!("{other:?}"),
    }
}

/// Feeds the decoder bytes from `make` many times; it must return (Ok or Err), never panic.
fn never_panics(mut make: impl FnMut(&mut ChaCha8Rng) -> Vec<u8>) -> (usize, usize) {
    let config = ProtocolConfig::default();
    let mut endpoint = ProtocolEndpoint::new(RobotId(0), 0, config.clone());
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut ok, mut err) = (0, 0);
    for _ in 0..3000 {
        let bytes = make(&mut rng);
        match decode(&bytes, &config) {
            Ok((_, message)) => {
                ok += 1;
                if let Message::Cloud(cloud) = message {
                    let _ = cloud.points.decode();
                }
            }
            Err(error) => {
                err += 1;
                assert!(!error.to_string().is_empty());
            }
        }
        let _ = endpoint.receive(RobotId(1), &bytes);
    }
    (ok, err)
}

#[test]
fn fuzz_random_bytes_never_panic() {
    let (_, err) = never_panics(|rng| {
        let len = rng.random_range(0..200);
        (0..len).map(|_| rng.random()).collect()
    });
    assert!(err > 0);
    // Random bodies behind a valid-looking header reach the payload decoder.
    never_panics(|rng| {
        let kind = rng.random_range(1..=7u8);
        let body: Vec<u8> = (0..rng.random_range(0..120)).map(|_| rng.random()).collect();
        let mut bytes = b"SKiD".to_vec();
        // Bodies are shorter than 128 bytes, so their length is a one-byte varint.
        bytes.extend_from_slice(&[1, 1, 0, 0, kind, body.len() as u8]);
        bytes.extend(body);
        bytes
    });
}

#[test]
fn fuzz_truncated_and_bit_flipped_messages_never_panic() {
    let config = ProtocolConfig::default();
    let originals: Vec<Vec<u8>> = sample_messages(1)
        .iter()
        .enumerate()
        .map(|(i, m)| encode(m, RobotId(1), 3, i as u64, &config).unwrap())
        .collect();
    // Every prefix of every message is refused.
    for bytes in &originals {
        for cut in 0..bytes.len() {
            assert!(
                decode(&bytes[..cut], &config).is_err(),
                "prefix {cut} of {} accepted",
                bytes.len()
            );
        }
    }
    let (ok, err) = never_panics(|rng| {
        let mut bytes = originals[rng.random_range(0..originals.len())].clone();
        for _ in 0..rng.random_range(1..4) {
            let at = rng.random_range(0..bytes.len());
            bytes[at] ^= 1 << rng.random_range(0..8);
        }
        bytes
    });
    assert!(err > 0 && ok + err == 3000);
}
