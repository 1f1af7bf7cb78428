//! The hub that N in-process robots share: it applies the link model to every message, keeps the
//! messages in flight ordered by arrival time, and owns the clock (simulated for bit-for-bit
//! reproducible lockstep runs, or the wall clock for threaded runs).
//!
//! Determinism: every directed link draws from its own ChaCha8 generator seeded from the hub seed and the
//! two robot ids, and messages due at the same instant are delivered in the order they were sent, so a
//! lockstep run that sends the same messages in the same order at the same simulated times gets the
//! same deliveries, losses and duplicates.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BTreeSet, BinaryHeap};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, Weak};
use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use skid_core::{PluginError, RobotId};

use crate::link::LinkModel;
use crate::radio::Radio;
use crate::stats::{HubStats, LinkStats};

/// Where the hub's time comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ClockMode {
    /// Time moves only when the runtime calls [`LoopbackHub::advance_to`]; `poll` never waits.
    #[default]
    Simulated,
    /// Nanoseconds since the hub was created; `poll` waits up to its timeout.
    Wall,
}

/// Everything that shapes a hub's behaviour; robots sharing a hub must agree on it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HubConfig {
    pub clock: ClockMode,
    /// Largest message a robot may send, in bytes.
    pub max_message_bytes: usize,
    pub link: LinkModel,
}

impl Default for HubConfig {
    fn default() -> Self {
        Self {
            clock: ClockMode::Simulated,
            max_message_bytes: 8 << 20,
            link: LinkModel::default(),
        }
    }
}

/// A message on its way.
#[derive(Debug)]
pub(crate) struct InFlight {
    pub deliver_at_nanos: u64,
    pub serial: u64,
    pub sent_at_nanos: u64,
    pub from: RobotId,
    pub payload: Arc<[u8]>,
}

impl PartialEq for InFlight {
    fn eq(&self, other: &Self) -> bool {
        (self.deliver_at_nanos, self.serial) == (other.deliver_at_nanos, other.serial)
    }
}
impl Eq for InFlight {}
impl PartialOrd for InFlight {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for InFlight {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.deliver_at_nanos, self.serial).cmp(&(other.deliver_at_nanos, other.serial))
    }
}

#[derive(Debug, Default)]
pub(crate) struct Inbox {
    pub queue: BinaryHeap<Reverse<InFlight>>,
    /// When each peer was last heard from, in hub nanoseconds.
    pub last_heard: BTreeMap<RobotId, u64>,
}

#[derive(Debug)]
struct LinkState {
    rng: ChaCha8Rng,
    stats: LinkStats,
}

#[derive(Debug)]
pub(crate) struct HubState {
    sim_now_nanos: u64,
    seed: u64,
    next_serial: u64,
    pub inboxes: BTreeMap<RobotId, Inbox>,
    positions: BTreeMap<RobotId, [f64; 3]>,
    /// Each sender's radio (bandwidth is a property of the sender's radio).
    radios: BTreeMap<RobotId, Radio>,
    links: BTreeMap<(RobotId, RobotId), LinkState>,
    cut: BTreeSet<(RobotId, RobotId)>,
    isolated: BTreeSet<RobotId>,
}

/// The shared part of a hub.
#[derive(Debug)]
pub(crate) struct HubInner {
    pub name: String,
    pub config: HubConfig,
    epoch: Instant,
    pub state: Mutex<HubState>,
    pub arrived: Condvar,
}

/// A handle to a hub; clones share it.
#[derive(Clone, Debug)]
pub struct LoopbackHub {
    pub(crate) inner: Arc<HubInner>,
}

static NAMED_HUBS: Mutex<BTreeMap<String, Weak<HubInner>>> = Mutex::new(BTreeMap::new());

fn unordered(a: RobotId, b: RobotId) -> (RobotId, RobotId) {
    if a <= b { (a, b) } else { (b, a) }
}

fn millis_to_nanos(ms: f64) -> u64 {
    // Saturating float-to-int conversion; the values are validated non-negative.
    (ms * 1.0e6).round() as u64
}

impl LoopbackHub {
    /// A private hub (not findable by name). `seed` drives loss, jitter, duplication and reordering.
    pub fn new(config: HubConfig, seed: u64) -> Result<Self, PluginError> {
        Self::create(String::new(), config, seed)
    }

    fn create(name: String, config: HubConfig, seed: u64) -> Result<Self, PluginError> {
        config
            .link
            .validate()
            .map_err(|reason| PluginError::failed("loopback", format!("link model: {reason}")))?;
        Ok(Self {
            inner: Arc::new(HubInner {
                name,
                config,
                epoch: Instant::now(),
                state: Mutex::new(HubState {
                    sim_now_nanos: 0,
                    seed,
                    next_serial: 0,
                    inboxes: BTreeMap::new(),
                    positions: BTreeMap::new(),
                    radios: BTreeMap::new(),
                    links: BTreeMap::new(),
                    cut: BTreeSet::new(),
                    isolated: BTreeSet::new(),
                }),
                arrived: Condvar::new(),
            }),
        })
    }

