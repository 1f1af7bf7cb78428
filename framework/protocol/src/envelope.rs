//! The versioned envelope around every message, postcard encoding, and decoding that checks the magic,
//! the version and the declared length against the configured limits before the payload is touched.
//!
//! Layout: `magic (4 raw bytes "SKiD") | postcard(version, robot, session, sequence, kind, payload_len) |
//! payload (postcard of the kind's body)`. The magic comes first so a foreign or shifted byte string is
//! refused after four bytes. The envelope adds a `session` (one per process incarnation) to the fields
//! of design guide §6, so a robot that restarts with sequence 0 is recognised as new rather than as a
//! replay of old messages.

use serde::{Deserialize, Serialize};
use skid_core::RobotId;

use crate::messages::{
    CloudMsg, CloudRequest, DescriptorBatch, Frames, InvalidMessage, Loops, Message, MessageKind, OdomChain,
    PeerStatus, PeerStatusV2,
};

/// The four bytes every SKiD message starts with.
pub const MAGIC: [u8; 4] = *b"SKiD";

/// The protocol version this build writes.
pub const PROTOCOL_VERSION: u16 = 3;

/// The oldest protocol version this build reads (version 2 differs only in `Hello` and `Heartbeat`,
/// whose status had no `settled`).
pub const MIN_SUPPORTED_VERSION: u16 = 2;

/// Upper bound of an encoded envelope header: magic plus the varints of its fields.
pub const MAX_HEADER_BYTES: usize = 4 + 3 + 5 + 5 + 10 + 1 + 5;

/// Size limits, in the runtime's `[protocol]` config table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProtocolConfig {
    /// Largest payload accepted or sent, in bytes (clouds are the largest messages).
    pub max_message_bytes: u32,
    /// Largest payload of a control message (hello, heartbeat, cloud request), in bytes.
    pub max_control_message_bytes: u32,
    /// How many sequence numbers behind the newest one a late message is still recognised as new or
    /// duplicate; older ones are dropped as stale.
    pub reorder_window: u32,
}

impl Default for ProtocolConfig {
    fn default() -> Self {
        Self {
            max_message_bytes: 4 << 20,
            max_control_message_bytes: 64 << 10,
            reorder_window: 1024,
        }
    }
}

impl ProtocolConfig {
    /// The payload limit for `kind`.
    pub fn limit_for(&self, kind: MessageKind) -> u32 {
        if kind.is_control() {
            self.max_control_message_bytes.min(self.max_message_bytes)
        } else {
            self.max_message_bytes
        }
    }
}

/// The header in front of every payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Envelope {
    pub version: u16,
    pub robot: RobotId,
    /// Identifies one run of the sender's process; a new session restarts its sequence numbers.
    pub session: u32,
    /// Per-sender sequence number, increasing by one per message within a session.
    pub sequence: u64,
    pub kind: MessageKind,
    pub payload_len: u32,
}

/// The header as postcard writes it (after the raw magic).
#[derive(Serialize, Deserialize)]
struct HeaderWire {
    version: u16,
    robot: u32,
    session: u32,
    sequence: u64,
    kind: u8,
    payload_len: u32,
}

/// Why bytes were not accepted as a message. Each variant names a class for the rejection counters.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DecodeError {
    #[error("message of {len} bytes is shorter than an envelope")]
    Truncated { len: usize },
    #[error("bad magic {found:02x?} (expected \"SKiD\")")]
    BadMagic { found: [u8; 4] },
    #[error("envelope header is malformed: {0}")]
    Header(postcard::Error),
    #[error("protocol version {found} is not supported (this build reads {min}..={max})")]
    UnsupportedVersion { found: u16, min: u16, max: u16 },
    #[error("unknown message kind {0}")]
    UnknownKind(u8),
    #[error("{kind:?} message declares {declared} bytes, more than the limit of {limit}")]
    Oversized {
        kind: Option<MessageKind>,
        declared: u64,
        limit: u32,
    },
    #[error("{kind:?} payload declares {declared} bytes but {actual} follow the header")]
    LengthMismatch {
        kind: MessageKind,
        declared: u32,
        actual: usize,
    },
    #[error("{kind:?} payload is malformed: {source}")]
    Payload {
        kind: MessageKind,
        source: postcard::Error,
    },
    #[error("{kind:?} payload is invalid: {source}")]
    Invalid {
        kind: MessageKind,
        source: InvalidMessage,
    },
    #[error("{kind:?} from {envelope} claims to come from {body}")]
    RobotMismatch {
        kind: MessageKind,
        envelope: RobotId,
        body: RobotId,
    },
    #[error("message signed by {envelope} arrived from {transport}")]
    SenderMismatch { envelope: RobotId, transport: RobotId },
}

