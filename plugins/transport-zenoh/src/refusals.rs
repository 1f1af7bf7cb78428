//! Counting what zenoh's access control dropped on arrival, by the certificate of the peer that sent it.
//!
//! The ACL runs inside zenoh, so its refusals never reach the transport's callbacks. Zenoh's statistics
//! (its `stats` feature) count every dropped message by reason and by the peer's certificate common
//! name, and the session's own admin space serves them as OpenMetrics text at
//! `@/<zid>/peer/metrics`; this module asks for them and sums the `access-control` drops received.

use std::collections::BTreeMap;
use std::time::Duration;

use zenoh::{Session, Wait};

/// How long the session's own admin space may take to answer.
const QUERY_TIMEOUT: Duration = Duration::from_secs(2);

/// The value of label `name` in one OpenMetrics sample line.
fn label<'a>(line: &'a str, name: &str) -> Option<&'a str> {
    let start = line.find(&format!("{name}=\""))? + name.len() + 2;
    let length = line[start..].find('"')?;
    Some(&line[start..start + length])
}

/// Messages received and dropped by the access control, by the sender's certificate common name
/// (`unknown` without one), summed from OpenMetrics text.
pub fn access_denied_by_peer(metrics: &str) -> BTreeMap<String, u64> {
    let mut denied = BTreeMap::new();
    for line in metrics.lines() {
        let Some((series, value)) = line.rsplit_once(' ') else {
            continue;
        };
        let received_and_dropped =
            series.contains("rx_network_message_dropped_payload") && series.contains("_count{");
        // Only the per-peer series: zenoh also reports a total without peer labels.
        let per_peer = label(series, "remote_zid").is_some();
        if !received_and_dropped || !per_peer || label(series, "reason") != Some("access-control") {
            continue;
        }
        let Ok(count) = value.trim().parse::<f64>() else {
            continue;
        };
        let peer = label(series, "remote_cn").unwrap_or("unknown").to_owned();
        *denied.entry(peer).or_insert(0) += count as u64;
    }
    denied
}

/// The access-control drops of `session` so far, by peer certificate; empty when the admin space does
/// not answer (the counts are then unknown, not zero, and a debug line says so).
pub fn access_denied(session: &Session) -> BTreeMap<String, u64> {
    let selector = format!(
        "@/{}/peer/metrics?compression=false;descriptors=false;disconnected=true;per_key=false",
        session.zid()
    );
    let replies = match session.get(selector).timeout(QUERY_TIMEOUT).wait() {
        Ok(replies) => replies,
        Err(error) => {
            tracing::debug!("zenoh metrics query failed: {error}");
            return BTreeMap::new();
        }
    };
    let mut denied = BTreeMap::new();
    while let Ok(reply) = replies.recv() {
        let Ok(sample) = reply.result() else {
            continue;
        };
        let text = String::from_utf8_lossy(&sample.payload().to_bytes()).into_owned();
        for (peer, count) in access_denied_by_peer(&text) {
            *denied.entry(peer).or_insert(0) += count;
        }
    }
    denied
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_access_control_drops_by_certificate() {
        let text = "\
rx_network_message_dropped_payload_bytes_count{remote_zid=\"a1\",remote_cn=\"robot-3\",message=\"put\",reason=\"access-control\"} 4
rx_network_message_dropped_payload_bytes_count{remote_zid=\"a1\",remote_cn=\"robot-3\",message=\"declare_subscriber\",reason=\"access-control\"} 2
rx_network_message_dropped_payload_bytes_sum{remote_zid=\"a1\",remote_cn=\"robot-3\",reason=\"access-control\"} 900
rx_network_message_dropped_payload_bytes_count{message=\"put\",reason=\"access-control\"} 6
rx_network_message_dropped_payload_bytes_count{remote_zid=\"b2\",remote_cn=\"robot-1\",reason=\"congestion\"} 7
tx_network_message_dropped_payload_bytes_count{remote_zid=\"b2\",remote_cn=\"robot-1\",reason=\"access-control\"} 5
";
        let denied = access_denied_by_peer(text);
        assert_eq!(denied.len(), 1);
        assert_eq!(denied.get("robot-3"), Some(&6));
    }
}
