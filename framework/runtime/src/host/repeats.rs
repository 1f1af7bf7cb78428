//! Repeats of the messages that state what a robot holds: its accepted loops with each peer and the
//! frames of the robots it merged with. Both are sent when they change, once, and nothing acknowledges
//! them; on a weak link (loss grows with range, and a radio busy with clouds drops what would wait too
//! long) one lost `Loops` message leaves the peer a loop short of a decision, and one lost `Frames`
//! message leaves every robot that joins through this one without a frame. So after a change the
//! current state is sent again at doubling intervals, a few times. The receiver takes a state it already
//! holds as a no-op, so a repeat costs only its bytes. Kimera-Multi (Tian et al., 2022) acknowledges
//! loops instead; repeats need no new message and no reply over the same weak link.

use std::collections::BTreeMap;

/// The first repeat follows a change after this long, in the host's clock; each later one waits twice
/// as long as the one before, up to [`LONGEST_WAIT_NANOS`].
pub(crate) const FIRST_REPEAT_NANOS: u64 = 2_000_000_000;

/// The longest wait between two repeats.
pub(crate) const LONGEST_WAIT_NANOS: u64 = 8_000_000_000;

/// Repeats after a change (at 2, 6, 14, 22, 30 and 38 s): with three messages in ten lost, the state
/// fails to arrive in all seven copies about twice in ten thousand.
pub(crate) const REPEATS: u32 = 6;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Due {
    next_nanos: u64,
    wait_nanos: u64,
    left: u32,
}

/// When each keyed state (a peer's loops, the frames) is next repeated.
#[derive(Debug)]
pub(crate) struct Repeats<K> {
    due: BTreeMap<K, Due>,
}

impl<K> Default for Repeats<K> {
    fn default() -> Self {
        Self { due: BTreeMap::new() }
    }
}

impl<K: Ord + Copy> Repeats<K> {
    /// The state under `key` changed and was sent at `now_nanos`: repeat it from the first interval.
    pub(crate) fn changed(&mut self, key: K, now_nanos: u64) {
        self.due.insert(
            key,
            Due {
                next_nanos: now_nanos.saturating_add(FIRST_REPEAT_NANOS),
                wait_nanos: FIRST_REPEAT_NANOS,
                left: REPEATS,
            },
        );
    }

    /// Whether any state is still to be repeated.
    pub(crate) fn pending(&self) -> bool {
        !self.due.is_empty()
    }

    /// The keys whose state is to be sent again at `now_nanos`; each counts as repeated.
    pub(crate) fn take_due(&mut self, now_nanos: u64) -> Vec<K> {
        let keys: Vec<K> = self
            .due
            .iter()
            .filter(|(_, due)| due.next_nanos <= now_nanos)
            .map(|(key, _)| *key)
            .collect();
        for key in &keys {
            let Some(due) = self.due.get_mut(key) else {
                continue;
            };
            due.left -= 1;
            if due.left == 0 {
                self.due.remove(key);
            } else {
                due.wait_nanos = due.wait_nanos.saturating_mul(2).min(LONGEST_WAIT_NANOS);
                due.next_nanos = now_nanos.saturating_add(due.wait_nanos);
            }
        }
        keys
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SECOND: u64 = 1_000_000_000;

    #[test]
    fn a_change_is_repeated_at_doubling_intervals_then_no_more() {
        let mut repeats = Repeats::default();
        repeats.changed(7u32, 10 * SECOND);
        assert!(repeats.take_due(11 * SECOND).is_empty());
        let mut sent_at = Vec::new();
        for second in 11..120 {
            if !repeats.take_due(second * SECOND).is_empty() {
                sent_at.push(second);
            }
        }
        assert_eq!(sent_at, vec![12, 16, 24, 32, 40, 48]);
        assert!(!repeats.pending());
        assert_eq!(sent_at.len(), REPEATS as usize);
    }

    #[test]
    fn a_new_change_starts_the_repeats_again() {
        let mut repeats = Repeats::default();
        repeats.changed(1u32, 0);
        assert_eq!(repeats.take_due(2 * SECOND), vec![1]);
        repeats.changed(1, 3 * SECOND);
        repeats.changed(2, 3 * SECOND);
        assert!(repeats.take_due(4 * SECOND).is_empty());
        assert_eq!(repeats.take_due(5 * SECOND), vec![1, 2]);
        assert!(repeats.pending());
    }
}