impl DecodeError {
    /// A short class name for counters and logs.
    pub fn class(&self) -> &'static str {
        match self {
            Self::Truncated { .. } => "truncated",
            Self::BadMagic { .. } => "bad_magic",
            Self::Header(_) => "bad_header",
            Self::UnsupportedVersion { .. } => "unsupported_version",
            Self::UnknownKind(_) => "unknown_kind",
            Self::Oversized { .. } => "oversized",
            Self::LengthMismatch { .. } => "length_mismatch",
            Self::Payload { .. } => "bad_payload",
            Self::Invalid { .. } => "invalid",
            Self::RobotMismatch { .. } | Self::SenderMismatch { .. } => "robot_mismatch",
        }
    }
}

/// Why a message could not be encoded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EncodeError {
    #[error("{kind:?} message of {bytes} bytes exceeds the limit of {limit}")]
    Oversized {
        kind: MessageKind,
        bytes: usize,
        limit: u32,
    },
    #[error("{kind:?} message is invalid: {source}")]
    Invalid {
        kind: MessageKind,
        source: InvalidMessage,
    },
    #[error("postcard: {0}")]
    Postcard(#[from] postcard::Error),
}

/// Encodes `message` in an envelope; invalid or oversized messages are refused before they leave.
pub fn encode(
    message: &Message,
    robot: RobotId,
    session: u32,
    sequence: u64,
    config: &ProtocolConfig,
) -> Result<Vec<u8>, EncodeError> {
    let kind = message.kind();
    message
        .validate()
        .map_err(|source| EncodeError::Invalid { kind, source })?;
    let payload = match message {
        Message::Hello(body) | Message::Heartbeat(body) => postcard::to_allocvec(body)?,
        Message::Descriptors(body) => postcard::to_allocvec(body)?,
        Message::CloudRequest(body) => postcard::to_allocvec(body)?,
        Message::Cloud(body) => postcard::to_allocvec(body)?,
        Message::OdomChain(body) => postcard::to_allocvec(body)?,
        Message::Loops(body) => postcard::to_allocvec(body)?,
        Message::Frames(body) => postcard::to_allocvec(body)?,
    };
    let limit = config.limit_for(kind);
    let payload_len = u32::try_from(payload.len())
        .ok()
        .filter(|&len| len <= limit)
        .ok_or(EncodeError::Oversized {
            kind,
            bytes: payload.len(),
            limit,
        })?;
    let header = HeaderWire {
        version: PROTOCOL_VERSION,
        robot: robot.0,
        session,
        sequence,
        kind: kind.code(),
        payload_len,
    };
    let mut bytes = Vec::with_capacity(MAX_HEADER_BYTES + payload.len());
    bytes.extend_from_slice(&MAGIC);
    let mut bytes = postcard::to_extend(&header, bytes)?;
    bytes.extend_from_slice(&payload);
    Ok(bytes)
}

