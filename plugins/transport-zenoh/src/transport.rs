//! The `Transport` implementation over a zenoh session: keyed puts out, callback subscribers in (into a
//! queue that `poll` drains, bounded in bytes per peer so a flooding peer loses only its own messages),
//! liveliness tokens for peer presence, and a readiness check (matching subscribers) that tests and the
//! runtime can wait on before the first burst.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use skid_core::slots::{Datagram, Destination, PeerInfo, Transport};
use skid_core::{PluginError, PluginResult, RobotId};
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Session, key_expr::KeyExpr};

use crate::config::{Congestion, Security, ZenohConfig};

/// What zenoh's threads hand to the robot's thread.
#[derive(Debug, Default)]
struct Inbox {
    queue: VecDeque<Datagram>,
    /// Bytes waiting in `queue`, per sending peer.
    queued_bytes: BTreeMap<RobotId, usize>,
    last_heard: BTreeMap<RobotId, Instant>,
    alive: BTreeSet<RobotId>,
    dropped_queue_full: u64,
    dropped_oversized: u64,
}

#[derive(Debug, Default)]
struct Shared {
    inbox: Mutex<Inbox>,
    arrived: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Inbox> {
        self.inbox.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// Counters of messages the transport dropped on receipt.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReceiveDrops {
    pub queue_full: u64,
    pub oversized: u64,
}

/// One robot's zenoh transport.
pub struct ZenohTransport {
    robot: RobotId,
    config: ZenohConfig,
    session: Session,
    shared: Arc<Shared>,
    _subscribers: Vec<Subscriber<()>>,
    _token: LivelinessToken,
}

impl std::fmt::Debug for ZenohTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohTransport")
            .field("robot", &self.robot)
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

fn zenoh_error(what: &str, error: impl std::fmt::Display) -> PluginError {
    PluginError::Transport(format!("zenoh {what}: {error}"))
}

/// The robot number in the last key segment, if it is one.
fn last_robot(key: &str) -> Option<RobotId> {
    key.rsplit('/').next()?.parse().ok().map(RobotId)
}

impl ZenohTransport {
    /// Opens a zenoh session for `robot` of a fleet of `fleet_size` robots (the access control admits
    /// robots `0..fleet_size`) and declares its subscribers and liveliness token.
    pub fn open(robot: RobotId, config: ZenohConfig, fleet_size: u32) -> Result<Self, PluginError> {
        config.validate()?;
        if config.security == Security::PlainTcp {
            tracing::warn!(
                robot = %robot,
                "zenoh runs over plain TCP (security = \"plain_tcp\"): no encryption and no authentication, \
                 any device on the network can join the fleet and forge its messages; use mutual_tls \
                 outside a trusted network"
            );
        }
        let session = zenoh::open(config.to_zenoh(fleet_size)?)
            .wait()
            .map_err(|e| zenoh_error("open", e))?;
        let shared = Arc::new(Shared::default());
        let prefix = &config.key_prefix;
        let mut subscribers = Vec::new();
        for to in [robot.0.to_string(), "all".to_owned()] {
            let shared = Arc::clone(&shared);
            let limit = config.max_message_bytes;
            let max_queued = config.max_queued_bytes;
            let subscriber = session
                .declare_subscriber(format!("{prefix}/msg/{to}/*"))
                .callback(move |sample: Sample| {
                    let Some(from) = last_robot(sample.key_expr().as_str()) else {
                        return;
                    };
                    if from == robot {
                        return;
                    }
                    let payload = sample.payload().to_bytes();
                    let mut inbox = shared.lock();
                    inbox.last_heard.insert(from, Instant::now());
                    if payload.len() > limit {
                        inbox.dropped_oversized += 1;
                        return;
                    }
                    let queued = inbox.queued_bytes.entry(from).or_insert(0);
                    if *queued + payload.len() > max_queued {
                        inbox.dropped_queue_full += 1;
                        return;
                    }
                    *queued += payload.len();
                    inbox.queue.push_back(Datagram {
                        from,
                        payload: payload.into_owned(),
                    });
                    drop(inbox);
                    shared.arrived.notify_all();
                })
                .wait()
                .map_err(|e| zenoh_error("subscriber", e))?;
            subscribers.push(subscriber);
        }
        let presence = Arc::clone(&shared);
        let alive_subscriber = session
            .liveliness()
            .declare_subscriber(format!("{prefix}/alive/*"))
            .history(true)
            .callback(move |sample: Sample| {
                let Some(peer) = last_robot(sample.key_expr().as_str()) else {
                    return;
                };
                if peer == robot {
                    return;
                }
                let mut inbox = presence.lock();
                match sample.kind() {
                    SampleKind::Put => inbox.alive.insert(peer),
                    SampleKind::Delete => inbox.alive.remove(&peer),
                };
            })
            .wait()
            .map_err(|e| zenoh_error("liveliness subscriber", e))?;
        subscribers.push(alive_subscriber);
        let token = session
            .liveliness()
            .declare_token(format!("{prefix}/alive/{}", robot.0))
            .wait()
            .map_err(|e| zenoh_error("liveliness token", e))?;
        Ok(Self {
            robot,
            config,
            session,
            shared,
            _subscribers: subscribers,
            _token: token,
        })
    }

