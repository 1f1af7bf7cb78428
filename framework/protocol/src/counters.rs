//! Per-kind message and byte counters, sent and received, plus rejections by class and duplicates, in a
//! serialisable snapshot the runtime writes into `metrics.json` (the paper's communication comparison,
//! Sec. IV-E, is about exactly these bytes).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::messages::MessageKind;

/// Messages and bytes of one kind in one direction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Tally {
    pub messages: u64,
    pub bytes: u64,
}

impl Tally {
    fn add(&mut self, bytes: usize) {
        self.messages += 1;
        self.bytes += bytes as u64;
    }
}

/// Running counters of one robot's protocol endpoint.
#[derive(Clone, Debug, Default)]
pub struct Counters {
    sent: [Tally; MessageKind::ALL.len()],
    received: [Tally; MessageKind::ALL.len()],
    rejected: BTreeMap<&'static str, Tally>,
    duplicates: Tally,
    stale: Tally,
}

/// A snapshot of [`Counters`], keyed by kind name (`descriptors`, `cloud`, …) and rejection class.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CountersSnapshot {
    pub sent: BTreeMap<String, Tally>,
    pub received: BTreeMap<String, Tally>,
    /// Messages refused by class (`bad_magic`, `oversized`, `invalid`, …); they are not in `received`.
    pub rejected: BTreeMap<String, Tally>,
    /// Messages seen before (same session and sequence); dropped, not in `received`.
    pub duplicates: Tally,
    /// Messages older than the reorder window; dropped, not in `received`.
    pub stale: Tally,
    pub sent_total: Tally,
    pub received_total: Tally,
}

impl Counters {
    pub fn record_sent(&mut self, kind: MessageKind, bytes: usize) {
        self.sent[kind.index()].add(bytes);
    }

    pub fn record_received(&mut self, kind: MessageKind, bytes: usize) {
        self.received[kind.index()].add(bytes);
    }

    pub fn record_rejected(&mut self, class: &'static str, bytes: usize) {
        self.rejected.entry(class).or_default().add(bytes);
    }

    pub fn record_duplicate(&mut self, bytes: usize) {
        self.duplicates.add(bytes);
    }

    pub fn record_stale(&mut self, bytes: usize) {
        self.stale.add(bytes);
    }

    pub fn sent(&self, kind: MessageKind) -> Tally {
        self.sent[kind.index()]
    }

    pub fn received(&self, kind: MessageKind) -> Tally {
        self.received[kind.index()]
    }

    /// Rejections of one class.
    pub fn rejected(&self, class: &str) -> Tally {
        self.rejected.get(class).copied().unwrap_or_default()
    }

    pub fn duplicates(&self) -> Tally {
        self.duplicates
    }

    /// The counters as a serialisable snapshot.
    pub fn snapshot(&self) -> CountersSnapshot {
        let by_kind = |tallies: &[Tally; MessageKind::ALL.len()]| {
            MessageKind::ALL
                .iter()
                .map(|kind| (kind.name().to_owned(), tallies[kind.index()]))
                .collect::<BTreeMap<_, _>>()
        };
        let total = |tallies: &[Tally; MessageKind::ALL.len()]| {
            tallies.iter().fold(Tally::default(), |sum, t| Tally {
                messages: sum.messages + t.messages,
                bytes: sum.bytes + t.bytes,
            })
        };
        CountersSnapshot {
            sent: by_kind(&self.sent),
            received: by_kind(&self.received),
            rejected: self.rejected.iter().map(|(k, v)| ((*k).to_owned(), *v)).collect(),
            duplicates: self.duplicates,
            stale: self.stale,
            sent_total: total(&self.sent),
            received_total: total(&self.received),
        }
    }
}
