//! Typed publisher and subscriber of one topic. A sample is loaned in shared memory, written once and
//! sent; the subscriber reads the header and the slice in place (no copy, no serialisation). Each send is
//! followed by an event, so a subscriber sleeps in `receive(timeout)` instead of polling.

use std::cell::Cell;
use std::time::{Duration, Instant};

use iceoryx2::port::EventActivation;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut::SampleMut;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use skid_core::CloudView;

use crate::error::{IpcError, IpcResult};
use crate::events::{PUBLISHER_DIED_EVENT, PUBLISHER_LEFT_EVENT, SAMPLE_EVENT};
use crate::topic::{Keyframes, Topic};

fn io_error(operation: &'static str, service: &str, error: impl std::fmt::Debug) -> IpcError {
    IpcError::Io {
        operation,
        service: service.to_owned(),
        reason: format!("{error:?}"),
    }
}

fn port_error(port: &'static str, service: &str, error: impl std::fmt::Debug) -> IpcError {
    IpcError::Port {
        port,
        service: service.to_owned(),
        reason: format!("{error:?}"),
    }
}

/// Sends samples of topic `T`.
pub struct TopicPublisher<S: Service, T: Topic> {
    service: String,
    pubsub: PubSubFactory<S, [T::Item], T::Header>,
    publisher: Publisher<S, [T::Item], T::Header>,
    notifier: Notifier<S>,
}

impl<S: Service, T: Topic> std::fmt::Debug for TopicPublisher<S, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TopicPublisher")
            .field("service", &self.service)
            .finish_non_exhaustive()
    }
}

impl<S: Service, T: Topic> TopicPublisher<S, T> {
    pub(crate) fn new(
        pubsub: PubSubFactory<S, [T::Item], T::Header>,
        event: EventFactory<S>,
        service: String,
    ) -> IpcResult<Self> {
        let publisher = pubsub
            .publisher_builder()
            .initial_max_slice_len(T::INITIAL_MAX_LEN)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .backpressure_strategy(if T::SAFE_OVERFLOW {
                BackpressureStrategy::DiscardData
            } else {
                BackpressureStrategy::RetryUntilDelivered
            })
            .create()
            .map_err(|e| port_error("publisher", &service, e))?;
        let notifier = event
            .notifier_builder()
            .default_event_id(EventId::new(SAMPLE_EVENT))
            .create()
            .map_err(|e| port_error("notifier", &service, e))?;
        Ok(Self {
            service,
            pubsub,
            publisher,
            notifier,
        })
    }

    /// Number of subscribers connected to the topic.
    pub fn subscriber_count(&self) -> usize {
        self.pubsub.dynamic_config().number_of_subscribers()
    }

    /// Waits until at least `count` subscribers exist and connects to them (a ready handshake before a
    /// burst: connections are otherwise made lazily on the next send). Returns whether they appeared.
    pub fn wait_for_subscribers(&self, count: usize, timeout: Duration) -> IpcResult<bool> {
        let deadline = Instant::now() + timeout;
        while self.subscriber_count() < count {
            if Instant::now() >= deadline {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        self.publisher
            .update_connections()
            .map_err(|e| io_error("update_connections", &self.service, e))?;
        Ok(true)
    }

    /// Loans `len` elements in shared memory and fills element `i` with `fill(i)` (the only write); the
    /// header and elements can still be changed in place before [`Loan::send`].
    pub fn loan_with(&self, len: usize, fill: impl FnMut(usize) -> T::Item) -> IpcResult<Loan<'_, S, T>> {
        let sample = self
            .publisher
            .loan_slice_uninit(len)
            .map_err(|e| io_error("loan", &self.service, e))?;
        Ok(Loan {
            sample: sample.write_from_fn(fill),
            publisher: self,
        })
    }

    /// [`Self::loan_with`], then sets `header` and sends. Returns the number of subscribers reached.
    pub fn send_with(
        &self,
        header: T::Header,
        len: usize,
        fill: impl FnMut(usize) -> T::Item,
    ) -> IpcResult<usize> {
        let mut loan = self.loan_with(len, fill)?;
        *loan.header_mut() = header;
        loan.send()
    }

    /// Copies `items` into a loaned sample once and sends it (see [`Self::send_with`]).
    pub fn send_slice(&self, header: T::Header, items: &[T::Item]) -> IpcResult<usize> {
        self.send_with(header, items.len(), |i| items[i])
    }
}

/// A sample written in shared memory and not sent yet.
pub struct Loan<'a, S: Service, T: Topic> {
    sample: SampleMut<S, [T::Item], T::Header>,
    publisher: &'a TopicPublisher<S, T>,
}

impl<S: Service, T: Topic> std::fmt::Debug for Loan<'_, S, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Loan")
            .field("len", &self.sample.payload().len())
            .finish_non_exhaustive()
    }
}

