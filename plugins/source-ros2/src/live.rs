//! Live ROS 2 topics as a message stream: one zenoh subscriber per topic on `rmw_zenoh`'s data key
//! expressions, `<domain id>/<topic without its leading slash>/<type>/<type hash>` with the type written
//! the DDS way (`sensor_msgs::msg::dds_::PointCloud2_`) — the mapping of the rmw_zenoh design document
//! (github.com/ros2/rmw_zenoh, docs/design.md). Payloads are CDR messages with their encapsulation header;
//! the attachment (sequence number, source timestamp, publisher GID) is not needed to decode them and is
//! ignored. Messages wait in a queue bounded in bytes; when the consumer falls behind, new ones are
//! dropped and counted rather than blocking zenoh.

use std::collections::{HashMap, VecDeque};
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use skid_bag::{BagError, Connection, Encoding, MessageReader, RawMessage};
use zenoh::Wait;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;

/// `pkg::msg::dds_::Type_` → `pkg/Type`; `None` for a chunk that is not a ROS 2 type.
pub fn type_from_dds(chunk: &str) -> Option<String> {
    let mut parts = chunk.split("::");
    let (Some(package), Some("msg"), Some("dds_"), Some(name), None) = (
        parts.next(),
        parts.next(),
        parts.next(),
        parts.next(),
        parts.next(),
    ) else {
        return None;
    };
    let name = name.strip_suffix('_').unwrap_or(name);
    (!package.is_empty() && !name.is_empty()).then(|| format!("{package}/{name}"))
}

/// The key expression that matches every publisher of `topic` in `domain_id`, whatever its type hash.
pub fn topic_key(domain_id: u32, topic: &str) -> String {
    format!("{domain_id}/{}/*/*", topic.trim_start_matches('/'))
}

#[derive(Default)]
struct Inbox {
    queue: VecDeque<RawMessage>,
    queued_bytes: usize,
    dropped: u64,
    connections: HashMap<String, Arc<Connection>>,
}

#[derive(Default)]
struct Shared {
    inbox: Mutex<Inbox>,
    arrived: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Inbox> {
        self.inbox
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// Receives the configured topics from a zenoh session.
pub struct LiveTopics {
    label: PathBuf,
    shared: Arc<Shared>,
    idle_timeout: Option<Duration>,
    _subscribers: Vec<Subscriber<()>>,
    _session: zenoh::Session,
}

fn now_nanos() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

impl LiveTopics {
    /// Subscribes to `topics` in `domain_id` on `session`; the stream ends after `idle_timeout` without
    /// a message (`None`: never).
    pub fn subscribe(
        session: zenoh::Session,
        domain_id: u32,
        topics: &[String],
        max_queued_bytes: usize,
        idle_timeout: Option<Duration>,
    ) -> Result<Self, String> {
        let shared = Arc::new(Shared::default());
        let mut subscribers = Vec::new();
        for topic in topics {
            let prefix = format!("{domain_id}/{}/", topic.trim_start_matches('/'));
            let shared = Arc::clone(&shared);
            let name = topic.clone();
            let subscriber = session
                .declare_subscriber(topic_key(domain_id, topic))
                .callback(move |sample: Sample| {
                    let key = sample.key_expr().as_str();
                    let type_chunk = key.strip_prefix(&prefix).and_then(|rest| rest.split('/').next());
                    let Some(message_type) = type_chunk.and_then(type_from_dds) else {
                        tracing::warn!("ignoring {key}: not an rmw_zenoh data key of {name}");
                        return;
                    };
                    let data = sample.payload().to_bytes().into_owned();
                    let mut inbox = shared.lock();
                    if inbox.queued_bytes + data.len() > max_queued_bytes {
                        inbox.dropped += 1;
                        return;
                    }
                    let connection =
                        Arc::clone(inbox.connections.entry(name.clone()).or_insert_with(|| {
                            Arc::new(Connection::live(&name, &message_type, Encoding::Cdr))
                        }));
                    inbox.queued_bytes += data.len();
                    inbox.queue.push_back(RawMessage {
                        connection,
                        log_time_nanos: now_nanos(),
                        data: data.into(),
                    });
                    drop(inbox);
                    shared.arrived.notify_all();
                })
                .wait()
                .map_err(|e| format!("subscribing to {topic}: {e}"))?;
            subscribers.push(subscriber);
        }
        let label = PathBuf::from(format!("ros2 topics in domain {domain_id}"));
        Ok(Self {
            label,
            shared,
            idle_timeout,
            _subscribers: subscribers,
            _session: session,
        })
    }

    /// What errors name this stream by.
    pub fn label(&self) -> PathBuf {
        self.label.clone()
    }

    /// Messages dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.shared.lock().dropped
    }
}

impl MessageReader for LiveTopics {
    fn connections(&self) -> Vec<Arc<Connection>> {
        self.shared.lock().connections.values().cloned().collect()
    }

    fn connections_complete(&self) -> bool {
        false
    }

    fn select_topics(&mut self, _topics: &[String]) {}

    fn next_message(&mut self) -> Result<Option<RawMessage>, BagError> {
        let mut inbox = self.shared.lock();
        loop {
            if let Some(message) = inbox.queue.pop_front() {
                inbox.queued_bytes -= message.data.len();
                return Ok(Some(message));
            }
            inbox = match self.idle_timeout {
                None => self
                    .shared
                    .arrived
                    .wait(inbox)
                    .unwrap_or_else(std::sync::PoisonError::into_inner),
                Some(timeout) => {
                    let (inbox, result) = self
                        .shared
                        .arrived
                        .wait_timeout(inbox, timeout)
                        .unwrap_or_else(std::sync::PoisonError::into_inner);
                    if result.timed_out() && inbox.queue.is_empty() {
                        tracing::info!(
                            "{}: no message for {:.1} s; the live source ends",
                            self.label.display(),
                            timeout.as_secs_f64()
                        );
                        return Ok(None);
                    }
                    inbox
                }
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dds_type_names_map_to_ros_types() {
        assert_eq!(
            type_from_dds("sensor_msgs::msg::dds_::PointCloud2_").as_deref(),
            Some("sensor_msgs/PointCloud2")
        );
        assert_eq!(
            type_from_dds("livox_ros_driver2::msg::dds_::CustomMsg_").as_deref(),
            Some("livox_ros_driver2/CustomMsg")
        );
        assert_eq!(type_from_dds("PointCloud2"), None);
        assert_eq!(type_from_dds("a::srv::dds_::B_"), None);
        assert_eq!(topic_key(3, "/robot1/points"), "3/robot1/points/*/*");
    }
}