    /// The key a message from this robot to `to` is put on.
    fn key_to(&self, destination: Destination) -> String {
        let to = match destination {
            Destination::Robot(robot) => robot.0.to_string(),
            Destination::AllPeers => "all".to_owned(),
        };
        format!("{}/msg/{to}/{}", self.config.key_prefix, self.robot.0)
    }

    /// Robots whose liveliness token is currently visible.
    pub fn alive_peers(&self) -> BTreeSet<RobotId> {
        self.shared.lock().alive.clone()
    }

    /// Messages dropped on receipt (oversized, or the queue full because `poll` was not called).
    pub fn receive_drops(&self) -> ReceiveDrops {
        let inbox = self.shared.lock();
        ReceiveDrops {
            queue_full: inbox.dropped_queue_full,
            oversized: inbox.dropped_oversized,
        }
    }

    /// True when a message sent to `peer` now would reach its subscriber (its subscription is known
    /// here). Use before a first burst: messages sent earlier are not delivered.
    pub fn is_ready_for(&self, peer: RobotId) -> PluginResult<bool> {
        let key =
            KeyExpr::try_from(self.key_to(Destination::Robot(peer))).map_err(|e| zenoh_error("key", e))?;
        let publisher = self
            .session
            .declare_publisher(key)
            .wait()
            .map_err(|e| zenoh_error("publisher", e))?;
        let status = publisher
            .matching_status()
            .wait()
            .map_err(|e| zenoh_error("matching status", e))?;
        Ok(status.matching())
    }

    /// Waits until every robot in `peers` is alive and ready to receive, or `timeout` passes; returns
    /// whether they all are. A set-up step (tests, start of a run), not for the pipeline's loop.
    pub fn wait_for_peers(&self, peers: &[RobotId], timeout: Duration) -> PluginResult<bool> {
        let deadline = Instant::now() + timeout;
        loop {
            let alive = self.alive_peers();
            let mut ready = true;
            for &peer in peers {
                ready = ready && alive.contains(&peer) && self.is_ready_for(peer)?;
            }
            if ready {
                return Ok(true);
            }
            if Instant::now() >= deadline {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for ZenohTransport {
    fn drop(&mut self) {
        // Closing withdraws the liveliness token at once, so peers see the robot leave.
        if let Err(error) = self.session.close().wait() {
            tracing::warn!("closing the zenoh session of {}: {error}", self.robot);
        }
    }
}

impl Transport for ZenohTransport {
    fn local_robot(&self) -> RobotId {
        self.robot
    }

    fn send(&mut self, destination: Destination, payload: &[u8]) -> PluginResult<()> {
        if payload.len() > self.config.max_message_bytes {
            return Err(PluginError::Transport(format!(
                "message of {} bytes exceeds max_message_bytes = {}",
                payload.len(),
                self.config.max_message_bytes
            )));
        }
        if destination == Destination::Robot(self.robot) {
            return Err(PluginError::InvalidInput(format!(
                "{} cannot send to itself",
                self.robot
            )));
        }
        let congestion = match self.config.congestion {
            Congestion::Drop => CongestionControl::Drop,
            Congestion::Block => CongestionControl::Block,
        };
        self.session
            .put(self.key_to(destination), payload)
            .congestion_control(congestion)
            .wait()
            .map_err(|e| zenoh_error("put", e))
    }

    fn poll(&mut self, timeout: Duration) -> PluginResult<Vec<Datagram>> {
        let deadline = Instant::now() + timeout;
        let mut inbox = self.shared.lock();
        while inbox.queue.is_empty() {
            let now = Instant::now();
            if now >= deadline {
                return Ok(Vec::new());
            }
            inbox = match self.shared.arrived.wait_timeout(inbox, deadline - now) {
                Ok((inbox, _)) => inbox,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        inbox.queued_bytes.clear();
        Ok(inbox.queue.drain(..).collect())
    }

    /// Messages refused before the protocol saw them: by the access control (per peer certificate,
    /// `access_denied robot-3`), for a full per-peer queue and for their size.
    fn refusals(&self) -> BTreeMap<String, u64> {
        let mut refusals: BTreeMap<String, u64> = BTreeMap::new();
        if self.config.security == Security::MutualTls {
            for (peer, count) in crate::refusals::access_denied(&self.session) {
                refusals.insert(format!("access_denied {peer}"), count);
            }
        }
        let drops = self.receive_drops();
        for (class, count) in [("queue_full", drops.queue_full), ("oversized", drops.oversized)] {
            if count > 0 {
                refusals.insert(class.to_owned(), count);
            }
        }
        refusals
    }

    fn peers(&self) -> Vec<PeerInfo> {
        let inbox = self.shared.lock();
        let robots: BTreeSet<RobotId> = inbox
            .alive
            .iter()
            .chain(inbox.last_heard.keys())
            .copied()
            .collect();
        robots
            .into_iter()
            .map(|robot| PeerInfo {
                robot,
                silent_for: inbox.last_heard.get(&robot).map(Instant::elapsed),
            })
            .collect()
    }
}
