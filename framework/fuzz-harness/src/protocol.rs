//! The inter-robot protocol harness: envelope and message decoding, the point and descriptor codecs, and
//! the endpoint's classification (sender check, duplicates, reordering), on bytes a hostile peer sends.

use skid_core::RobotId;
use skid_protocol::{Message, ProtocolConfig, ProtocolEndpoint, decode, encode};

/// Decodes `data` as a message from a peer; an accepted message must validate, decode its points and
/// descriptor values without panicking, and re-encode to a message equal to itself.
pub fn protocol_message(data: &[u8]) {
    let config = ProtocolConfig::default();
    if let Ok((envelope, message)) = decode(data, &config) {
        assert!(
            message.validate().is_ok(),
            "decode accepted a message that does not validate"
        );
        decode_bodies(&message);
        let again = encode(
            &message,
            envelope.robot,
            envelope.session,
            envelope.sequence,
            &config,
        )
        .expect("an accepted message re-encodes");
        let (envelope_again, message_again) = decode(&again, &config).expect("a re-encoded message decodes");
        assert_eq!(envelope_again.robot, envelope.robot);
        assert_eq!(envelope_again.sequence, envelope.sequence);
        assert_eq!(message_again, message, "a message changed through re-encoding");
    }
    // The endpoint sees the same bytes twice: the second copy is never accepted as new.
    let mut endpoint = ProtocolEndpoint::new(RobotId(1), 7, config);
    let first = endpoint.receive(RobotId(2), data);
    let second = endpoint.receive(RobotId(2), data);
    if matches!(first, Ok(skid_protocol::Incoming::Message(_))) {
        assert!(
            !matches!(second, Ok(skid_protocol::Incoming::Message(_))),
            "the same message was accepted twice"
        );
    }
}

/// Decodes the compressed parts of a message as the receiving robot does.
fn decode_bodies(message: &Message) {
    match message {
        Message::Cloud(cloud) => {
            if let Ok(points) = cloud.points.decode() {
                assert_eq!(points.len(), cloud.points.len());
                assert!(
                    points
                        .iter()
                        .all(|p| p.x.is_finite() && p.y.is_finite() && p.z.is_finite())
                );
            }
        }
        Message::Descriptors(batch) => {
            for entry in &batch.entries {
                if let Ok(values) = entry.values.decode() {
                    assert_eq!(values.len(), entry.values.len());
                }
            }
        }
        _ => {}
    }
}
