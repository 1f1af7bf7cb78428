//! What every container reader yields: [`Connection`]s (a topic with its message type and
//! serialization) and [`RawMessage`]s (one serialized message with its receive time), and the
//! [`MessageReader`] trait the ROS 1, MCAP and sqlite3 readers implement.

use std::ops::{Deref, Range};
use std::sync::Arc;

use crate::error::BagError;
use crate::wire::Encoding;

/// A topic as the bag records it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Connection {
    pub topic: String,
    /// The message type in ROS 1 spelling (`sensor_msgs/PointCloud2`); ROS 2's `pkg/msg/Type` is
    /// normalised to it so both kinds of bag are matched alike.
    pub message_type: String,
    /// The message definition text when the bag stores it (ROS 1 connection records, MCAP schemas).
    pub definition: String,
    pub encoding: Encoding,
}

impl Connection {
    pub(crate) fn new(topic: &str, message_type: &str, definition: String, encoding: Encoding) -> Self {
        Self {
            topic: topic.to_owned(),
            message_type: normalise_type(message_type),
            definition,
            encoding,
        }
    }
}

impl Connection {
    /// A topic received live (no stored definition).
    pub fn live(topic: &str, message_type: &str, encoding: Encoding) -> Self {
        Self::new(topic, message_type, String::new(), encoding)
    }
}

/// `pkg/msg/Type` → `pkg/Type`; ROS 1 names are returned as they are.
pub fn normalise_type(message_type: &str) -> String {
    let mut parts = message_type.split('/');
    match (parts.next(), parts.next(), parts.next(), parts.next()) {
        (Some(package), Some("msg"), Some(name), None) => format!("{package}/{name}"),
        _ => message_type.to_owned(),
    }
}

/// One serialized message.
#[derive(Clone, Debug)]
pub struct RawMessage {
    pub connection: Arc<Connection>,
    /// When the recorder received it (bag time), nanoseconds since the epoch.
    pub log_time_nanos: u64,
    /// The serialized message (for CDR, with its encapsulation header).
    pub data: MessageBytes,
}

/// A message's bytes: a range of a shared buffer (a decompressed ROS 1 chunk, which the reader reuses
/// once every message of it has been dropped) or a buffer of its own.
#[derive(Clone, Debug)]
pub struct MessageBytes {
    buffer: Arc<Vec<u8>>,
    range: Range<usize>,
}

impl MessageBytes {
    /// `range` of `buffer`; the range must lie inside the buffer.
    pub(crate) fn shared(buffer: &Arc<Vec<u8>>, range: Range<usize>) -> Self {
        debug_assert!(range.end <= buffer.len());
        Self {
            buffer: Arc::clone(buffer),
            range,
        }
    }
}

/// Hands out message buffers, reusing the last one when every message made from it has been dropped,
/// so reading a bag does not allocate (and page-fault) a fresh buffer per message.
#[derive(Debug, Default)]
pub(crate) struct BufferPool {
    spare: Option<Arc<Vec<u8>>>,
}

impl BufferPool {
    /// A buffer holding a copy of `bytes`.
    pub(crate) fn copy_of(&mut self, bytes: &[u8]) -> MessageBytes {
        let mut buffer = self
            .spare
            .take()
            .and_then(|spare| Arc::try_unwrap(spare).ok())
            .unwrap_or_default();
        buffer.clear();
        buffer.extend_from_slice(bytes);
        let buffer = Arc::new(buffer);
        self.spare = Some(Arc::clone(&buffer));
        MessageBytes::shared(&buffer, 0..bytes.len())
    }
}

impl From<Vec<u8>> for MessageBytes {
    fn from(bytes: Vec<u8>) -> Self {
        let range = 0..bytes.len();
        Self {
            buffer: Arc::new(bytes),
            range,
        }
    }
}

impl Deref for MessageBytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        &self.buffer[self.range.clone()]
    }
}

/// A container reader that streams the messages of selected topics in file order, holding at most one
/// chunk (or one page of rows) in memory.
pub trait MessageReader: Send {
    /// The connections known so far: all of them for an indexed bag, MCAP with a summary, or sqlite3;
    /// for an unindexed ROS 1 bag, those met while reading.
    fn connections(&self) -> Vec<Arc<Connection>>;

    /// Whether [`connections`](Self::connections) is complete before reading any message.
    fn connections_complete(&self) -> bool {
        true
    }

    /// Restricts the messages returned to these topics (all topics when never called).
    fn select_topics(&mut self, topics: &[String]);

    /// The next message of a selected topic, or `None` at the end of the bag.
    fn next_message(&mut self) -> Result<Option<RawMessage>, BagError>;
}
