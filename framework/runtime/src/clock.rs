//! The clock a robot's host times its cloud requests by, handed to it by the executor that runs it.
//!
//! The executors that play a whole fleet in one process (`lockstep`, `threads`, `processes`) run in scan
//! time: a request is stamped with the newest scan's stamp, and once the sources end the executor moves
//! the clock on with the link simulator's, so a run is reproducible bit for bit whatever the machine's
//! speed. One robot in its own process (`[deploy] robot = N`) talks to live peers and keeps running after
//! its scans end, so it runs on the wall clock.

use std::time::{Duration, Instant};

/// How long a cloud request may stay unanswered before it is sent again, in the host's time.
pub const CLOUD_RETRY_PERIOD: Duration = Duration::from_secs(2);

/// [`CLOUD_RETRY_PERIOD`] in nanoseconds.
pub(crate) const CLOUD_RETRY_NANOS: u64 = CLOUD_RETRY_PERIOD.as_nanos() as u64;

/// `seconds` of the host's time in nanoseconds (negative and NaN become 0).
pub(crate) fn nanos_from_s(seconds: f64) -> u64 {
    (seconds * 1e9) as u64
}

/// The time a host keeps, in nanoseconds.
#[derive(Clone, Copy, Debug)]
pub enum HostClock {
    /// The newest scan's stamp, or `floor_nanos` when the executor moved the clock past it.
    ScanTime { floor_nanos: u64 },
    /// Time since `origin`.
    Wall { origin: Instant },
}

impl HostClock {
    /// Scan time, from zero.
    pub fn scan_time() -> Self {
        Self::ScanTime { floor_nanos: 0 }
    }

    /// Wall time from now.
    pub fn wall() -> Self {
        Self::Wall {
            origin: Instant::now(),
        }
    }

    /// The time now, for a host whose newest scan has the stamp `newest_scan_nanos`.
    pub fn now_nanos(&self, newest_scan_nanos: u64) -> u64 {
        match self {
            Self::ScanTime { floor_nanos } => newest_scan_nanos.max(*floor_nanos),
            Self::Wall { origin } => u64::try_from(origin.elapsed().as_nanos()).unwrap_or(u64::MAX),
        }
    }

    /// Moves scan time on to at least `nanos` (after the sources end); the wall clock moves by itself.
    pub fn advance_to(&mut self, nanos: u64) {
        if let Self::ScanTime { floor_nanos } = self {
            *floor_nanos = (*floor_nanos).max(nanos);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_time_follows_the_scans_and_never_goes_back() {
        let mut clock = HostClock::scan_time();
        assert_eq!(clock.now_nanos(5), 5);
        clock.advance_to(10);
        assert_eq!(clock.now_nanos(5), 10);
        assert_eq!(clock.now_nanos(12), 12);
        clock.advance_to(3);
        assert_eq!(clock.now_nanos(0), 10);
    }

    #[test]
    fn wall_time_ignores_the_scans() {
        let clock = HostClock::wall();
        assert!(clock.now_nanos(u64::MAX) < 60_000_000_000);
    }
}
