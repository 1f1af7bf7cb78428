//! Per-link counters of the loopback hub: what was sent, delivered and dropped (and why), and the
//! one-way latencies, for metrics and for reproducing the paper's latency-versus-distance table.

use serde::{Deserialize, Serialize};
use skid_core::RobotId;

/// Counters of one directed link.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinkStats {
    pub from: RobotId,
    pub to: RobotId,
    pub sent_messages: u64,
    pub sent_bytes: u64,
    pub delivered_messages: u64,
    pub delivered_bytes: u64,
    pub dropped_lost: u64,
    pub dropped_out_of_range: u64,
    /// Link cut, robot isolated or not attached (also when cut while in flight).
    pub dropped_unreachable: u64,
    pub dropped_queue_full: u64,
    /// Messages delivered twice by the link model.
    pub duplicated: u64,
    /// Sum and maximum of the one-way latency of delivered messages (queueing + airtime + latency).
    pub latency_sum_ms: f64,
    pub latency_max_ms: f64,
}

impl LinkStats {
    pub(crate) fn new(from: RobotId, to: RobotId) -> Self {
        Self {
            from,
            to,
            sent_messages: 0,
            sent_bytes: 0,
            delivered_messages: 0,
            delivered_bytes: 0,
            dropped_lost: 0,
            dropped_out_of_range: 0,
            dropped_unreachable: 0,
            dropped_queue_full: 0,
            duplicated: 0,
            latency_sum_ms: 0.0,
            latency_max_ms: 0.0,
        }
    }

    pub(crate) fn record_latency(&mut self, latency_ms: f64, bytes: usize) {
        self.delivered_messages += 1;
        self.delivered_bytes += bytes as u64;
        self.latency_sum_ms += latency_ms;
        self.latency_max_ms = self.latency_max_ms.max(latency_ms);
    }

    /// Mean one-way latency of delivered messages, if any were delivered.
    pub fn mean_latency_ms(&self) -> Option<f64> {
        (self.delivered_messages > 0).then(|| self.latency_sum_ms / self.delivered_messages as f64)
    }
}

/// Every link's counters at one moment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HubStats {
    pub now_nanos: u64,
    pub links: Vec<LinkStats>,
}

impl HubStats {
    /// The counters of the link `from → to`, if it carried anything.
    pub fn link(&self, from: RobotId, to: RobotId) -> Option<&LinkStats> {
        self.links.iter().find(|link| link.from == from && link.to == to)
    }
}
