//! One robot's endpoint on a loopback hub: the `Transport` slot implementation.

use std::any::Any;
use std::sync::Arc;
use std::time::{Duration, Instant};

use skid_core::slots::{Datagram, Destination, NetworkTotals, PeerInfo, SimulatedNetwork, Transport};
use skid_core::{PluginError, PluginResult, RobotId};

use crate::hub::{ClockMode, HubState, LoopbackHub};

/// A robot attached to a [`LoopbackHub`]; dropping it detaches the robot.
#[derive(Debug)]
pub struct LoopbackEndpoint {
    hub: LoopbackHub,
    robot: RobotId,
}

impl LoopbackHub {
    /// Attaches `robot`; a robot that is attached already is an error. Dropping the endpoint detaches it
    /// (its undelivered messages are lost, as when a robot's process dies); it may attach again later.
    pub fn endpoint(&self, robot: RobotId) -> Result<LoopbackEndpoint, PluginError> {
        self.attach(robot)?;
        Ok(LoopbackEndpoint::new(self.clone(), robot))
    }
}

impl LoopbackEndpoint {
    fn new(hub: LoopbackHub, robot: RobotId) -> Self {
        Self { hub, robot }
    }

    /// The hub this endpoint is attached to.
    pub fn hub(&self) -> &LoopbackHub {
        &self.hub
    }

    /// Takes every message due by now; returns the messages and the time of the next pending one.
    fn take_due(&self, state: &mut HubState) -> (Vec<Datagram>, Option<u64>) {
        let now = self.hub.now_locked(state);
        let mut due = Vec::new();
        loop {
            let Some(inbox) = state.inboxes.get_mut(&self.robot) else {
                return (due, None);
            };
            let next = inbox.queue.peek().map(|message| message.0.deliver_at_nanos);
            match next {
                Some(at) if at <= now => {}
                _ => return (due, next),
            }
            let Some(std::cmp::Reverse(message)) = inbox.queue.pop() else {
                return (due, None);
            };
            let connected = LoopbackHub::is_connected(state, message.from, self.robot);
            if connected && let Some(inbox) = state.inboxes.get_mut(&self.robot) {
                inbox.last_heard.insert(message.from, now);
            }
            LoopbackHub::record_delivery(state, &message, self.robot, connected);
            if connected {
                due.push(Datagram {
                    from: message.from,
                    payload: message.payload.to_vec(),
                });
            }
        }
    }
}

impl Drop for LoopbackEndpoint {
    fn drop(&mut self) {
        self.hub.lock().inboxes.remove(&self.robot);
    }
}

impl Transport for LoopbackEndpoint {
    fn local_robot(&self) -> RobotId {
        self.robot
    }

    fn send(&mut self, destination: Destination, payload: &[u8]) -> PluginResult<()> {
        let limit = self.hub.config().max_message_bytes;
        if payload.len() > limit {
            return Err(PluginError::Transport(format!(
                "message of {} bytes exceeds the loopback limit of {limit} bytes",
                payload.len()
            )));
        }
        let receivers: Vec<RobotId> = match destination {
            Destination::Robot(robot) if robot == self.robot => {
                return Err(PluginError::InvalidInput(format!(
                    "{robot} cannot send to itself"
                )));
            }
            Destination::Robot(robot) => vec![robot],
            Destination::AllPeers => {
                let state = self.hub.lock();
                state
                    .inboxes
                    .keys()
                    .copied()
                    .filter(|&robot| robot != self.robot)
                    .collect()
            }
        };
        self.hub.transmit(self.robot, &receivers, payload);
        Ok(())
    }

    /// On a simulated clock this returns what is due at the current simulated time without waiting
    /// (time stands still until the runtime advances it). On the wall clock it waits up to `timeout` for
    /// the first message, then returns everything due.
    fn poll(&mut self, timeout: Duration) -> PluginResult<Vec<Datagram>> {
        let deadline = Instant::now() + timeout;
        let mut state = self.hub.lock();
        loop {
            let (due, next_nanos) = self.take_due(&mut state);
            if !due.is_empty() || self.hub.config().clock == ClockMode::Simulated {
                return Ok(due);
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(due);
            }
            let mut wait = deadline - now;
            if let Some(next) = next_nanos {
                let until_next = Duration::from_nanos(next.saturating_sub(self.hub.now_locked(&state)));
                wait = wait.min(until_next.max(Duration::from_micros(50)));
            }
            // Any send wakes the wait early; the loop re-checks under the same lock, so no wake-up is lost.
            state = match self.hub.inner.arrived.wait_timeout(state, wait) {
                Ok((state, _)) => state,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
    }

    fn peers(&self) -> Vec<PeerInfo> {
        let state = self.hub.lock();
        let now = self.hub.now_locked(&state);
        let heard = state
            .inboxes
            .get(&self.robot)
            .map(|inbox| inbox.last_heard.clone())
            .unwrap_or_default();
        let mut robots: Vec<RobotId> = state
            .inboxes
            .keys()
            .chain(heard.keys())
            .copied()
            .filter(|&robot| robot != self.robot)
            .collect();
        robots.sort();
        robots.dedup();
        robots
            .into_iter()
            .map(|robot| PeerInfo {
                robot,
                silent_for: heard
                    .get(&robot)
                    .map(|&at| Duration::from_nanos(now.saturating_sub(at))),
            })
            .collect()
    }

    fn simulated_network(&self) -> Option<Arc<dyn SimulatedNetwork>> {
        Some(Arc::new(self.hub.clone()))
    }
}

/// The hub is the simulated network the runtime drives.
impl SimulatedNetwork for LoopbackHub {
    fn now_nanos(&self) -> u64 {
        LoopbackHub::now_nanos(self)
    }

    fn advance_to(&self, nanos: u64) {
        LoopbackHub::advance_to(self, nanos);
    }

    fn set_position(&self, robot: RobotId, position_m: [f64; 3]) {
        LoopbackHub::set_position(self, robot, position_m);
    }

    fn totals(&self) -> NetworkTotals {
        let stats = self.stats();
        let mut totals = NetworkTotals::default();
        let mut latency_sum_ms = 0.0;
        for link in &stats.links {
            totals.sent_messages += link.sent_messages;
            totals.delivered_messages += link.delivered_messages;
            totals.lost += link.dropped_lost;
            totals.queue_full += link.dropped_queue_full;
            totals.unreachable += link.dropped_out_of_range + link.dropped_unreachable;
            latency_sum_ms += link.latency_sum_ms;
        }
        if totals.delivered_messages > 0 {
            totals.mean_latency_ms = latency_sum_ms / totals.delivered_messages as f64;
        }
        totals
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}
