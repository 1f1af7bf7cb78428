//! The event ids a topic's event service carries, shared by the node that creates the service and the
//! ports that notify and wait on it.

/// Event id a publisher sends after each sample.
pub(crate) const SAMPLE_EVENT: usize = 1;
/// Event id iceoryx2 sends when a publisher's notifier is dropped (clean shutdown).
pub(crate) const PUBLISHER_LEFT_EVENT: usize = 2;
/// Event id iceoryx2 sends when a dead publisher's notifier is cleaned up (crash).
pub(crate) const PUBLISHER_DIED_EVENT: usize = 3;