/// Reads and checks the envelope only: magic, version, kind, and the declared length against the limit
/// and against the bytes that follow. Returns the header and the payload bytes.
pub fn decode_envelope<'a>(
    bytes: &'a [u8],
    config: &ProtocolConfig,
) -> Result<(Envelope, &'a [u8]), DecodeError> {
    let hard_limit = MAX_HEADER_BYTES as u64 + u64::from(config.max_message_bytes);
    if bytes.len() as u64 > hard_limit {
        return Err(DecodeError::Oversized {
            kind: None,
            declared: bytes.len() as u64,
            limit: config.max_message_bytes,
        });
    }
    let (magic, rest) = bytes
        .split_first_chunk::<4>()
        .ok_or(DecodeError::Truncated { len: bytes.len() })?;
    if *magic != MAGIC {
        return Err(DecodeError::BadMagic { found: *magic });
    }
    let (header, payload) = postcard::take_from_bytes::<HeaderWire>(rest).map_err(|error| match error {
        postcard::Error::DeserializeUnexpectedEnd => DecodeError::Truncated { len: bytes.len() },
        other => DecodeError::Header(other),
    })?;
    if !(MIN_SUPPORTED_VERSION..=PROTOCOL_VERSION).contains(&header.version) {
        return Err(DecodeError::UnsupportedVersion {
            found: header.version,
            min: MIN_SUPPORTED_VERSION,
            max: PROTOCOL_VERSION,
        });
    }
    let kind = MessageKind::from_code(header.kind).ok_or(DecodeError::UnknownKind(header.kind))?;
    let limit = config.limit_for(kind);
    if header.payload_len > limit {
        return Err(DecodeError::Oversized {
            kind: Some(kind),
            declared: u64::from(header.payload_len),
            limit,
        });
    }
    if payload.len() != header.payload_len as usize {
        return Err(DecodeError::LengthMismatch {
            kind,
            declared: header.payload_len,
            actual: payload.len(),
        });
    }
    let envelope = Envelope {
        version: header.version,
        robot: RobotId(header.robot),
        session: header.session,
        sequence: header.sequence,
        kind,
        payload_len: header.payload_len,
    };
    Ok((envelope, payload))
}

/// Decodes a whole message: the envelope checks of [`decode_envelope`], then the payload (which must be
/// consumed exactly), then the semantic checks of [`Message::validate`] and that the body's robot is the
/// envelope's (a cloud request names its requester, a cloud its keyframe's owner).
pub fn decode(bytes: &[u8], config: &ProtocolConfig) -> Result<(Envelope, Message), DecodeError> {
    let (envelope, payload) = decode_envelope(bytes, config)?;
    let kind = envelope.kind;
    let message = decode_payload(kind, envelope.version, payload)
        .map_err(|source| DecodeError::Payload { kind, source })?;
    message
        .validate()
        .map_err(|source| DecodeError::Invalid { kind, source })?;
    let body = message.body_robot();
    if body != envelope.robot {
        return Err(DecodeError::RobotMismatch {
            kind,
            envelope: envelope.robot,
            body,
        });
    }
    Ok((envelope, message))
}

fn decode_payload(kind: MessageKind, version: u16, payload: &[u8]) -> Result<Message, postcard::Error> {
    fn exact<'a, T: Deserialize<'a>>(payload: &'a [u8]) -> Result<T, postcard::Error> {
        let (value, rest) = postcard::take_from_bytes::<T>(payload)?;
        if rest.is_empty() {
            Ok(value)
        } else {
            Err(postcard::Error::DeserializeBadEncoding)
        }
    }
    let status = |payload: &[u8]| -> Result<PeerStatus, postcard::Error> {
        if version == 2 {
            exact::<PeerStatusV2>(payload).map(PeerStatus::from)
        } else {
            exact::<PeerStatus>(payload)
        }
    };
    Ok(match kind {
        MessageKind::Hello => Message::Hello(status(payload)?),
        MessageKind::Heartbeat => Message::Heartbeat(status(payload)?),
        MessageKind::Descriptors => Message::Descriptors(exact::<DescriptorBatch>(payload)?),
        MessageKind::CloudRequest => Message::CloudRequest(exact::<CloudRequest>(payload)?),
        MessageKind::Cloud => Message::Cloud(exact::<CloudMsg>(payload)?),
        MessageKind::OdomChain => Message::OdomChain(exact::<OdomChain>(payload)?),
        MessageKind::Loops => Message::Loops(exact::<Loops>(payload)?),
        MessageKind::Frames => Message::Frames(exact::<Frames>(payload)?),
    })
}