    /// The process-wide hub called `name`, created with `config` and `seed` if no live hub has that name.
    /// A live hub with another config is an error (robots sharing a hub must agree on the link model).
    /// The hub lives while an endpoint or a handle holds it.
    pub fn named(name: &str, config: HubConfig, seed: u64) -> Result<Self, PluginError> {
        let mut hubs = NAMED_HUBS.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        hubs.retain(|_, hub| hub.strong_count() > 0);
        if let Some(inner) = hubs.get(name).and_then(Weak::upgrade) {
            if inner.config != config {
                return Err(PluginError::failed(
                    "loopback",
                    format!(
                        "hub `{name}` already exists with another configuration; robots sharing a hub must use the same [transport.loopback] settings"
                    ),
                ));
            }
            return Ok(Self { inner });
        }
        let hub = Self::create(name.to_owned(), config, seed)?;
        hubs.insert(name.to_owned(), Arc::downgrade(&hub.inner));
        Ok(hub)
    }

    /// The live hub called `name`, if any (for the runtime to drive its clock and robot positions).
    pub fn find(name: &str) -> Option<Self> {
        let hubs = NAMED_HUBS.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        hubs.get(name).and_then(Weak::upgrade).map(|inner| Self { inner })
    }

    pub fn name(&self) -> &str {
        &self.inner.name
    }

    pub fn config(&self) -> &HubConfig {
        &self.inner.config
    }

