//! Duplicate and reorder handling: a sliding window of seen sequence numbers per peer session (the
//! anti-replay window of RFC 6479, used here for lossy radio links that duplicate and reorder), and a
//! "newest wins" map for state that must not regress when an older message arrives late.

use std::collections::HashMap;
use std::hash::Hash;

use skid_core::RobotId;

/// How a sequence number relates to what was seen before from the same peer session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arrival {
    /// The next expected number.
    InOrder,
    /// Newer than expected: `missing` numbers were skipped (lost, or still on their way).
    AfterGap { missing: u64 },
    /// Older than the newest seen but not seen before: it was overtaken.
    Late,
    /// Seen before.
    Duplicate,
    /// Too old to tell (beyond the window); treated as a duplicate.
    Stale,
    /// The first message of a session; `restarted` when the peer had another session before.
    First { restarted: bool },
}

impl Arrival {
    /// True when the message is new and should be processed.
    pub fn is_new(self) -> bool {
        !matches!(self, Self::Duplicate | Self::Stale)
    }
}

/// Seen sequence numbers of one peer session within a window behind the newest.
#[derive(Clone, Debug)]
pub struct SequenceWindow {
    highest: u64,
    bits: Vec<u64>,
}

impl SequenceWindow {
    /// A window that has seen `first`, remembering `window` numbers (rounded up to a multiple of 64).
    pub fn new(first: u64, window: u32) -> Self {
        let words = (window.max(64) as usize).div_ceil(64);
        let mut this = Self {
            highest: first,
            bits: vec![0; words],
        };
        this.mark(first);
        this
    }

    fn capacity(&self) -> u64 {
        self.bits.len() as u64 * 64
    }

    fn slot(&self, sequence: u64) -> (usize, u64) {
        let position = sequence % self.capacity();
        ((position / 64) as usize, 1u64 << (position % 64))
    }

    fn mark(&mut self, sequence: u64) {
        let (word, bit) = self.slot(sequence);
        self.bits[word] |= bit;
    }

    fn is_marked(&self, sequence: u64) -> bool {
        let (word, bit) = self.slot(sequence);
        self.bits[word] & bit != 0
    }

    /// Classifies `sequence` and records it.
    pub fn observe(&mut self, sequence: u64) -> Arrival {
        if sequence > self.highest {
            let ahead = sequence - self.highest;
            if ahead >= self.capacity() {
                self.bits.iter_mut().for_each(|word| *word = 0);
            } else {
                for skipped in self.highest + 1..sequence {
                    let (word, bit) = self.slot(skipped);
                    self.bits[word] &= !bit;
                }
            }
            self.highest = sequence;
            self.mark(sequence);
            return if ahead == 1 {
                Arrival::InOrder
            } else {
                Arrival::AfterGap { missing: ahead - 1 }
            };
        }
        if self.highest - sequence >= self.capacity() {
            return Arrival::Stale;
        }
        if self.is_marked(sequence) {
            return Arrival::Duplicate;
        }
        self.mark(sequence);
        Arrival::Late
    }
}

/// Sequence windows for every peer, reset when a peer starts a new session.
#[derive(Clone, Debug, Default)]
pub struct PeerSequences {
    window: u32,
    peers: HashMap<RobotId, (u32, SequenceWindow)>,
}

impl PeerSequences {
    pub fn new(window: u32) -> Self {
        Self {
            window,
            peers: HashMap::new(),
        }
    }

    /// Classifies message `sequence` of `robot`'s `session` and records it.
    pub fn observe(&mut self, robot: RobotId, session: u32, sequence: u64) -> Arrival {
        match self.peers.get_mut(&robot) {
            Some((known, window)) if *known == session => window.observe(sequence),
            previous => {
                let restarted = previous.is_some();
                self.peers
                    .insert(robot, (session, SequenceWindow::new(sequence, self.window)));
                Arrival::First { restarted }
            }
        }
    }

    /// The session last seen from `robot`.
    pub fn session(&self, robot: RobotId) -> Option<u32> {
        self.peers.get(&robot).map(|(session, _)| *session)
    }
}

/// Remembers, per key, the `(session, sequence)` of the message that last set it, so that a late
/// message (for example an old `Loops` that still lists a loop since retracted) does not undo a newer
/// one. Keys are typically a loop's keyframe pair or `(robot, "heartbeat")`.
#[derive(Clone, Debug)]
pub struct NewestWins<K> {
    latest: HashMap<K, (u32, u64)>,
}

impl<K> Default for NewestWins<K> {
    fn default() -> Self {
        Self {
            latest: HashMap::new(),
        }
    }
}

impl<K: Eq + Hash> NewestWins<K> {
    /// True (and remembered) when the message `(session, sequence)` is newer than the one that last set
    /// `key`; a new session always wins, since the sender restarted.
    pub fn update(&mut self, key: K, session: u32, sequence: u64) -> bool {
        match self.latest.get_mut(&key) {
            Some(latest) if latest.0 == session && latest.1 >= sequence => false,
            Some(latest) => {
                *latest = (session, sequence);
                true
            }
            None => {
                self.latest.insert(key, (session, sequence));
                true
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_classifies_order_gaps_duplicates_and_stale() {
        let mut window = SequenceWindow::new(0, 64);
        assert_eq!(window.observe(1), Arrival::InOrder);
        assert_eq!(window.observe(4), Arrival::AfterGap { missing: 2 });
        assert_eq!(window.observe(3), Arrival::Late);
        assert_eq!(window.observe(3), Arrival::Duplicate);
        assert_eq!(window.observe(4), Arrival::Duplicate);
        assert_eq!(window.observe(2), Arrival::Late);
        assert_eq!(window.observe(200), Arrival::AfterGap { missing: 195 });
        assert_eq!(window.observe(100), Arrival::Stale);
        // Numbers skipped by the jump are not mistaken for duplicates.
        assert_eq!(window.observe(199), Arrival::Late);
    }

    #[test]
    fn new_session_resets_the_window() {
        let mut peers = PeerSequences::new(128);
        let robot = RobotId(2);
        assert_eq!(peers.observe(robot, 7, 0), Arrival::First { restarted: false });
        assert_eq!(peers.observe(robot, 7, 1), Arrival::InOrder);
        assert_eq!(peers.observe(robot, 7, 1), Arrival::Duplicate);
        assert_eq!(peers.observe(robot, 9, 0), Arrival::First { restarted: true });
        assert_eq!(peers.observe(robot, 9, 1), Arrival::InOrder);
        assert_eq!(peers.session(robot), Some(9));
    }

    #[test]
    fn newest_wins_ignores_late_updates() {
        let mut state = NewestWins::default();
        assert!(state.update("loop", 1, 5));
        assert!(!state.update("loop", 1, 3));
        assert!(!state.update("loop", 1, 5));
        assert!(state.update("loop", 1, 6));
        assert!(state.update("loop", 2, 0));
    }
}
