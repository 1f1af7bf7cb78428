//! SKiD inter-robot protocol (design guide §6): the messages robots exchange in SKiD-SLAM's distributed
//! pipeline (Sec. III of the paper: light global descriptors first, clouds only for loop candidates,
//! odometry chains for PCM, accepted loops so both sides agree), a versioned envelope with size limits
//! checked before decoding, postcard encoding, byte counters per kind, and duplicate/reorder handling.
//!
//! - [`messages`]: [`Message`] and its bodies, with semantic validation.
//! - [`codec`]: compact cloud (1 cm grid, Morton order, delta varints) and quantised descriptor forms.
//! - [`packed`]: a cloud's wire form, those varints compressed by zstd and unpacked through a bound.
//! - [`wire`]: poses and information matrices on the wire.
//! - [`envelope`]: [`encode`], [`decode`], [`decode_envelope`], [`ProtocolConfig`] and typed errors.
//! - [`endpoint`]: [`ProtocolEndpoint`], numbering, classification and [`Counters`] for one robot.
//! - [`sequence`]: per-peer sequence windows and "newest wins" state.
//!
//! Decoding never panics on arbitrary bytes (see the fuzz-style tests); a malformed message is a
//! [`DecodeError`] naming what was wrong.

pub mod codec;
pub mod counters;
pub mod endpoint;
pub mod envelope;
pub mod messages;
pub mod packed;
pub mod sequence;
pub mod wire;

pub use codec::{CodecError, CompressedPoints, DescriptorEncoding, DescriptorValues};
pub use counters::{Counters, CountersSnapshot, Tally};
pub use endpoint::{Incoming, ProtocolEndpoint, Received};
pub use envelope::{
    DecodeError, EncodeError, Envelope, MAGIC, MIN_SUPPORTED_VERSION, PROTOCOL_VERSION, ProtocolConfig,
    decode, decode_envelope, encode,
};
pub use messages::{
    Capabilities, ChainEdge, CloudMsg, CloudRequest, DescriptorBatch, DescriptorEntry, FrameMsg, Frames,
    HeldKeyframe, InvalidMessage, LoopMsg, Loops, MAX_HELD_PEERS, Message, MessageKind, OdomChain,
    PeerStatus,
};
pub use sequence::{Arrival, NewestWins, PeerSequences, SequenceWindow};
pub use wire::{InformationMsg, PoseMsg};
