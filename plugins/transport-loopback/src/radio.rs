//! A robot's radio in the link model: every message it sends occupies it for the message's airtime.
//! Messages wait in two queues. Small ones (up to `sparse_bytes`: descriptors, odometry, loops, cloud
//! requests) go before the bulk ones (keyframe clouds), as the fair queuing of Linux's Wi-Fi stack
//! (FQ-CoDel in mac80211; Høiland-Jørgensen et al., "Ending the Anomaly", USENIX ATC 2017) serves sparse
//! flows before a backlogged one, so a cloud on its way to a far robot does not hold back the next
//! keyframe's descriptor for seconds. A sparse message takes its airtime from the bulk queue: the bulk
//! messages sent after it finish that much later (the model settles a message's times when it is sent,
//! so the ones already queued keep theirs). With `sparse_bytes = 0` there is one first-in, first-out
//! queue.

/// When a robot's radio is next free, per queue, in hub nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Radio {
    sparse_free_at_nanos: u64,
    bulk_free_at_nanos: u64,
}

impl Radio {
    /// Queues a message of `airtime_nanos` at `now_nanos`: when its transmission ends, or `None` when
    /// it would wait longer than `max_wait_nanos` (the queue is full and the message is dropped).
    pub(crate) fn send(
        &mut self,
        now_nanos: u64,
        airtime_nanos: u64,
        sparse: bool,
        max_wait_nanos: u64,
    ) -> Option<u64> {
        let start = if sparse {
            self.sparse_free_at_nanos.max(now_nanos)
        } else {
            self.bulk_free_at_nanos
                .max(self.sparse_free_at_nanos)
                .max(now_nanos)
        };
        if start - now_nanos > max_wait_nanos {
            return None;
        }
        let done = start + airtime_nanos;
        if sparse {
            self.sparse_free_at_nanos = done;
            if self.bulk_free_at_nanos > now_nanos {
                self.bulk_free_at_nanos += airtime_nanos;
            }
        } else {
            self.bulk_free_at_nanos = done;
        }
        Some(done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn a_small_message_goes_before_queued_clouds_and_delays_them_by_its_airtime() {
        let mut radio = Radio::default();
        // Two clouds of 3 s airtime each, then a descriptor of 80 ms.
        assert_eq!(radio.send(0, 3000 * MS, false, 5000 * MS), Some(3000 * MS));
        assert_eq!(radio.send(0, 3000 * MS, false, 5000 * MS), Some(6000 * MS));
        assert_eq!(radio.send(10 * MS, 80 * MS, true, 5000 * MS), Some(90 * MS));
        // The third cloud waits behind both clouds and the descriptor's airtime: over 5 s, so dropped.
        assert_eq!(radio.send(20 * MS, 3000 * MS, false, 5000 * MS), None);
        // Small messages queue among themselves.
        assert_eq!(radio.send(20 * MS, 80 * MS, true, 5000 * MS), Some(170 * MS));
    }

    #[test]
    fn without_sparse_messages_the_radio_is_one_fifo_queue() {
        let mut radio = Radio::default();
        assert_eq!(radio.send(0, 3000 * MS, false, 5000 * MS), Some(3000 * MS));
        assert_eq!(radio.send(0, 80 * MS, false, 5000 * MS), Some(3080 * MS));
        assert_eq!(radio.send(4000 * MS, 80 * MS, false, 5000 * MS), Some(4080 * MS));
    }
}
