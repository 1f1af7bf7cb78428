//! One robot's protocol state: it numbers outgoing messages, checks and classifies incoming ones
//! (malformed, duplicate, late, from a restarted peer) and keeps the byte counters.

use skid_core::RobotId;

use crate::counters::Counters;
use crate::envelope::{DecodeError, EncodeError, Envelope, ProtocolConfig, decode, encode};
use crate::messages::Message;
use crate::sequence::{Arrival, PeerSequences};

/// A message accepted from a peer.
#[derive(Clone, Debug, PartialEq)]
pub struct Received {
    pub envelope: Envelope,
    pub message: Message,
    /// How it arrived relative to the peer's earlier messages (never `Duplicate` or `Stale`).
    pub arrival: Arrival,
}

/// What became of bytes handed to [`ProtocolEndpoint::receive`] that were well-formed.
#[derive(Clone, Debug, PartialEq)]
pub enum Incoming {
    /// A new message to process.
    Message(Received),
    /// A copy of a message already received, or one older than the reorder window; dropped.
    Dropped { envelope: Envelope, arrival: Arrival },
}

/// Encoder and decoder with sequence numbering, duplicate detection and counters for one robot.
#[derive(Clone, Debug)]
pub struct ProtocolEndpoint {
    robot: RobotId,
    session: u32,
    next_sequence: u64,
    config: ProtocolConfig,
    counters: Counters,
    peers: PeerSequences,
}

impl ProtocolEndpoint {
    /// The endpoint of `robot`. `session` must differ between runs of the robot's process that peers may
    /// both see (for example derived from the start time, or from the seed and a restart counter in
    /// lockstep runs, which must stay reproducible).
    pub fn new(robot: RobotId, session: u32, config: ProtocolConfig) -> Self {
        Self {
            robot,
            session,
            next_sequence: 0,
            peers: PeerSequences::new(config.reorder_window),
            config,
            counters: Counters::default(),
        }
    }

    pub fn robot(&self) -> RobotId {
        self.robot
    }

    pub fn session(&self) -> u32 {
        self.session
    }

    pub fn config(&self) -> &ProtocolConfig {
        &self.config
    }

    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Encodes `message` with the next sequence number and counts it as sent.
    pub fn encode(&mut self, message: &Message) -> Result<Vec<u8>, EncodeError> {
        let bytes = encode(
            message,
            self.robot,
            self.session,
            self.next_sequence,
            &self.config,
        )?;
        self.next_sequence += 1;
        self.counters.record_sent(message.kind(), bytes.len());
        Ok(bytes)
    }

    /// Counts one extra copy of an encoded message as sent (when the same bytes go to several peers one
    /// by one).
    pub fn record_resent(&mut self, message: &Message, bytes: usize) {
        self.counters.record_sent(message.kind(), bytes);
    }

    /// Checks bytes that the transport says came from `from`. Malformed bytes are an error (counted by
    /// class); copies and too-old messages are dropped (counted); anything else is returned.
    pub fn receive(&mut self, from: RobotId, bytes: &[u8]) -> Result<Incoming, DecodeError> {
        let result = decode(bytes, &self.config).and_then(|(envelope, message)| {
            if envelope.robot == from {
                Ok((envelope, message))
            } else {
                Err(DecodeError::SenderMismatch {
                    envelope: envelope.robot,
                    transport: from,
                })
            }
        });
        let (envelope, message) = match result {
            Ok(decoded) => decoded,
            Err(error) => {
                self.counters.record_rejected(error.class(), bytes.len());
                return Err(error);
            }
        };
        let arrival = self
            .peers
            .observe(envelope.robot, envelope.session, envelope.sequence);
        match arrival {
            Arrival::Duplicate => {
                self.counters.record_duplicate(bytes.len());
                Ok(Incoming::Dropped { envelope, arrival })
            }
            Arrival::Stale => {
                self.counters.record_stale(bytes.len());
                Ok(Incoming::Dropped { envelope, arrival })
            }
            _ => {
                self.counters.record_received(envelope.kind, bytes.len());
                Ok(Incoming::Message(Received {
                    envelope,
                    message,
                    arrival,
                }))
            }
        }
    }
}
