//! A stage's iceoryx2 node: it creates the typed ports through one shared service-builder function (so
//! every participant agrees on types and settings), and it watches for stage processes that died (their
//! node is listed as dead at once; their resources are reclaimed, and subscribers told through the
//! event service's dead-notifier event, when some process runs the cleanup, about once a second).

use std::time::{Duration, Instant};

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use crate::error::{IpcError, IpcResult};
use crate::events::{PUBLISHER_DIED_EVENT, PUBLISHER_LEFT_EVENT};
use crate::port::{TopicPublisher, TopicSubscriber};
use crate::topic::Topic;

/// The publish-subscribe and event services of one topic.
pub(crate) type TopicServices<S, T> = (
    PubSubFactory<S, [<T as Topic>::Item], <T as Topic>::Header>,
    EventFactory<S>,
);

/// How often [`IpcNode::maintain`] cleans up after dead nodes.
pub const CLEANUP_PERIOD: Duration = Duration::from_secs(1);

/// What a cleanup found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CleanupReport {
    /// Dead nodes whose resources were reclaimed.
    pub cleaned: u64,
    /// Dead nodes that could not be cleaned (permissions, or another process is cleaning them).
    pub failed: u64,
}

/// One iceoryx2 node with the topics of a namespace (for example `skid/<run>/robot0`). `S` is
/// `ipc::Service` between processes or `local::Service` between threads of one process: the same
/// typed ports either way.
pub struct IpcNode<S: Service> {
    node: Node<S>,
    namespace: String,
    last_cleanup: Option<Instant>,
}

impl<S: Service> std::fmt::Debug for IpcNode<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IpcNode")
            .field("name", &self.node.name().as_str())
            .field("namespace", &self.namespace)
            .finish_non_exhaustive()
    }
}

/// The node of a stage talking to other processes.
pub type ProcessNode = IpcNode<ipc::Service>;
/// The node of a stage talking to other threads of the same process.
pub type ThreadNode = IpcNode<local::Service>;

fn reason(error: impl std::fmt::Debug) -> String {
    format!("{error:?}")
}

impl<S: Service> IpcNode<S> {
    /// A node called `name` whose services live under `namespace`. iceoryx2's own log is limited to
    /// errors (it warns about the absent config file otherwise).
    pub fn new(name: &str, namespace: &str) -> IpcResult<Self> {
        set_log_level(LogLevel::Error);
        let node_name = NodeName::new(name).map_err(|e| IpcError::Name {
            name: name.into(),
            reason: reason(e),
        })?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<S>()
            .map_err(|e| IpcError::Node {
                name: name.into(),
                reason: reason(e),
            })?;
        Ok(Self {
            node,
            namespace: namespace.trim_end_matches('/').to_owned(),
            last_cleanup: None,
        })
    }

    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    /// The full service name of topic `T`.
    pub fn service_name<T: Topic>(&self) -> String {
        format!("{}/{}", self.namespace, T::NAME)
    }

    fn name_of<T: Topic>(&self) -> IpcResult<ServiceName> {
        let name = self.service_name::<T>();
        ServiceName::new(&name).map_err(|e| IpcError::Name {
            name,
            reason: reason(e),
        })
    }

    /// Opens (or creates) topic `T`'s publish-subscribe and event services. Every port of every process
    /// goes through here, so types and settings always match.
    pub(crate) fn open_topic<T: Topic>(&self) -> IpcResult<TopicServices<S, T>> {
        let name = self.name_of::<T>()?;
        let service_error = |e| IpcError::Service {
            service: self.service_name::<T>(),
            reason: reason(e),
        };
        let pubsub = self
            .node
            .service_builder(&name)
            .publish_subscribe::<[T::Item]>()
            .user_header::<T::Header>()
            .history_size(T::HISTORY)
            .enable_safe_overflow(T::SAFE_OVERFLOW)
            .subscriber_max_buffer_size(T::BUFFER.max(T::HISTORY))
            .max_publishers(4)
            .max_subscribers(16)
            .open_or_create()
            .map_err(|e| service_error(reason(e)))?;
        let event = self
            .node
            .service_builder(&name)
            .event()
            .notifier_dropped_event(EventId::new(PUBLISHER_LEFT_EVENT))
            .notifier_dead_event(EventId::new(PUBLISHER_DIED_EVENT))
            .max_notifiers(4)
            .max_listeners(16)
            .open_or_create()
            .map_err(|e| service_error(reason(e)))?;
        Ok((pubsub, event))
    }

    /// A publisher on topic `T`.
    pub fn publisher<T: Topic>(&self) -> IpcResult<TopicPublisher<S, T>> {
        let (pubsub, event) = self.open_topic::<T>()?;
        TopicPublisher::new(pubsub, event, self.service_name::<T>())
    }

    /// A subscriber on topic `T`.
    pub fn subscriber<T: Topic>(&self) -> IpcResult<TopicSubscriber<S, T>> {
        let (pubsub, event) = self.open_topic::<T>()?;
        TopicSubscriber::new(pubsub, event, self.service_name::<T>())
    }

    /// Names of nodes (of any namespace) whose process died without cleaning up.
    pub fn dead_nodes(&self) -> Vec<String> {
        let mut dead = Vec::new();
        let listed = Node::<S>::list(self.node.config(), |state| {
            if let NodeState::Dead(view) = state {
                let name = view
                    .details()
                    .as_ref()
                    .map_or_else(|| "(unnamed)".to_owned(), |d| d.name().as_str().to_owned());
                dead.push(name);
            }
            CallbackProgression::Continue
        });
        if let Err(error) = listed {
            tracing::warn!("listing iceoryx2 nodes: {error:?}");
        }
        dead
    }

    /// Reclaims the resources of dead nodes and removes them from their services, which wakes their
    /// subscribers with the dead-publisher event.
    pub fn cleanup_dead_nodes(&mut self) -> CleanupReport {
        self.last_cleanup = Some(Instant::now());
        let state = self.node.try_cleanup_dead_nodes();
        CleanupReport {
            cleaned: state.cleanups,
            failed: state.failed_cleanups,
        }
    }

    /// Runs [`Self::cleanup_dead_nodes`] when [`CLEANUP_PERIOD`] has passed since the last one; call it
    /// from the stage's loop.
    pub fn maintain(&mut self) -> CleanupReport {
        match self.last_cleanup {
            Some(at) if at.elapsed() < CLEANUP_PERIOD => CleanupReport::default(),
            _ => self.cleanup_dead_nodes(),
        }
    }
}