impl<S: Service, T: Topic> Loan<'_, S, T> {
    pub fn header_mut(&mut self) -> &mut T::Header {
        self.sample.user_header_mut()
    }

    pub fn items_mut(&mut self) -> &mut [T::Item] {
        self.sample.payload_mut()
    }

    /// Sends the sample and wakes the subscribers; returns the number of subscribers reached.
    pub fn send(self) -> IpcResult<usize> {
        let service = &self.publisher.service;
        let delivered = self.sample.send().map_err(|e| io_error("send", service, e))?;
        self.publisher
            .notifier
            .notify()
            .map_err(|e| io_error("notify", service, e))?;
        Ok(delivered)
    }
}

/// A received sample: header and elements, read in place in shared memory.
pub struct Received<S: Service, T: Topic> {
    sample: Sample<S, [T::Item], T::Header>,
}

impl<S: Service, T: Topic> std::fmt::Debug for Received<S, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Received")
            .field("header", self.header())
            .field("len", &self.items().len())
            .finish()
    }
}

impl<S: Service, T: Topic> Received<S, T> {
    pub fn header(&self) -> &T::Header {
        self.sample.user_header()
    }

    /// The elements, pointing into the publisher's shared-memory segment.
    pub fn items(&self) -> &[T::Item] {
        self.sample.payload()
    }
}

impl<S: Service> Received<S, Keyframes> {
    /// The keyframe cloud as the view every plugin takes, still in shared memory.
    pub fn cloud(&self) -> CloudView<'_> {
        CloudView::from(self.items())
    }
}

/// What a subscriber learnt from the event service while waiting.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PublisherEvents {
    /// A publisher closed cleanly.
    pub left: u64,
    /// A publisher's process died (reported once some process cleaned up after it).
    pub died: u64,
}

/// Receives samples of topic `T`.
pub struct TopicSubscriber<S: Service, T: Topic> {
    service: String,
    pubsub: PubSubFactory<S, [T::Item], T::Header>,
    subscriber: Subscriber<S, [T::Item], T::Header>,
    listener: Listener<S>,
    events: Cell<PublisherEvents>,
}

impl<S: Service, T: Topic> std::fmt::Debug for TopicSubscriber<S, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TopicSubscriber")
            .field("service", &self.service)
            .finish_non_exhaustive()
    }
}

impl<S: Service, T: Topic> TopicSubscriber<S, T> {
    pub(crate) fn new(
        pubsub: PubSubFactory<S, [T::Item], T::Header>,
        event: EventFactory<S>,
        service: String,
    ) -> IpcResult<Self> {
        let subscriber = pubsub
            .subscriber_builder()
            .buffer_size(T::BUFFER.max(T::HISTORY))
            .create()
            .map_err(|e| port_error("subscriber", &service, e))?;
        let listener = event
            .listener_builder()
            .create()
            .map_err(|e| port_error("listener", &service, e))?;
        Ok(Self {
            service,
            pubsub,
            subscriber,
            listener,
            events: Cell::new(PublisherEvents::default()),
        })
    }

    /// Number of publishers connected to the topic.
    pub fn publisher_count(&self) -> usize {
        self.pubsub.dynamic_config().number_of_publishers()
    }

    /// The next sample if one is waiting.
    pub fn try_receive(&self) -> IpcResult<Option<Received<S, T>>> {
        self.subscriber
            .receive()
            .map(|sample| sample.map(|sample| Received { sample }))
            .map_err(|e| io_error("receive", &self.service, e))
    }

    /// The next sample, sleeping on the event service up to `timeout` when none is waiting.
    pub fn receive(&self, timeout: Duration) -> IpcResult<Option<Received<S, T>>> {
        if let Some(sample) = self.try_receive()? {
            return Ok(Some(sample));
        }
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let mut events = self.events.get();
            let record = |activation: EventActivation| match activation.id.as_value() {
                PUBLISHER_LEFT_EVENT => events.left += activation.count,
                PUBLISHER_DIED_EVENT => events.died += activation.count,
                _ => {}
            };
            // A zero timeout would block indefinitely in the socket wait: take what is there instead.
            let waited = if left.is_zero() {
                self.listener.try_wait(record)
            } else {
                self.listener.timed_wait(record, left)
            };
            let interrupted = match waited {
                Ok(_) => false,
                // A signal woke the wait: hand control back (as after a timeout) so the caller can
                // see whether it was asked to stop.
                Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => true,
                Err(error) => return Err(io_error("wait", &self.service, error)),
            };
            self.events.set(events);
            if let Some(sample) = self.try_receive()? {
                return Ok(Some(sample));
            }
            if left.is_zero() || events.died > 0 || interrupted {
                return Ok(None);
            }
        }
    }

    /// Publisher departures seen since the last call (cleared by the call).
    pub fn take_publisher_events(&self) -> PublisherEvents {
        self.events.take()
    }
}