    pub(crate) fn lock(&self) -> MutexGuard<'_, HubState> {
        self.inner
            .state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Gives `robot` an inbox; a robot that is attached already is an error (the endpoint is made in
    /// `endpoint.rs`, [`LoopbackHub::endpoint`]).
    pub(crate) fn attach(&self, robot: RobotId) -> Result<(), PluginError> {
        let mut state = self.lock();
        if state.inboxes.contains_key(&robot) {
            return Err(PluginError::failed(
                "loopback",
                format!("{robot} is already attached to hub `{}`", self.inner.name),
            ));
        }
        state.inboxes.insert(robot, Inbox::default());
        Ok(())
    }

    /// The hub's current time in nanoseconds.
    pub fn now_nanos(&self) -> u64 {
        let state = self.lock();
        self.now_locked(&state)
    }

    pub(crate) fn now_locked(&self, state: &HubState) -> u64 {
        match self.inner.config.clock {
            ClockMode::Simulated => state.sim_now_nanos,
            // Saturates after 584 years.
            ClockMode::Wall => u64::try_from(self.inner.epoch.elapsed().as_nanos()).unwrap_or(u64::MAX),
        }
    }

    /// Moves simulated time forward to `nanos` (earlier times are ignored; the clock never goes back).
    /// Does nothing on a wall-clock hub.
    pub fn advance_to(&self, nanos: u64) {
        let mut state = self.lock();
        state.sim_now_nanos = state.sim_now_nanos.max(nanos);
        drop(state);
        self.inner.arrived.notify_all();
    }

    /// Sets a robot's position (metres, any common world frame) for range-dependent degradation. Robots
    /// without a position are treated as next to everyone.
    pub fn set_position(&self, robot: RobotId, position_m: [f64; 3]) {
        if position_m.iter().all(|v| v.is_finite()) {
            self.lock().positions.insert(robot, position_m);
        }
    }

    /// Cuts the link between `a` and `b` in both directions; messages in flight on it are lost.
    pub fn cut_link(&self, a: RobotId, b: RobotId) {
        self.lock().cut.insert(unordered(a, b));
    }

    pub fn restore_link(&self, a: RobotId, b: RobotId) {
        self.lock().cut.remove(&unordered(a, b));
    }

    /// Cuts every link of `robot` (it keeps running but hears nobody and nobody hears it).
    pub fn isolate(&self, robot: RobotId) {
        self.lock().isolated.insert(robot);
    }

    pub fn rejoin(&self, robot: RobotId) {
        self.lock().isolated.remove(&robot);
    }

    /// Puts raw bytes in `to`'s inbox as if `from` had sent them, due now, bypassing the link model and
    /// the size limit: for fault tests (a peer sending malformed or oversized messages). Does nothing when
    /// `to` is not attached.
    pub fn inject(&self, from: RobotId, to: RobotId, payload: &[u8]) {
        let mut state = self.lock();
        let now = self.now_locked(&state);
        let serial = state.next_serial;
        state.next_serial += 1;
        let Some(inbox) = state.inboxes.get_mut(&to) else {
            return;
        };
        inbox.queue.push(Reverse(InFlight {
            deliver_at_nanos: now,
            serial,
            sent_at_nanos: now,
            from,
            payload: Arc::from(payload),
        }));
        drop(state);
        self.inner.arrived.notify_all();
    }

    /// Per-link counters and latencies.
    pub fn stats(&self) -> HubStats {
        let state = self.lock();
        HubStats {
            now_nanos: self.now_locked(&state),
            links: state.links.values().map(|link| link.stats.clone()).collect(),
        }
    }

    /// Distance between two robots, 0 when either has no position.
    fn distance_m(state: &HubState, a: RobotId, b: RobotId) -> f64 {
        match (state.positions.get(&a), state.positions.get(&b)) {
            (Some(p), Some(q)) => p
                .iter()
                .zip(q)
                .map(|(u, v)| (u - v) * (u - v))
                .sum::<f64>()
                .sqrt(),
            _ => 0.0,
        }
    }

    pub(crate) fn is_connected(state: &HubState, a: RobotId, b: RobotId) -> bool {
        !state.cut.contains(&unordered(a, b)) && !state.isolated.contains(&a) && !state.isolated.contains(&b)
    }

    /// Applies the link model to one message from `from` to each of `receivers` and queues what survives.
    pub(crate) fn transmit(&self, from: RobotId, receivers: &[RobotId], payload: &[u8]) {
        let model = &self.inner.config.link;
        let payload: Arc<[u8]> = Arc::from(payload);
        let mut state = self.lock();
        let now = self.now_locked(&state);
        let seed = state.seed;
        // The sender's radio sends once at the slowest rate among the receivers in range.
        let qualities: Vec<_> = receivers
            .iter()
            .map(|&to| model.quality_at(Self::distance_m(&state, from, to)))
            .collect();
        let slowest_bps = qualities
            .iter()
            .flatten()
            .map(|q| q.bandwidth_bps)
            .fold(f64::INFINITY, f64::min);
        let airtime_nanos = if slowest_bps.is_finite() {
            millis_to_nanos(payload.len() as f64 * 8.0 / slowest_bps * 1.0e3)
        } else {
            0
        };
        let any_in_range = qualities.iter().any(Option::is_some);
        let sparse = payload.len() <= model.sparse_bytes;
        let max_wait_nanos = millis_to_nanos(model.max_queue_ms);
        let sent = if any_in_range {
            let radio = state.radios.entry(from).or_default();
            radio.send(now, airtime_nanos, sparse, max_wait_nanos)
        } else {
            Some(now + airtime_nanos)
        };
        let queue_full = sent.is_none();
        let done_at = sent.unwrap_or(now);
        let mut delivered_any = false;
        for (&to, quality) in receivers.iter().zip(&qualities) {
            let connected = Self::is_connected(&state, from, to);
            let attached = state.inboxes.contains_key(&to);
            let link = state.links.entry((from, to)).or_insert_with(|| LinkState {
                rng: ChaCha8Rng::seed_from_u64(
                    seed ^ (u64::from(from.0) << 32 | u64::from(to.0)).wrapping_mul(0x9e37_79b9_7f4a_7c15),
                ),
                stats: LinkStats::new(from, to),
            });
            link.stats.sent_messages += 1;
            link.stats.sent_bytes += payload.len() as u64;
            let Some(quality) = quality else {
                link.stats.dropped_out_of_range += 1;
                continue;
            };
            if !connected || !attached {
                link.stats.dropped_unreachable += 1;
                continue;
            }
            if queue_full {
                link.stats.dropped_queue_full += 1;
                continue;
            }
            // Fixed draws per message keep the streams aligned whatever the outcome.
            let lost = link.rng.random::<f64>() < quality.loss;
            let copies = if link.rng.random::<f64>() < model.duplicate {
                2
            } else {
                1
            };
            let held_back = link.rng.random::<f64>() < model.reorder;
            let jitters = [link.rng.random::<f64>(), link.rng.random::<f64>()];
            if lost {
                link.stats.dropped_lost += 1;
                continue;
            }
            let mut arrivals = Vec::with_capacity(2);
            for jitter in jitters.iter().take(copies) {
                let mut latency_ms = quality.latency_ms + jitter * model.jitter_ms;
                if held_back {
                    latency_ms += model.reorder_delay_ms;
                }
                arrivals.push(done_at + millis_to_nanos(latency_ms));
            }
            if copies == 2 {
                link.stats.duplicated += 1;
            }
            for deliver_at_nanos in arrivals {
                let serial = state.next_serial;
                state.next_serial += 1;
                if let Some(inbox) = state.inboxes.get_mut(&to) {
                    inbox.queue.push(Reverse(InFlight {
                        deliver_at_nanos,
                        serial,
                        sent_at_nanos: now,
                        from,
                        payload: Arc::clone(&payload),
                    }));
                    delivered_any = true;
                }
            }
        }
        drop(state);
        if delivered_any {
            self.inner.arrived.notify_all();
        }
    }

    /// Records a delivery (or a loss to a link cut while the message was in flight) in the link stats.
    pub(crate) fn record_delivery(state: &mut HubState, message: &InFlight, to: RobotId, delivered: bool) {
        if let Some(link) = state.links.get_mut(&(message.from, to)) {
            if delivered {
                let latency_ms = (message.deliver_at_nanos - message.sent_at_nanos) as f64 / 1.0e6;
                link.stats.record_latency(latency_ms, message.payload.len());
            } else {
                link.stats.dropped_unreachable += 1;
            }
        }
    }
}
